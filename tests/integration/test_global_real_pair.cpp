// The global yaw search (issue 7) on the real pair with a known true transform (desk_gt_a onto
// desk_gt_b, identity; method.md §6): far starts that every local strategy loses.
#include <gtest/gtest.h>

#include "lmalign/core/geometry.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/registration/presets.hpp"
#include "support/real_pair.hpp"

namespace lmalign {
namespace {

TEST(GlobalRealPair, YawSearchFindsTheTruthFromAFarStart) {
  const std::string a = test::real_pair_source_file();
  const std::string b = test::real_pair_target_file();
  LMALIGN_REQUIRE_FILE(a);
  LMALIGN_REQUIRE_FILE(b);
  const Points3 source = read_map(a).positions();
  const PreparedTarget target(read_map(b));
  // Yaw 150 deg about the world origin and 2 m in XY.
  const Isometry3 D = pose_from_xyz_rpy_deg(1.5, -1.3, 0, 0, 0, 150);
  const Points3 moved = transform_points(D, source);
  SourceView view;
  view.positions = &moved;
  const TransformError local = transform_error(
      align(find_preset("robust_obs"), view, target).registration.T_target_source * D,
      Isometry3::Identity());
  EXPECT_GT(local.rotation_deg, 5.0);
  const TransformError e = transform_error(
      align(find_preset("global_robust_obs"), view, target).registration.T_target_source * D,
      Isometry3::Identity());
  EXPECT_LT(e.rotation_deg, 1.0);
  EXPECT_LT(e.translation_m, 0.015);
}

}  // namespace
}  // namespace lmalign
