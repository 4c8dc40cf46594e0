// The aperiodic street simulator (include/lmalign/sim/street_sim.hpp): the statistics the
// accuracy benchmark relies on (no strong period along the road, KITTI-like stereo depths and
// covariances, the windows' overlap), determinism and the truth.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/sim/road_sim.hpp"
#include "lmalign/sim/street_sim.hpp"
#include "support/invalid_options.hpp"
#include "support/sim_checks.hpp"

namespace lmalign {
namespace {

sim::StreetSimOptions small_options() {
  sim::StreetSimOptions o;
  o.num_landmarks = 2000;
  o.seed = 7;
  return o;
}

// The strongest spectral line of the landmark density along the road: the periodogram of the
// density (0.25 m bins of arc length, mean removed; the Fourier transform of its
// autocorrelation) at periods of 1.2-15 m, over the median of its 16 neighbouring frequencies.
// A periodic scene has a line at its period; an aperiodic one's spectrum is smooth (a ratio of
// the order of the largest of ~100 exponential draws over their median, under 10).
double strongest_line(const std::vector<double>& arcs_m, double* period_m) {
  constexpr double kBin = 0.25;
  std::vector<double> sorted = arcs_m;
  std::sort(sorted.begin(), sorted.end());
  const double lo = sorted[sorted.size() / 20], hi = sorted[sorted.size() * 19 / 20];
  const auto n = static_cast<std::size_t>((hi - lo) / kBin) + 1;
  std::vector<double> h(n, 0.0);
  for (double s : arcs_m) {
    if (s >= lo && s <= hi) h[std::min(n - 1, static_cast<std::size_t>((s - lo) / kBin))] += 1.0;
  }
  double mean = 0.0;
  for (double v : h) mean += v / static_cast<double>(n);
  std::vector<double> power(n / 2 + 1, 0.0);
  for (std::size_t k = 1; k <= n / 2; ++k) {
    double re = 0.0, im = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const double a = 2.0 * M_PI * static_cast<double>(k * i) / static_cast<double>(n);
      re += (h[i] - mean) * std::cos(a);
      im -= (h[i] - mean) * std::sin(a);
    }
    power[k] = re * re + im * im;
  }
  double best = 0.0;
  for (std::size_t k = 9; k + 9 <= n / 2; ++k) {
    const double period = kBin * static_cast<double>(n) / static_cast<double>(k);
    if (period < 1.2 || period > 15.0) continue;
    std::vector<double> around;
    for (std::size_t j = k - 9; j <= k + 9; ++j) {
      if (j + 1 < k || j > k + 1) around.push_back(power[j]);
    }
    std::nth_element(around.begin(), around.begin() + 8, around.end());
    if (power[k] / around[8] > best) {
      best = power[k] / around[8];
      *period_m = period;
    }
  }
  return best;
}

// Landmarks precise enough to resolve a 1.5 m period: largest sigma below 0.5 m.
bool precise(const Landmark& lm) {
  return Eigen::SelfAdjointEigenSolver<Mat3>(lm.cov_world_m2).eigenvalues()[2] < 0.25;
}

TEST(StreetSim, DensityAlongTheRoadHasNoSpectralLineUnlikeThePeriodicRoad) {
  double worst = 0.0;
  for (std::uint64_t seed : {1, 2, 3, 4}) {
    sim::StreetSimOptions o = small_options();
    o.num_landmarks = 3000;
    o.seed = seed;
    const sim::SlamMapPair pair = sim::simulate_street_pair(o);
    const std::vector<Vec3> line = sim::street_centre_line(seed, 400.0, 0.25);
    std::vector<double> arcs;  // arc length of each landmark's nearest centre-line point
    for (const Landmark& lm : pair.target.landmarks) {
      if (!precise(lm)) continue;
      double best = 1e18;
      std::size_t at = 0;
      for (std::size_t i = 0; i < line.size(); ++i) {
        const double d = (Vec3(lm.p_world.x(), 0.0, lm.p_world.z()) - line[i]).squaredNorm();
        if (d < best) {
          best = d;
          at = i;
        }
      }
      if (best < 25.0 * 25.0) arcs.push_back(0.25 * static_cast<double>(at));
    }
    ASSERT_GT(arcs.size(), 800u);
    double period = 0.0;
    const double line_ratio = strongest_line(arcs, &period);
    worst = std::max(worst, line_ratio);
    EXPECT_LT(line_ratio, 12.0) << "seed " << seed << ": a line at " << period << " m";
  }
  // The same statistic finds road_sim's period (its 1.5 m ground texture, 3 m window grid).
  for (std::uint64_t seed : {1, 2}) {
    sim::RoadSimOptions r;
    r.num_landmarks = 3000;
    r.seed = seed;
    const sim::SlamMapPair road = sim::simulate_road_pair(r);
    std::vector<double> z;
    for (const Landmark& lm : road.target.landmarks) {
      if (precise(lm)) z.push_back(lm.p_world.z());
    }
    double period = 0.0;
    const double line_ratio = strongest_line(z, &period);
    EXPECT_GT(line_ratio, 1.5 * worst) << "road seed " << seed;
    EXPECT_GT(line_ratio, 15.0) << "road seed " << seed;
    EXPECT_NEAR(period, 1.5, 0.1) << "road seed " << seed;
  }
}

// KITTI-like stereo: depths (from the last observing keyframe) within the range, most near; the
// covariance's long axis along the viewing ray, its sigma growing with the depth squared and the
// sigma across with the depth.
TEST(StreetSim, StereoDepthsAndCovariances) {
  const sim::StreetSimOptions o = small_options();
  const sim::SlamMapPair pair = sim::simulate_street_pair(o);
  const Map& map = pair.target;  // world frame
  std::map<Id, const Frame*> frames;
  for (const Frame& f : map.frames) frames[f.id] = &f;
  std::vector<double> depths, log_depth, log_along, log_across;
  std::size_t along_ray = 0, far_away = 0;
  for (const Landmark& lm : map.landmarks) {
    const Isometry3 T = frames.at(lm.observations.back().frame_id)->T_world_camera();
    const Vec3 pc = T.inverse() * lm.p_world;
    ASSERT_GT(pc.z(), 0.0);
    depths.push_back(pc.z());
    far_away += pc.z() > o.max_range_m ? 1 : 0;
    Eigen::SelfAdjointEigenSolver<Mat3> es(lm.cov_world_m2);
    ASSERT_GT(es.eigenvalues()[0], 0.0);
    const Vec3 ray = (lm.p_world - T.translation()).normalized();
    along_ray += std::abs(ray.dot(es.eigenvectors().col(2))) > 0.99 ? 1 : 0;
    if (pc.z() > 3.0 && pc.z() < 100.0) {
      log_depth.push_back(std::log(pc.z()));
      log_along.push_back(0.5 * std::log(es.eigenvalues()[2]));
      log_across.push_back(0.25 * std::log(es.eigenvalues()[0] * es.eigenvalues()[1]));
    }
  }
  std::sort(depths.begin(), depths.end());
  EXPECT_GT(depths.front(), 0.5 * o.min_range_m);
  // Noise moves far landmarks beyond the range, a few.
  EXPECT_LT(static_cast<double>(far_away), 0.05 * static_cast<double>(depths.size()));
  const double median = depths[depths.size() / 2];
  EXPECT_GT(median, 10.0);
  EXPECT_LT(median, 40.0);                            // KITTI's maps: 16-23 m
  EXPECT_GT(depths[depths.size() * 95 / 100], 60.0);  // and far ones
  EXPECT_GT(static_cast<double>(along_ray), 0.95 * static_cast<double>(map.landmarks.size()));
  // Least-squares slopes of log sigma against log depth: 2 along the ray, 1 across.
  auto slope = [&](const std::vector<double>& y) {
    double mx = 0, my = 0;
    for (std::size_t i = 0; i < y.size(); ++i) {
      mx += log_depth[i];
      my += y[i];
    }
    mx /= static_cast<double>(y.size());
    my /= static_cast<double>(y.size());
    double sxy = 0, sxx = 0;
    for (std::size_t i = 0; i < y.size(); ++i) {
      sxy += (log_depth[i] - mx) * (y[i] - my);
      sxx += (log_depth[i] - mx) * (log_depth[i] - mx);
    }
    return sxy / sxx;
  };
  ASSERT_GT(log_depth.size(), 1000u);
  EXPECT_NEAR(slope(log_along), 2.0, 0.3);
  EXPECT_NEAR(slope(log_across), 1.0, 0.15);
}

// The covariance is the stereo one: the estimate's error against the true point is consistent
// with it (mean NEES about 3) where the stereo back-projection is nearly linear (depth < 20 m,
// disparity > 19 px); farther, the 1/disparity law biases the depth outwards.
TEST(StreetSim, CovarianceMatchesTheError) {
  const sim::StreetWindows w = sim::simulate_street_windows(small_options(), 2);
  ASSERT_EQ(w.true_positions.size(), 2u);
  for (std::size_t k = 0; k < 2; ++k) {
    const Map& map = w.maps[k];
    ASSERT_EQ(w.true_positions[k].size(), map.landmarks.size());
    double sum = 0.0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < map.landmarks.size(); ++i) {
      const Landmark& lm = map.landmarks[i];
      const Frame* last = map.find_frame(lm.observations.back().frame_id);
      const double depth = (last->T_world_camera().inverse() * w.true_positions[k][i]).z();
      if (depth > 20.0) continue;
      const Vec3 e = lm.p_world - w.true_positions[k][i];
      sum += e.dot(lm.cov_world_m2.ldlt().solve(e));
      ++n;
    }
    ASSERT_GT(n, 300u);
    EXPECT_NEAR(sum / static_cast<double>(n), 3.0, 0.4) << n << " landmarks";
  }
}

