// The inputs that the tests replay through the fuzz oracles (docs/robustness.md): every file of
// fuzz/regressions/<target>/ (inputs that once failed) and fuzz/corpus/<target>/ (the seeds).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace lmalign::test {

/// The repository's fuzz/ folder (found from this header's path).
inline std::filesystem::path fuzz_dir() {
  return std::filesystem::path(__FILE__).parent_path().parent_path().parent_path() / "fuzz";
}

/// The regression inputs of `target`, then its seeds, each folder sorted by name.
inline std::vector<std::filesystem::path> fuzz_inputs(const std::string& target) {
  std::vector<std::filesystem::path> all;
  for (const char* kind : {"regressions", "corpus"}) {
    std::vector<std::filesystem::path> files;
    const std::filesystem::path dir = fuzz_dir() / kind / target;
    if (!std::filesystem::is_directory(dir)) continue;
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
      if (entry.is_regular_file()) files.push_back(entry.path());
    }
    std::sort(files.begin(), files.end());
    all.insert(all.end(), files.begin(), files.end());
  }
  return all;
}

inline std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// Runs every input of `target` through `check` (an oracle that aborts on a violation, naming
/// the input on stderr first); at least `min_inputs` are expected (the seeds are part of the
/// repository: finding none means the path is wrong).
inline void replay_fuzz_inputs(const std::string& target,
                               void (*check)(const std::uint8_t*, std::size_t),
                               std::size_t min_inputs) {
  const std::vector<std::filesystem::path> files = fuzz_inputs(target);
  for (const std::filesystem::path& file : files) {
    SCOPED_TRACE(file.string());
    std::fprintf(stderr, "replaying %s\n", file.c_str());
    const std::string data = file_bytes(file);
    check(reinterpret_cast<const std::uint8_t*>(data.data()), data.size());
  }
  EXPECT_GE(files.size(), min_inputs) << "no fuzz inputs under " << fuzz_dir();
}

}  // namespace lmalign::test
