#include "cli_main.hpp"

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <map>
#include <new>
#include <string>

#include <CLI/CLI.hpp>

#include "lmalign/core/error.hpp"

namespace lmalign::cli {

const char* const kBuildMapDescription =
    "Build a landmark map from a TUM RGB-D sequence folder (rgb.txt, depth.txt, images,\n"
    "groundtruth.txt if present) with an RGB-D visual odometry: ORB features, PnP RANSAC\n"
    "tracking, keyframes, sliding-window bundle adjustment (Ceres), BA-marginal covariances.\n"
    "Writes the map (method.md section 1) and the keyframe trajectory (TUM format).\n"
    "See docs/map-builder.md.";

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

// What the exception in flight says (its what(); out of memory in words).
std::string current_exception_message() {
  try {
    throw;
  } catch (const lmalign::Error& e) {
    return e.what();
  } catch (const std::bad_alloc&) {
    return "out of memory (an allocation failed; the input may be too large for this machine)";
  } catch (const std::exception& e) {
    return e.what();
  } catch (...) {
    return "an unknown exception";
  }
}

// The last resort (an exception that escaped where it cannot be caught, e.g. a thread): one
// line and exit code 2 rather than an abort. Should not happen: please report it.
[[noreturn]] void on_terminate() {
  std::string what = "terminated";
  if (std::current_exception()) what = current_exception_message();
  std::cerr << "lmalign: error: internal error: " << one_line(what.c_str()) << "\n";
  std::cerr.flush();
  std::_Exit(2);
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

void install_terminate_handler() { std::set_terminate(on_terminate); }

int run_cli(int argc, char** argv, const std::vector<CommandAdder>& commands) {
  CLI::App app{
      "lmalign: rigid alignment of sparse landmark maps (mini-maps) from feature-based visual "
      "SLAM,\nwith the confidence-weighted ICP of Saraiva et al. and the checks a careful "
      "researcher would add.\n"
      "Frames: results are T_target_source, with p_target = T_target_source * p_source.\n"
      "Units: metres, degrees on the command line, m^2 for scores."};
  app.set_version_flag("--version", std::string("lmalign ") + LMALIGN_VERSION);
  app.require_subcommand(1);

  std::map<CLI::App*, CommandRunner> runners;
  for (CommandAdder adder : commands) {
    const std::size_t before = app.get_subcommands({}).size();
    CommandRunner run = adder(app);
    auto subs = app.get_subcommands({});
    if (subs.size() > before) runners[subs.back()] = std::move(run);
  }

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
  } catch (...) {
    std::cerr << "lmalign: error: " << one_line(current_exception_message().c_str()) << "\n";
    return 2;
  }

  try {
    for (auto& [sub, run] : runners) {
      if (sub->parsed()) return check_stdout(run());
    }
    std::cerr << "lmalign: error: no command given (see lmalign --help)\n";
    return 2;
  } catch (...) {
    // Every exception, lmalign's or a library's (std::filesystem, yaml-cpp, nlohmann::json,
    // an allocation), is one line and exit code 2.
    std::cerr << "lmalign: error: " << one_line(current_exception_message().c_str()) << "\n";
    return 2;
  }
}

}  // namespace lmalign::cli