TEST(StreetSim, ObservationsFramesAndSpacing) {
  const sim::StreetSimOptions o = small_options();
  const sim::SlamMapPair pair = sim::simulate_street_pair(o);
  for (const Map* m : {&pair.source, &pair.target}) {
    EXPECT_EQ(m->landmarks.size(), o.num_landmarks);
    ASSERT_EQ(m->frames.size(), o.window_frames);
    EXPECT_NO_THROW(m->validate());
    test::expect_stereo_observations(*m, o.max_observations);
    for (const Landmark& lm : m->landmarks) {
      for (const Observation& ob : lm.observations) {  // inside the image, up to the noise
        EXPECT_GT(ob.u_px, -6.0);
        EXPECT_LT(ob.u_px, 1248.0);
        EXPECT_GT(ob.v_px, -6.0);
        EXPECT_LT(ob.v_px, 381.0);
      }
    }
    for (std::size_t f = 1; f < m->frames.size(); ++f) {  // about 1 m per keyframe, +- 10%
      const double step = (m->frames[f].p_world_camera - m->frames[f - 1].p_world_camera).norm();
      EXPECT_GT(step, 0.85 * o.frame_step_m);
      EXPECT_LT(step, 1.15 * o.frame_step_m);
    }
  }
}

// Window k + 1 starts round((1 - overlap) F) keyframes after window k: the shared keyframes have
// the same poses (through the truth).
TEST(StreetSim, OverlapSharesKeyframes) {
  for (double overlap : {0.0, 0.25, 0.5}) {
    sim::StreetSimOptions o = small_options();
    o.overlap = overlap;
    o.T_target_source = pose_from_xyz_rpy_deg(3, -1, 20, 1, 2, 30);
    const sim::SlamMapPair pair = sim::simulate_street_pair(o);
    const auto shared = static_cast<std::size_t>(std::lround(overlap * 30.0));
    std::size_t same = 0;
    for (const Frame& s : pair.source.frames) {
      for (const Frame& t : pair.target.frames) {
        same += (pair.T_target_source * s.p_world_camera - t.p_world_camera).norm() < 1e-9 ? 1 : 0;
      }
    }
    EXPECT_EQ(same, shared) << "overlap " << overlap;
    // The source's last keyframe lies one step before the target's first non-shared one.
    const Vec3 last = pair.T_target_source * pair.source.frames.back().p_world_camera;
    EXPECT_NEAR((last - pair.target.frames[shared].p_world_camera).norm(), 1.0, 0.12);
  }
}

