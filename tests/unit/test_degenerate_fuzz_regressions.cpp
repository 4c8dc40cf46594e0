// Replays the fuzzing inputs through the fuzz oracles in every test build, including the
// AddressSanitizer + UndefinedBehaviorSanitizer one (docs/robustness.md):
//   fuzz/regressions/<target>/  every input that once crashed a fuzz target (must stay fixed);
//   fuzz/corpus/<target>/       the seed corpus (real-format and malformed files).
// An oracle violation aborts the test binary, naming the input on stderr.
#include <cstddef>
#include <cstdint>
#include <string>

#include <gtest/gtest.h>

#include "../../fuzz/default_alignment_check.hpp"
#include "../../fuzz/experiment_config_check.hpp"
#include "../../fuzz/foreign_map_check.hpp"
#include "../../fuzz/map_reader_check.hpp"
#include "support/fuzz_inputs.hpp"

namespace lmalign {
namespace {

void replay(const std::string& target, void (*check)(const std::uint8_t*, std::size_t),
            std::size_t min_inputs = 10) {
  test::replay_fuzz_inputs(target, check, min_inputs);
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

TEST(DegenerateFuzzRegressions, DefaultAlignmentInputsSatisfyTheOracle) {
  replay("default_alignment", &fuzz::check_default_alignment_bytes, 5);
}

}  // namespace
}  // namespace lmalign
