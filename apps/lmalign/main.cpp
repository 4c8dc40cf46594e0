// lmalign: align sparse landmark maps from feature-based visual SLAM.
//
// `build-map` (the RGB-D map builder, OpenCV + Ceres) runs in a helper executable beside this one,
// lmalign-build-map: this binary does not load those libraries, so that every other command
// starts in milliseconds instead of the ~0.1 s that loading OpenCV's dependency chain takes
// (docs/cli.md).
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstring>
#include <iostream>
#include <string>

#include "cli_main.hpp"

namespace {

#ifdef LMALIGN_BUILD_MAP_HELPER
// The directory of this executable (/proc/self/exe), with a trailing '/'; empty if unknown.
std::string own_directory() {
  char buf[PATH_MAX];
  const ssize_t n = ::readlink("/proc/self/exe", buf, sizeof(buf) - 1);
  if (n <= 0) return {};
  const std::string path(buf, static_cast<std::size_t>(n));
  const std::size_t slash = path.rfind('/');
  return slash == std::string::npos ? std::string() : path.substr(0, slash + 1);
}

// Replaces this process with the helper, same arguments (argv[0] included, so that its usage
// lines name the command the user typed). Returns only on failure, with the exit code.
int run_build_map_helper(char** argv) {
  const std::string helper = own_directory() + LMALIGN_BUILD_MAP_HELPER;
  ::execv(helper.c_str(), argv);
  std::cerr << "lmalign: error: build-map runs in the helper executable '" << helper
            << "', which could not be started (" << std::strerror(errno)
            << "); build lmalign with OpenCV and Ceres (docs/map-builder.md)\n";
  return 2;
}

// The arguments main() was given, for the stub below.
char** g_argv = nullptr;

// `build-map` in the command list and in --help. main() hands `lmalign build-map ...` to the
// helper before parsing; should the parser still reach this command, it is handed over the same.
lmalign::cli::CommandRunner add_build_map_stub(CLI::App& root) {
  root.add_subcommand("build-map", lmalign::cli::kBuildMapDescription)->allow_extras();
  return [] { return run_build_map_helper(g_argv); };
}
#endif

}  // namespace

int main(int argc, char** argv) {
  lmalign::cli::install_terminate_handler();
#ifdef LMALIGN_BUILD_MAP_HELPER
  g_argv = argv;
  if (argc >= 2 && std::strcmp(argv[1], "build-map") == 0) return run_build_map_helper(argv);
#endif
  return lmalign::cli::run_cli(argc, argv,
                               {
                                   &lmalign::cli::add_align_command,
                                   &lmalign::cli::add_options_command,
                                   &lmalign::cli::add_split_command,
                                   &lmalign::cli::add_experiment_command,
                                   &lmalign::cli::add_eval_trajectory_command,
                                   &lmalign::cli::add_convert_command,
                                   &lmalign::cli::add_simulate_command,
#ifdef LMALIGN_HAVE_MERGE
                                   &lmalign::cli::add_merge_command,
#endif
#ifdef LMALIGN_BUILD_MAP_HELPER
                                   &add_build_map_stub,
#endif
                               });
}