// Curves and turns: along a long street the heading changes, by 90 deg within tens of metres
// somewhere (a turn), and always stays within the allowed [-45, 90] deg or its mirror.
TEST(StreetSim, CentreLineHasCurvesAndTurns) {
  std::size_t worlds_with_turns = 0, worlds_with_curves = 0;
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    const std::vector<Vec3> line = sim::street_centre_line(seed, 2000.0, 1.0);
    std::vector<double> heading;
    for (std::size_t i = 1; i < line.size(); ++i) {
      const Vec3 d = line[i] - line[i - 1];
      EXPECT_NEAR(d.norm(), 1.0, 1e-3);
      heading.push_back(std::atan2(d.x(), d.z()) * 180.0 / M_PI);
    }
    const auto [lo, hi] = std::minmax_element(heading.begin(), heading.end());
    EXPECT_LE(*hi - *lo, 135.0 + 1.0) << seed;
    EXPECT_TRUE((*lo >= -46.0 && *hi <= 91.0) || (*lo >= -91.0 && *hi <= 46.0)) << seed;
    bool turn = false, curve = false;
    for (std::size_t i = 0; i + 30 < heading.size(); ++i) {
      const double change = std::abs(heading[i + 30] - heading[i]);
      turn = turn || change > 80.0;
      curve = curve || (change > 3.0 && change < 20.0);
    }
    worlds_with_turns += turn ? 1 : 0;
    worlds_with_curves += curve ? 1 : 0;
  }
  EXPECT_GE(worlds_with_turns, 8u);
  EXPECT_GE(worlds_with_curves, 9u);
}

