// lmalign-build-map: the helper that runs `lmalign build-map` (the only part of the CLI that
// links OpenCV and Ceres; lmalign hands `build-map ...` over to it with execv, same arguments).
// It can also be run directly: lmalign-build-map build-map SEQUENCE -o MAP ...
#include "cli_main.hpp"

int main(int argc, char** argv) {
  lmalign::cli::install_terminate_handler();
  return lmalign::cli::run_cli(argc, argv, {&lmalign::cli::add_build_map_command});
}
