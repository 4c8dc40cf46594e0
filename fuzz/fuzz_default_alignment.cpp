// libFuzzer target: the default alignment (align() with the recommended preset, as `lmalign align`
// calls it) of two small fuzzed maps, with the oracle of default_alignment_check.hpp
// (docs/robustness.md).
// Build: cmake -DLMALIGN_FUZZ=ON -DCMAKE_CXX_COMPILER=clang++; run: make fuzz.
#include <cstddef>
#include <cstdint>

#include <omp.h>

#include "default_alignment_check.hpp"

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  omp_set_num_threads(1);  // one input at a time; the result does not depend on it
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lmalign::fuzz::check_default_alignment_bytes(data, size);
  return 0;
}
