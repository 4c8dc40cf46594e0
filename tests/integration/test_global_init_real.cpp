// Global initialisation on the real pair with a known true transform (desk_gt_a onto desk_gt_b,
// identity; method.md §6): seeded random starts with any yaw (about a vertical axis through a
// random landmark) and XY offsets up to 3 m. Each must land in the right basin (< 5 deg and
// < 10 cm) and close to the truth. docs/accuracy.md gives the full sweep.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "lmalign/core/geometry.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/registration/global_init.hpp"
#include "support/real_pair.hpp"

namespace lmalign {
namespace {

TEST(GlobalInitReal, AnyYawAndThreeMetresOnTheRealPair) {
  const std::string a = test::real_pair_source_file();
  const std::string b = test::real_pair_target_file();
  LMALIGN_REQUIRE_FILE(a);
  LMALIGN_REQUIRE_FILE(b);
  const Points3 source = read_map(a).positions();
  const PreparedTarget target(read_map(b));
  std::mt19937 rng(20261121);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 6; ++i) {
    const double yaw_deg = -180.0 + 360.0 * u(rng);
    const double r_m = 3.0 * u(rng), dir = 2.0 * M_PI * u(rng);
    const Vec3 pivot = source[static_cast<std::size_t>(u(rng) * source.size()) % source.size()];
    Isometry3 D = Isometry3::Identity();
    D.linear() = Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Vec3::UnitZ()).toRotationMatrix();
    D.translation() =
        pivot - D.linear() * pivot + Vec3(r_m * std::cos(dir), r_m * std::sin(dir), 0);
    const GlobalInitResult r = global_align(transform_points(D, source), target);
    // The recovered map-to-map transform against the truth (the identity).
    const TransformError e = transform_error(r.T_target_source * D, Isometry3::Identity());
    EXPECT_LT(e.rotation_deg, 2.0) << "yaw " << yaw_deg << " offset " << r_m;
    EXPECT_LT(e.translation_m, 0.04) << "yaw " << yaw_deg << " offset " << r_m;
    EXPECT_GT(r.inlier_fraction, 0.3);
  }
}

}  // namespace
}  // namespace lmalign
