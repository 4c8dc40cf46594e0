// Config -> cases: configs/paper.yaml is exactly the protocol of method.md §5 (45 cases), basin
// draws are seeded and reproducible, escalations are laid out per quadrant.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/experiment/cases.hpp"
#include "lmalign/experiment/config.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

std::string repo_file(const std::string& relative) {
  // tests/unit/<this file> -> repository root.
  return (std::filesystem::path(__FILE__).parent_path().parent_path().parent_path() / relative)
      .string();
}

ExperimentConfig paper_config() {
  ConfigLoadOptions o;
  o.data_dir = "/data";  // maps are not read when expanding
  return load_experiment_config(repo_file("configs/paper.yaml"), o);
}

Pose6 pose(double x, double y, double z, double roll, double pitch, double yaw) {
  return Pose6{x, y, z, roll, pitch, yaw};
}

TEST(ExperimentCases, PaperConfigIsExactlyTheProtocolOfMethodSection5) {
  const ExperimentConfig c = paper_config();
  // The real pair, ground truth identity, the paper's settings (method.md §5-6).
  EXPECT_EQ(c.source.path, "/data/tum_fr1_desk/ground_truth_pair/desk_gt_a.txt");
  EXPECT_EQ(c.target.path, "/data/tum_fr1_desk/ground_truth_pair/desk_gt_b.txt");
  EXPECT_EQ(c.ground_truth.kind, GroundTruthSpec::Kind::kIdentity);
  EXPECT_EQ(c.max_iterations, 150);
  ASSERT_TRUE(c.max_distance_m.has_value());
  EXPECT_TRUE(std::isinf(*c.max_distance_m));
  EXPECT_EQ(c.success.rotation_deg, 5.0);
  EXPECT_EQ(c.success.translation_m, 0.10);

  const std::vector<Case> cases = expand_cases(c);
  // The expected protocol, written out from method.md §5.
  struct Expected {
    std::string experiment;
    int k;
    Pose6 pose;
  };
  std::vector<Expected> want;
  for (int k : {1, 3, 5, 7, 10, 15, 20})
    want.push_back({"table1_k", k, pose(0, 1, 0.4, 10, 0, 22.5)});
  for (int yaw = 0; yaw <= 70; yaw += 10)
    want.push_back({"table2_yaw", 5, pose(0, 0, 0, 0, 0, yaw)});
  const std::vector<std::pair<std::pair<int, int>, std::vector<double>>> quadrants{
      {{1, 1}, {0.25, 0.5, 0.57, 0.58}},
      {{-1, 1}, {0.25, 0.5, 0.9}},
      {{-1, -1}, {0.25, 0.5}},
      {{1, -1}, {0.25, 0.5, 1.25, 2.0, 3.0}}};
  for (const auto& [signs, offsets] : quadrants) {
    for (double d : offsets) {
      want.push_back({"table3_xy", 5, pose(signs.first * d, signs.second * d, 0, 0, 0, 0)});
    }
  }
  for (const auto& [signs, offsets] : quadrants) {
    (void)offsets;
    for (double yaw : {10.0, -10.0, 30.0, -30.0}) {
      want.push_back(
          {"table4_xy_yaw", 5, pose(signs.first * 0.5, signs.second * 0.5, 0, 0, 0, yaw)});
    }
  }
  ASSERT_EQ(want.size(), 45u);  // 7 + 8 + 14 + 16
  ASSERT_EQ(cases.size(), 45u);
  std::set<std::string> ids;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const Case& got = cases[i];
    SCOPED_TRACE(got.id());
    EXPECT_EQ(got.index, i);
    EXPECT_EQ(got.experiment, want[i].experiment);
    EXPECT_EQ(got.k, want[i].k);
    EXPECT_TRUE(got.displacement == want[i].pose);
    EXPECT_TRUE(got.D.isApprox(
        pose_from_xyz_rpy_deg(want[i].pose.x_m, want[i].pose.y_m, want[i].pose.z_m,
                              want[i].pose.roll_deg, want[i].pose.pitch_deg, want[i].pose.yaw_deg),
        0.0));
    EXPECT_EQ(got.strategies, preset_names("paper"));
    EXPECT_EQ(got.escalation_group, -1);
    EXPECT_TRUE(ids.insert(got.id()).second) << "duplicate id";
  }
  EXPECT_EQ(cases[2].id(), "table1_k/k=5");
  EXPECT_EQ(cases[17].id(), "table3_xy/+X+Y 0.57");
  EXPECT_EQ(cases[29].id(), "table4_xy_yaw/+X+Y yaw=10");
  EXPECT_EQ(cases[44].id(), "table4_xy_yaw/+X-Y yaw=-30");
  // The history plot defaults to the configured Table 1 k=5 case.
  EXPECT_EQ(default_plot_case(c, cases), std::optional<std::size_t>(2));
}