TEST(StreetSim, DeterministicPerSeed) {
  const sim::StreetSimOptions o = small_options();
  const sim::SlamMapPair a = sim::simulate_street_pair(o), b = sim::simulate_street_pair(o);
  EXPECT_EQ(a.source.positions(), b.source.positions());
  EXPECT_EQ(a.target.positions(), b.target.positions());
  EXPECT_EQ(a.target.covariances_m2(), b.target.covariances_m2());
  sim::StreetSimOptions other = o;
  other.seed = 8;
  EXPECT_FALSE(sim::simulate_street_pair(other).target.positions() == a.target.positions());
  // The world's centre line is the seed's alone: a longer one extends a shorter one.
  const std::vector<Vec3> short_line = sim::street_centre_line(7, 100.0, 0.5);
  const std::vector<Vec3> long_line = sim::street_centre_line(7, 300.0, 0.5);
  ASSERT_EQ(short_line.size(), 201u);
  for (std::size_t i = 0; i < short_line.size(); ++i) EXPECT_EQ(short_line[i], long_line[i]);
}

// p_target = T_target_source * p_source; windows: each in its first keyframe's frame, placed by
// T_world_map, consecutive windows' shared keyframes at the same world poses.
TEST(StreetSim, TrueTransformsRelateTheMaps) {
  sim::StreetSimOptions o = small_options();
  const sim::SlamMapPair plain = sim::simulate_street_pair(o);
  o.T_target_source = pose_from_xyz_rpy_deg(5, 2, -30, 3, -2, 120);
  const sim::SlamMapPair moved = sim::simulate_street_pair(o);
  ASSERT_TRUE(moved.T_target_source.isApprox(o.T_target_source));
  test::expect_source_moved(plain, moved);
  o.T_target_source = Isometry3::Identity();
  const sim::StreetWindows w = sim::simulate_street_windows(o, 3);
  ASSERT_EQ(w.maps.size(), 3u);
  ASSERT_EQ(w.T_world_map.size(), 3u);
  const std::size_t stride = o.window_frames - 8;  // round(0.25 * 30) = 8 shared
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_LT(w.maps[k].frames.front().p_world_camera.norm(), 1e-9);
    EXPECT_LT(rotation_angle_deg(w.maps[k].frames.front().T_world_camera().linear()), 1e-6);
    if (k == 0) continue;
    for (std::size_t f = 0; f < 8; ++f) {
      const Vec3 a = w.T_world_map[k - 1] * w.maps[k - 1].frames[stride + f].p_world_camera;
      const Vec3 b = w.T_world_map[k] * w.maps[k].frames[f].p_world_camera;
      EXPECT_LT((a - b).norm(), 1e-9);
    }
  }
  // The pair is windows 0 and 1 of the same drive: its target is window 1 in the world frame.
  const Map target = transform_map(w.maps[1], w.T_world_map[1]);
  ASSERT_EQ(target.frames.size(), plain.target.frames.size());
  EXPECT_LT((target.frames[5].p_world_camera - plain.target.frames[5].p_world_camera).norm(), 1e-9);
}

TEST(StreetSim, InvalidOptionsNamed) {
  using Change = test::OptionChange<sim::StreetSimOptions>;
  test::expect_each_change_named(
      small_options(), [](const sim::StreetSimOptions& o) { sim::simulate_street_pair(o); },
      {Change{[](auto& o) { o.overlap = 0.8; }, "overlap"},
       Change{[](auto& o) { o.overlap = std::nan(""); }, "overlap"},
       Change{[](auto& o) { o.num_landmarks = 3; }, "num_landmarks"},
       Change{[](auto& o) { o.window_frames = 1; }, "window_frames"},
       Change{[](auto& o) { o.min_range_m = 200.0; }, "max_range_m"},
       Change{[](auto& o) { o.pixel_sigma_px = 0.0; }, "pixel_sigma_px"},
       // more than a window sees
       Change{[](auto& o) { o.num_landmarks = 900000; }, "fewer than the 900000 landmarks"}});
  EXPECT_THROW(sim::simulate_street_windows(small_options(), 1), InvalidArgument);
  EXPECT_THROW(sim::street_centre_line(1, -1.0), InvalidArgument);
}

}  // namespace
}  // namespace lmalign
