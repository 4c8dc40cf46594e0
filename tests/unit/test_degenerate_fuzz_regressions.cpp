// Replays the fuzzing inputs through the fuzz oracles in every test build, including the
// AddressSanitizer + UndefinedBehaviorSanitizer one (docs/robustness.md):
//   fuzz/regressions/<target>/  every input that once crashed a fuzz target (must stay fixed);
//   fuzz/corpus/<target>/       the seed corpus (real-format and malformed files).
// An oracle violation aborts the test binary, naming the input on stderr.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "../../fuzz/experiment_config_check.hpp"
#include "../../fuzz/foreign_map_check.hpp"
#include "../../fuzz/map_reader_check.hpp"

namespace lmalign {
namespace {

namespace fs = std::filesystem;

fs::path fuzz_dir() {
  return fs::path(__FILE__).parent_path().parent_path().parent_path() / "fuzz";
}

std::vector<fs::path> inputs(const std::string& kind, const std::string& target) {
  std::vector<fs::path> files;
  const fs::path dir = fuzz_dir() / kind / target;
  if (!fs::is_directory(dir)) return files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.is_regular_file()) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

std::string bytes_of(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void replay(const std::string& target, void (*check)(const std::uint8_t*, std::size_t),
            std::size_t min_inputs = 10) {
  std::size_t count = 0;
  for (const char* kind : {"regressions", "corpus"}) {
    for (const fs::path& file : inputs(kind, target)) {
      SCOPED_TRACE(file.string());
      std::fprintf(stderr, "replaying %s\n", file.c_str());
      const std::string data = bytes_of(file);
      check(reinterpret_cast<const std::uint8_t*>(data.data()), data.size());
      ++count;
    }
  }
  // The seed corpus is part of the repository: finding nothing means the path is wrong.
  EXPECT_GE(count, min_inputs) << "no fuzz inputs under " << fuzz_dir();
}

TEST(DegenerateFuzzRegressions, MapReaderInputsSatisfyTheOracle) {
  replay("map_reader", &fuzz::check_map_bytes);
}

TEST(DegenerateFuzzRegressions, ExperimentConfigInputsSatisfyTheOracle) {
  replay("experiment_config", &fuzz::check_experiment_config_bytes);
}

TEST(DegenerateFuzzRegressions, BundlerReaderInputsSatisfyTheOracle) {
  replay("bundler_reader", &fuzz::check_bundler_bytes, 5);
}

TEST(DegenerateFuzzRegressions, ColmapReaderInputsSatisfyTheOracle) {
  replay("colmap_reader", &fuzz::check_colmap_bytes, 5);
}

TEST(DegenerateFuzzRegressions, PlyReaderInputsSatisfyTheOracle) {
  replay("ply_reader", &fuzz::check_ply_bytes, 5);
}

TEST(DegenerateFuzzRegressions, StellaVslamReaderInputsSatisfyTheOracle) {
  replay("stella_vslam_reader", &fuzz::check_stella_vslam_bytes, 5);
}

}  // namespace
}  // namespace lmalign