ExperimentConfig basin_config(std::uint64_t seed, const std::string& pivot = "landmark",
                              const std::string& dirs = "xy") {
  return parse_experiment_config(
      "source: a.txt\ntarget: b.txt\nexperiments:\n  - {name: b, type: basin, samples: 5, seed: " +
          std::to_string(seed) + ", yaw_pivot: " + pivot + ", translation_directions: " + dirs +
          ", levels: {yaw_deg: [0, 30, 180], translation_m: [0, 0.5, 3]}}\n",
      "b.yaml", "/");
}

TEST(ExperimentCases, BasinDrawsAreSeededReproducibleAndOfTheRequestedSize) {
  const Points3 source = test::room_points(300, 5);
  const std::vector<Case> a = expand_cases(basin_config(42), source);
  const std::vector<Case> b = expand_cases(basin_config(42), source);
  const std::vector<Case> other = expand_cases(basin_config(43), source);
  // Level 0 is one draw (the identity); the others 5 each: 1 + 5 + 5 per axis.
  ASSERT_EQ(a.size(), 22u);
  ASSERT_EQ(other.size(), a.size());
  std::size_t differ = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    SCOPED_TRACE(a[i].id());
    EXPECT_TRUE(a[i].D.isApprox(b[i].D, 0.0));
    EXPECT_TRUE(a[i].displacement == b[i].displacement);
    if (!a[i].D.isApprox(other[i].D, 1e-9)) ++differ;
    const Isometry3& D = a[i].D;
    // The case parameters describe D in the paper's parametrisation.
    const Pose6& p = a[i].displacement;
    EXPECT_TRUE(pose_from_xyz_rpy_deg(p.x_m, p.y_m, p.z_m, p.roll_deg, p.pitch_deg, p.yaw_deg)
                    .isApprox(D, 1e-9));
    if (a[i].group == "yaw") {
      EXPECT_EQ(a[i].variable, "yaw_deg");
      EXPECT_NEAR(rotation_angle_deg(D.linear()), a[i].value, 1e-9);
      EXPECT_NEAR((D.linear() * Vec3::UnitZ() - Vec3::UnitZ()).norm(), 0.0, 1e-12);  // a pure yaw
      EXPECT_NEAR(D.translation().z(), 0.0, 1e-12);
      // The pivot is a vertical line through a source landmark: that landmark's x, y are fixed.
      bool fixed_landmark = false;
      for (const Vec3& s : source) {
        if (((D * s) - s).head<2>().norm() < 1e-9) fixed_landmark = true;
      }
      EXPECT_TRUE(fixed_landmark);
    } else {
      EXPECT_EQ(a[i].group, "translation");
      EXPECT_EQ(a[i].variable, "translation_m");
      EXPECT_TRUE(D.linear().isApprox(Mat3::Identity(), 0.0));
      EXPECT_NEAR(D.translation().norm(), a[i].value, 1e-12);
      EXPECT_EQ(D.translation().z(), 0.0);  // xy directions
    }
  }
  EXPECT_GE(differ, 15u);  // every draw but the two level-0 identities
  EXPECT_EQ(a[0].label, "yaw=0 #0");
  EXPECT_EQ(a[1].label, "yaw=30 #0");
  EXPECT_EQ(a[11].label, "t=0 #0");
  EXPECT_TRUE(a[0].D.isApprox(Isometry3::Identity(), 0.0));
  // Draws are random: the 5 draws of a level are not all the same.
  std::set<double> yaws;
  for (std::size_t i = 1; i <= 5; ++i) yaws.insert(std::round(a[i].D.translation().x() * 1e6));
  EXPECT_GE(yaws.size(), 3u);
}

