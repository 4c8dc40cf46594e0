// Replays fuzz/regressions/merge_manifest/ and fuzz/corpus/merge_manifest/ through the merge
// manifest's fuzz oracle (fuzz/merge_manifest_check.hpp) in every test build, including the
// AddressSanitizer + UndefinedBehaviorSanitizer one (docs/robustness.md). An oracle violation
// aborts the test binary, naming the input on stderr.
#include <gtest/gtest.h>

#include "../../fuzz/merge_manifest_check.hpp"
#include "support/fuzz_inputs.hpp"

namespace lmalign {
namespace {

TEST(MergeFuzzRegressions, ManifestInputsSatisfyTheOracle) {
  test::replay_fuzz_inputs("merge_manifest", &fuzz::check_merge_manifest_bytes, 5);
}

}  // namespace
}  // namespace lmalign
