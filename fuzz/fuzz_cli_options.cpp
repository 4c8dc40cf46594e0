// libFuzzer target: the numeric options of `lmalign align` (--displace, --initial-guess,
// --prior-sigma, --set, ...), through the CLI's own run_cli() in this process, on two small
// fixed maps; the oracle of cli_options_check.hpp (docs/robustness.md). The standard output goes
// to /dev/null; std::cerr is captured per input. Build: cmake -DLMALIGN_FUZZ=ON
// -DCMAKE_CXX_COMPILER=clang++; run: make fuzz.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <omp.h>

#include "../apps/lmalign/cli_main.hpp"
#include "cli_options_check.hpp"

namespace {
std::string g_dir;
}

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  omp_set_num_threads(1);
  g_dir =
      (std::filesystem::temp_directory_path() / ("lmalign_fuzz_cli_" + std::to_string(::getpid())))
          .string();
  std::filesystem::create_directories(g_dir);
  lmalign::fuzz::write_cli_fuzz_maps(g_dir);
  if (std::freopen("/dev/null", "w", stdout) == nullptr) std::abort();
  std::atexit([] {
    std::error_code ec;
    std::filesystem::remove_all(g_dir, ec);
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const lmalign::fuzz::CliOptionsInput in = lmalign::fuzz::decode_cli_options(
      std::string(reinterpret_cast<const char*>(data), size), g_dir);
  lmalign::fuzz::write_cli_fuzz_files(in, g_dir);
  std::vector<std::string> args{"lmalign", "align", g_dir + "/source.txt", g_dir + "/target.txt"};
  args.insert(args.end(), in.args.begin(), in.args.end());
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::ostringstream err;
  std::streambuf* saved = std::cerr.rdbuf(err.rdbuf());
  const int code = lmalign::cli::run_cli(static_cast<int>(args.size()), argv.data(),
                                         {&lmalign::cli::add_align_command});
  std::cerr.rdbuf(saved);
  std::cout.clear();
  std::clearerr(stdout);
  lmalign::fuzz::check_cli_outcome(code, err.str());
  return 0;
}