TEST(ExperimentCases, BasinDrawsOfALevelDoNotDependOnTheOtherLevels) {
  const Points3 source = test::room_points(300, 5);
  const auto with_levels = [&](const std::string& yaw, const std::string& trans) {
    return expand_cases(
        parse_experiment_config(
            "source: a.txt\ntarget: b.txt\nexperiments:\n  - {name: b, type: basin, "
            "samples: 4, seed: 9, levels: {yaw_deg: " +
                yaw + ", translation_m: " + trans + "}}\n",
            "b.yaml", "/"),
        source);
  };
  const std::vector<Case> few = with_levels("[30]", "[1]");
  const std::vector<Case> many = with_levels("[0, 15, 30, 60]", "[0.5, 1, 2]");
  ASSERT_EQ(few.size(), 8u);
  const auto find = [&](const std::string& label) {
    for (const Case& c : many) {
      if (c.label == label) return c;
    }
    ADD_FAILURE() << label;
    return Case{};
  };
  for (const Case& c : few) EXPECT_TRUE(c.D.isApprox(find(c.label).D, 0.0)) << c.label;
}

TEST(ExperimentCases, BasinPivotsAndDirections) {
  const Points3 source = test::room_points(300, 5);
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : source) centroid += p;
  centroid /= static_cast<double>(source.size());
  for (const Case& c : expand_cases(basin_config(7, "centroid", "xyz"), source)) {
    if (c.group == "yaw") {
      EXPECT_NEAR(((c.D * centroid) - centroid).norm(), 0.0, 1e-9) << c.id();
    } else {
      EXPECT_NEAR(c.D.translation().norm(), c.value, 1e-12);
    }
  }
  // The origin pivot needs no source points; the others do.
  const ExperimentConfig origin = basin_config(7, "origin");
  EXPECT_FALSE(cases_need_source_points(origin));
  for (const Case& c : expand_cases(origin)) {
    if (c.group == "yaw") EXPECT_NEAR(c.D.translation().norm(), 0.0, 1e-12);
  }
  EXPECT_TRUE(cases_need_source_points(basin_config(7)));
  EXPECT_THROW(expand_cases(basin_config(7)), InvalidArgument);
}

ExperimentConfig random_config(std::uint64_t seed, int samples, const std::string& extra = "",
                               double roll_pitch_deg = 3.0) {
  return parse_experiment_config(
      "source: a.txt\ntarget: b.txt\nexperiments:\n  - {name: r, type: random, samples: " +
          std::to_string(samples) + ", seed: " + std::to_string(seed) +
          ", yaw_deg: 180, translation_m: 10, roll_pitch_deg: " + std::to_string(roll_pitch_deg) +
          extra + "}\n",
      "r.yaml", "/");
}

// Random starts (issue 18's benchmark): seeded, each draw independent of the sample count, the
// offset length recorded as the case's value, yaw covering [-180, 180], roll and pitch small,
// the rotation about the pivot and the offset across the up axis.
TEST(ExperimentCases, RandomStartsAreSeededBoundedAndAboutThePivot) {
  const Points3 source = test::room_points(300, 5);
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : source) centroid += p;
  centroid /= static_cast<double>(source.size());
  const std::vector<Case> a = expand_cases(random_config(3, 200), source);
  const std::vector<Case> b = expand_cases(random_config(3, 200), source);
  const std::vector<Case> few = expand_cases(random_config(3, 10), source);
  const std::vector<Case> other = expand_cases(random_config(4, 200), source);
  ASSERT_EQ(a.size(), 200u);
  ASSERT_EQ(few.size(), 10u);
  double min_yaw = 0, max_yaw = 0, max_offset = 0;
  std::size_t differ = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    SCOPED_TRACE(a[i].id());
    EXPECT_EQ(a[i].label, "start #" + std::to_string(i));
    EXPECT_EQ(a[i].group, "random");
    EXPECT_EQ(a[i].variable, "offset_m");
    EXPECT_TRUE(a[i].D.isApprox(b[i].D, 0.0));
    if (i < few.size()) EXPECT_TRUE(a[i].D.isApprox(few[i].D, 0.0));
    if (!a[i].D.isApprox(other[i].D, 1e-9)) ++differ;
    const Isometry3& D = a[i].D;
    // z up: the offset is horizontal, and the centroid moves by exactly that offset.
    const Vec3 moved = D * centroid - centroid;
    EXPECT_NEAR(moved.z(), 0.0, 1e-9);
    EXPECT_NEAR(moved.norm(), a[i].value, 1e-9);
    EXPECT_LE(a[i].value, 10.0);
    max_offset = std::max(max_offset, a[i].value);
    // Roll and pitch within 3 deg: the up axis tilts by at most ~4.3 deg.
    const double tilt_deg =
        std::acos(std::clamp((D.linear() * Vec3::UnitZ()).z(), -1.0, 1.0)) * 180.0 / M_PI;
    EXPECT_LE(tilt_deg, 3.0 * std::sqrt(2.0) + 1e-9);
    const Pose6& p = a[i].displacement;
    EXPECT_TRUE(pose_from_xyz_rpy_deg(p.x_m, p.y_m, p.z_m, p.roll_deg, p.pitch_deg, p.yaw_deg)
                    .isApprox(D, 1e-9));
    min_yaw = std::min(min_yaw, p.yaw_deg);
    max_yaw = std::max(max_yaw, p.yaw_deg);
  }
  EXPECT_EQ(differ, a.size());
  EXPECT_LT(min_yaw, -150.0);  // 200 uniform draws cover both ends
  EXPECT_GT(max_yaw, 150.0);
  EXPECT_GT(max_offset, 9.0);
  EXPECT_TRUE(cases_need_source_points(random_config(3, 5)));
  EXPECT_THROW(expand_cases(random_config(3, 5)), InvalidArgument);
  EXPECT_FALSE(cases_need_source_points(random_config(3, 5, ", pivot: origin")));
}

