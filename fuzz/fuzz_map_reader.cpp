// libFuzzer target: the map-file reader (read_map on a stream), with the oracle of
// map_reader_check.hpp. Build: cmake -DLMALIGN_FUZZ=ON -DCMAKE_CXX_COMPILER=clang++; run:
// make fuzz (docs/robustness.md).
#include <cstddef>
#include <cstdint>

#include <omp.h>

#include "map_reader_check.hpp"

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  omp_set_num_threads(1);  // one input at a time; no thread pool churn per input
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lmalign::fuzz::check_map_bytes(data, size);
  return 0;
}
