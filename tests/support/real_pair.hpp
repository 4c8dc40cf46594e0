// The real mini-map pair whose true transform is known (desk_gt_a onto desk_gt_b, the identity to
// ~0.7 deg and ~1 cm; method.md §6), for integration tests: the file paths, and a fixture that
// loads the pair once per test suite.
#pragma once

#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "lmalign/map/map_io.hpp"
#include "lmalign/registration/registration.hpp"
#include "support/data_path.hpp"

namespace lmalign::test {

inline std::string real_pair_source_file() {
  return data_file("tum_fr1_desk/ground_truth_pair/desk_gt_a.txt");
}
inline std::string real_pair_target_file() {
  return data_file("tum_fr1_desk/ground_truth_pair/desk_gt_b.txt");
}

/// Derive a suite's fixture from this: source_ (desk_gt_a) and target_ (desk_gt_b, prepared with
/// all weights) are loaded once per suite; each test skips locally, or fails with CI=true, when
/// the data is missing (LMALIGN_REQUIRE_FILE).
class RealPairTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!std::filesystem::exists(real_pair_source_file()) ||
        !std::filesystem::exists(real_pair_target_file())) {
      return;
    }
    source_ = std::make_unique<Map>(read_map(real_pair_source_file()));
    target_ = std::make_unique<PreparedTarget>(read_map(real_pair_target_file()));
  }
  static void TearDownTestSuite() {
    source_.reset();
    target_.reset();
  }
  void SetUp() override {
    LMALIGN_REQUIRE_FILE(real_pair_source_file());
    LMALIGN_REQUIRE_FILE(real_pair_target_file());
  }

  static inline std::unique_ptr<Map> source_;
  static inline std::unique_ptr<PreparedTarget> target_;
};

}  // namespace lmalign::test
