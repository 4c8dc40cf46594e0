// libFuzzer target: the ply reader, with the oracle of foreign_map_check.hpp
// (docs/robustness.md). Build: cmake -DLMALIGN_FUZZ=ON -DCMAKE_CXX_COMPILER=clang++; run: make
// fuzz.
#include <cstddef>
#include <cstdint>

#include <omp.h>

#include "foreign_map_check.hpp"

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  omp_set_num_threads(1);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lmalign::fuzz::check_ply_bytes(data, size);
  return 0;
}
