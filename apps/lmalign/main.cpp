// lmalign: align sparse landmark maps from feature-based visual SLAM.
#include <cstdio>
#include <exception>
#include <iostream>
#include <map>
#include <string>

#include <CLI/CLI.hpp>

#include "commands.hpp"
#include "lmalign/core/error.hpp"

namespace {
// An error message as one printable line: control bytes of paths or file contents (a newline in
// a file name, an escape sequence) are written as \xHH (docs/robustness.md).
std::string one_line(const char* message) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  for (const char* p = message; *p != '\0'; ++p) {
    const auto byte = static_cast<unsigned char>(*p);
    if (byte < 0x20 || byte == 0x7f) {
      out += "\\x";
      out += kHex[byte >> 4];
      out += kHex[byte & 0xf];
    } else {
      out += *p;
    }
  }
  return out;
}

// Output that could not be written (a full disk, a closed pipe) is an error, not a success.
int check_stdout(int code) {
  std::cout.flush();
  if (std::fflush(stdout) != 0 || std::ferror(stdout) || !std::cout) {
    std::cerr << "lmalign: error: cannot write the standard output\n";
    return code == 0 ? 2 : code;
  }
  return code;
}
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "lmalign: rigid alignment of sparse landmark maps (mini-maps) from feature-based visual "
      "SLAM,\nwith the confidence-weighted ICP of Saraiva et al. and the checks a careful "
      "researcher would add.\n"
      "Frames: results are T_target_source, with p_target = T_target_source * p_source.\n"
      "Units: metres, degrees on the command line, m^2 for scores."};
  app.set_version_flag("--version", std::string("lmalign ") + LMALIGN_VERSION);
  app.require_subcommand(1);

  std::map<CLI::App*, lmalign::cli::CommandRunner> runners;
  auto add = [&](lmalign::cli::CommandRunner (*adder)(CLI::App&)) {
    const std::size_t before = app.get_subcommands({}).size();
    lmalign::cli::CommandRunner run = adder(app);
    auto subs = app.get_subcommands({});
    if (subs.size() > before) runners[subs.back()] = std::move(run);
  };
  add(&lmalign::cli::add_align_command);
  add(&lmalign::cli::add_split_command);
  add(&lmalign::cli::add_experiment_command);
  add(&lmalign::cli::add_eval_trajectory_command);
#ifdef LMALIGN_HAVE_VO
  add(&lmalign::cli::add_build_map_command);
#endif

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // Usage errors are bad input like any other: one line, exit code 2.
    std::cerr << "lmalign: error: " << one_line(e.what()) << " (see lmalign --help)\n";
    return 2;
  }

  try {
    for (auto& [sub, run] : runners) {
      if (sub->parsed()) return check_stdout(run());
    }
    std::cerr << "lmalign: error: no command given (see lmalign --help)\n";
    return 2;
  } catch (const lmalign::Error& e) {
    std::cerr << "lmalign: error: " << one_line(e.what()) << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "lmalign: internal error: " << one_line(e.what()) << "\n";
    return 3;
  }
}
