// lmalign: align sparse landmark maps from feature-based visual SLAM.
#include <exception>
#include <iostream>
#include <map>
#include <string>

#include <CLI/CLI.hpp>

#include "commands.hpp"
#include "lmalign/core/error.hpp"

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
    std::cerr << "lmalign: error: " << e.what() << " (see lmalign --help)\n";
    return 2;
  }

  try {
    for (auto& [sub, run] : runners) {
      if (sub->parsed()) return run();
    }
    std::cerr << "lmalign: error: no command given (see lmalign --help)\n";
    return 2;
  } catch (const lmalign::Error& e) {
    std::cerr << "lmalign: error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "lmalign: internal error: " << e.what() << "\n";
    return 3;
  }
}