// up axis y (camera frames, KITTI): the yaw turns about y and the offsets lie in the x-z plane.
TEST(ExperimentCases, RandomStartsWithUpAxisYTurnAboutY) {
  const std::vector<Case> cases =
      expand_cases(random_config(5, 50, ", pivot: origin, up_axis: y", 0.0));
  ASSERT_EQ(cases.size(), 50u);
  double max_angle = 0.0;
  for (const Case& c : cases) {
    EXPECT_NEAR((c.D.linear() * Vec3::UnitY() - Vec3::UnitY()).norm(), 0.0, 1e-12) << c.id();
    EXPECT_NEAR(c.D.translation().y(), 0.0, 1e-12) << c.id();
    EXPECT_NEAR(c.D.translation().norm(), c.value, 1e-9) << c.id();
    max_angle = std::max(max_angle, rotation_angle_deg(c.D.linear()));
  }
  EXPECT_GT(max_angle, 150.0);
}

TEST(ExperimentCases, EscalationListsEveryLevelPerQuadrantInOrder) {
  const ExperimentConfig c = parse_experiment_config(R"(source: a.txt
target: b.txt
experiments:
  - {name: fixed, type: yaw, yaw_deg: [5]}
  - {name: esc, type: xy, escalate: {start_m: 0.25, step_m: 0.25, max_m: 1.0}, quadrants: [-X+Y, +X-Y], pose: {z_m: 0.1}}
)",
                                                     "e.yaml", "/");
  const std::vector<Case> cases = expand_cases(c);
  ASSERT_EQ(cases.size(), 1u + 2u * 4u);
  EXPECT_EQ(cases[0].escalation_group, -1);
  const std::vector<double> levels{0.25, 0.5, 0.75, 1.0};
  for (int g = 0; g < 2; ++g) {
    for (int l = 0; l < 4; ++l) {
      const Case& x = cases[1 + g * 4 + l];
      EXPECT_EQ(x.escalation_group, g);
      EXPECT_EQ(x.escalation_level, l);
      EXPECT_EQ(x.group, g == 0 ? "-X+Y" : "+X-Y");
      EXPECT_EQ(x.value, levels[l]);
      EXPECT_EQ(x.displacement.x_m, (g == 0 ? -1 : 1) * levels[l]);
      EXPECT_EQ(x.displacement.y_m, (g == 0 ? 1 : -1) * levels[l]);
      EXPECT_EQ(x.displacement.z_m, 0.1);
    }
  }
  EXPECT_EQ(cases[3].label, "-X+Y 0.75");
}

TEST(ExperimentCases, FindCaseByIndexOrId) {
  const ExperimentConfig c = paper_config();
  const std::vector<Case> cases = expand_cases(c);
  EXPECT_EQ(find_case(cases, "12"), std::optional<std::size_t>(12));
  EXPECT_EQ(find_case(cases, "table2_yaw/yaw=30"), std::optional<std::size_t>(10));
  EXPECT_EQ(find_case(cases, "45"), std::nullopt);
  EXPECT_EQ(find_case(cases, "table2_yaw/yaw=35"), std::nullopt);
  ExperimentConfig bad = c;
  bad.plot_case = "nope";
  EXPECT_THROW(default_plot_case(bad, cases), InvalidArgument);
  ExperimentConfig unset = c;
  unset.plot_case.clear();
  EXPECT_EQ(default_plot_case(unset, cases),
            std::optional<std::size_t>(2));  // first k experiment, k=5
}

}  // namespace
}  // namespace lmalign
