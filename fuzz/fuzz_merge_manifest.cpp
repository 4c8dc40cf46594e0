// libFuzzer target: the merge manifest, read and planned (parse_manifest, plan_candidates, the
// pose graph of its priors), with the oracle of merge_manifest_check.hpp (docs/robustness.md).
// Build: cmake -DLMALIGN_FUZZ=ON -DCMAKE_CXX_COMPILER=clang++ (with Ceres); run: make fuzz.
#include <cstddef>
#include <cstdint>

#include <omp.h>

#include "merge_manifest_check.hpp"

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  omp_set_num_threads(1);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lmalign::fuzz::check_merge_manifest_bytes(data, size);
  return 0;
}
