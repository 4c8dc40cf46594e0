// Outdoor stereo road scenes (road_sim.hpp). Every draw comes from one std::mt19937_64 per
// session through explicit formulas (uniform01, Box-Muller), so the maps are the same with any
// standard library.
#include "lmalign/sim/road_sim.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "draws.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"

namespace lmalign::sim {

namespace {

constexpr double kImageWidthPx = 1242.0;
constexpr double kImageHeightPx = 375.0;
constexpr double kPixelSigmaPx = 0.5;     // pixel noise of observations and across the ray
constexpr double kLaneX = 1.75;           // camera path: right lane
constexpr double kGridM = 3.0;            // window grid on the facades
constexpr double kDashPeriodM = 9.0;      // lane-centre dash every 9 m ...
constexpr double kDashLengthM = 3.0;      // ... 3 m long
constexpr double kEdgeLineX = 3.5;        // edge lines at x = -/+ 3.5 m
constexpr double kTextureStepM = 1.5;     // regular ground texture
constexpr double kTextureJitterM = 0.15;  // per texture node, per axis
constexpr double kWindowJitterM = 0.10;   // per window corner, per axis

using detail::gauss;
using detail::mix;
using detail::place_with_ray_noise;
using detail::uniform01;

Isometry3 keyframe_pose(double z) {
  const double x = kLaneX + 0.3 * std::sin(0.05 * z);
  const double yaw = std::atan(0.3 * 0.05 * std::cos(0.05 * z));  // along the path's tangent
  Isometry3 T = Isometry3::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Vec3::UnitY()).toRotationMatrix();
  T.translation() = Vec3(x, 0.0, z);
  return T;
}

// A deterministic number in [0, 1) for a feature of the world: (seed, kind, cell index, salt).
double world_hash01(std::uint64_t seed, std::uint64_t kind, std::int64_t cell, std::uint64_t salt) {
  const std::uint64_t h =
      mix(seed ^ mix(kind * 0x9e3779b97f4a7c15ULL ^ mix(static_cast<std::uint64_t>(cell) ^ salt)));
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

// The world's buildings: blocks of kGridM * 4 = 12 m along the road; each block's facade stands
// facade_offset_m + [-1.5, 1.5] m from the road centre (per side and block).
constexpr double kBlockM = 12.0;
double facade_x(const RoadSimOptions& o, double side, double z) {
  const auto block = static_cast<std::int64_t>(std::floor(z / kBlockM));
  return side *
         (o.facade_offset_m + 3.0 * (world_hash01(o.seed, side > 0 ? 1 : 2, block, 0) - 0.5));
}

// A true landmark position with z in [z0, z0 + length]; false if the draw fell outside the
// pattern (the caller draws again). The pattern (window corners, texture nodes, their jitter, the
// facades' setbacks and which windows exist) depends on options.seed only: both sessions see the
// same world. Points anywhere on a wall are drawn per session, as surface samples.
bool draw_point(const RoadSimOptions& o, double z0, double length, std::mt19937_64& rng, Vec3* P) {
  const double ground_y = o.camera_height_m;
  const double z = z0 + length * uniform01(rng);
  if (uniform01(rng) < o.ground_fraction) {
    const double kind = uniform01(rng);
    if (kind < 0.4) {  // lane-centre dash
      const double phase = z - kDashPeriodM * std::floor(z / kDashPeriodM);
      if (phase > kDashLengthM) return false;
      *P = Vec3(0.075 * (2.0 * uniform01(rng) - 1.0), ground_y, z);
    } else if (kind < 0.7) {  // edge lines
      const double side = uniform01(rng) < 0.5 ? -1.0 : 1.0;
      *P = Vec3(side * kEdgeLineX + 0.075 * (2.0 * uniform01(rng) - 1.0), ground_y, z);
    } else {  // regular texture: a node of a 1.5 m grid, jittered per node
      const auto ix = static_cast<std::int64_t>(std::floor(5.0 * uniform01(rng)));
      const auto iz = static_cast<std::int64_t>(std::round(z / kTextureStepM));
      const std::int64_t cell = iz * 8 + ix;
      const double gx = -3.0 + kTextureStepM * static_cast<double>(ix) +
                        kTextureJitterM * (2.0 * world_hash01(o.seed, 3, cell, 1) - 1.0);
      const double gz = kTextureStepM * static_cast<double>(iz) +
                        kTextureJitterM * (2.0 * world_hash01(o.seed, 3, cell, 2) - 1.0);
      if (gz < z0 || gz > z0 + length) return false;
      *P = Vec3(gx, ground_y, gz);
    }
    return true;
  }
  const double side = uniform01(rng) < 0.5 ? -1.0 : 1.0;
  if (uniform01(rng) < 0.5) {  // anywhere on the wall
    *P = Vec3(facade_x(o, side, z), ground_y - o.facade_height_m * uniform01(rng), z);
    return true;
  }
  // A window corner: windows 1.2 m wide, 1.5 m high, on a 3 m grid from 1 m above the ground;
  // 70% of the grid's cells have a window.
  const int levels = std::max(1, static_cast<int>(std::floor((o.facade_height_m - 2.5) / kGridM)));
  const int level = std::min(levels - 1, static_cast<int>(uniform01(rng) * levels));
  const auto column = static_cast<std::int64_t>(std::floor(z / kGridM));
  const std::int64_t cell = (column * 64 + level) * 2 + (side > 0 ? 1 : 0);
  if (world_hash01(o.seed, 4, cell, 0) > 0.7) return false;
  const int corner = static_cast<int>(4.0 * uniform01(rng));
  const double cz = kGridM * static_cast<double>(column) + ((corner & 1) != 0 ? 1.2 : 0.0) +
                    kWindowJitterM * (2.0 * world_hash01(o.seed, 4, cell, 1 + corner) - 1.0);
  const double h = 1.0 + kGridM * level + ((corner & 2) != 0 ? 1.5 : 0.0) +
                   kWindowJitterM * (2.0 * world_hash01(o.seed, 4, cell, 5 + corner) - 1.0);
  if (cz < z0 || cz > z0 + length) return false;
  *P = Vec3(facade_x(o, side, cz), ground_y - h, cz);
  return true;
}

// True if the keyframe T_world_camera sees P with both cameras, at a depth in the range; the
// left pixel in *px.
bool sees(const RoadSimOptions& o, const Isometry3& T_world_camera, const Vec3& P,
          Eigen::Vector2d* px) {
  const Vec3 pc = T_world_camera.inverse() * P;
  if (pc.z() < o.min_range_m || pc.z() > o.max_range_m) return false;
  *px = o.intrinsics().project(pc);
  const double u_right = px->x() - o.fx_px * o.baseline_m / pc.z();
  return px->x() >= 0.0 && px->x() < kImageWidthPx && u_right >= 0.0 && px->y() >= 0.0 &&
         px->y() < kImageHeightPx;
}

// One session: keyframes every frame_step_m along the stretch [z0, z0 + L] of road, and the
// landmarks they see (z in [z0 + min_range, z0 + L + max_range]).
Map simulate_session(const RoadSimOptions& o, double z0, std::uint64_t session_seed) {
  const double L = o.stretch_length_m;
  const double first_z = z0;
  const auto num_frames = static_cast<std::size_t>(std::floor(L / o.frame_step_m)) + 1;
  Map map;
  std::vector<Isometry3> T_world_camera(num_frames);
  map.frames.resize(num_frames);
  for (std::size_t f = 0; f < num_frames; ++f) {
    T_world_camera[f] = keyframe_pose(first_z + o.frame_step_m * static_cast<double>(f));
    map.frames[f].id = static_cast<Id>(f);
    map.frames[f].q_world_camera = Quat(T_world_camera[f].linear());
    map.frames[f].p_world_camera = T_world_camera[f].translation();
  }
  const double lm_z0 = z0 + o.min_range_m;
  const double lm_length = L + o.max_range_m - o.min_range_m;

  const PinholeIntrinsics K = o.intrinsics();
  std::mt19937_64 rng(mix(session_seed));
  std::vector<std::pair<std::size_t, Landmark>> made;  // (last frame, landmark)
  made.reserve(o.num_landmarks);
  const std::size_t max_attempts = 200 * o.num_landmarks + 10000;
  std::size_t attempts = 0;
  std::vector<std::size_t> visible;
  std::vector<Eigen::Vector2d> pixels;
  while (made.size() < o.num_landmarks) {
    if (++attempts > max_attempts) {
      throw InvalidArgument(
          "road simulator: could not place " + std::to_string(o.num_landmarks) +
          " observable landmarks (is the range or the image too small for the scene?)");
    }
    Vec3 P;
    if (!draw_point(o, lm_z0, lm_length, rng, &P)) continue;
    // Keyframes whose position along the road can see P at a range in [min, max].
    const double lo = (P.z() - o.max_range_m - first_z) / o.frame_step_m;
    const double hi = (P.z() - o.min_range_m - first_z) / o.frame_step_m + 1.0;
    const auto f_lo = static_cast<std::size_t>(std::max(0.0, std::floor(lo)));
    const auto f_hi = std::min(num_frames, static_cast<std::size_t>(std::max(0.0, std::ceil(hi))));
    visible.clear();
    pixels.clear();
    for (std::size_t f = f_lo; f < f_hi; ++f) {
      Eigen::Vector2d px;
      if (sees(o, T_world_camera[f], P, &px)) {
        visible.push_back(f);
        pixels.push_back(px);
      }
    }
    if (visible.size() < 2) continue;
    // 2..max_observations consecutive visible keyframes.
    const std::size_t want =
        2 + static_cast<std::size_t>(uniform01(rng) * static_cast<double>(o.max_observations - 1));
    const std::size_t nobs = std::min(want, visible.size());
    const std::size_t start =
        static_cast<std::size_t>(uniform01(rng) * static_cast<double>(visible.size() - nobs + 1));
    Landmark lm;
    for (std::size_t i = start; i < start + nobs; ++i) {
      const Eigen::Vector2d px =
          pixels[i] + Eigen::Vector2d(kPixelSigmaPx * gauss(rng), kPixelSigmaPx * gauss(rng));
      lm.observations.push_back({static_cast<Id>(visible[i]), px.x(), px.y()});
    }
    // Stereo triangulation from the last (closest) observation.
    const Isometry3& T_last = T_world_camera[visible[start + nobs - 1]];
    const double depth = (T_last.inverse() * P).z();
    const Vec3 ray = (P - T_last.translation()).normalized();
    const double sigma_along = depth * depth * o.disparity_sigma_px / (K.fx_px * o.baseline_m);
    const double sigma_across = depth * kPixelSigmaPx / K.fx_px;
    place_with_ray_noise(lm, P, ray, sigma_across, sigma_along, [&] { return gauss(rng); });
    made.emplace_back(visible[start + nobs - 1], std::move(lm));
  }
  // Creation order, as a SLAM system numbers them: by the frame that made them.
  std::stable_sort(made.begin(), made.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  map.landmarks.reserve(made.size());
  for (std::size_t i = 0; i < made.size(); ++i) {
    made[i].second.id = static_cast<Id>(i);
    map.landmarks.push_back(std::move(made[i].second));
  }
  return map;
}

bool positive_finite(double v) { return std::isfinite(v) && v > 0.0; }

}  // namespace

bool RoadSimOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& msg) {
    if (why != nullptr) *why = msg;
    return false;
  };
  if (num_landmarks < 10 || num_landmarks > 10000000)
    return fail("num_landmarks must be in [10, 10000000]");
  if (!(overlap >= 0.0 && overlap <= 0.5)) return fail("overlap must be in [0, 0.5]");
  if (!positive_finite(stretch_length_m)) return fail("stretch_length_m must be > 0");
  if (!positive_finite(fx_px)) return fail("fx_px must be > 0");
  if (!positive_finite(baseline_m)) return fail("baseline_m must be > 0");
  if (!positive_finite(disparity_sigma_px)) return fail("disparity_sigma_px must be > 0");
  if (!positive_finite(camera_height_m)) return fail("camera_height_m must be > 0");
  if (!positive_finite(frame_step_m)) return fail("frame_step_m must be > 0");
  if (!positive_finite(min_range_m) || !std::isfinite(max_range_m) || max_range_m <= min_range_m)
    return fail("min_range_m and max_range_m must satisfy 0 < min_range_m < max_range_m");
  if (max_observations < 2) return fail("max_observations must be >= 2");
  if (!(std::isfinite(facade_offset_m) && facade_offset_m > 5.0))
    return fail("facade_offset_m must be > 5");
  if (!positive_finite(facade_height_m)) return fail("facade_height_m must be > 0");
  if (!(ground_fraction >= 0.0 && ground_fraction <= 1.0))
    return fail("ground_fraction must be in [0, 1]");
  if (stretch_length_m / frame_step_m > 1e6)
    return fail("stretch_length_m / frame_step_m must be <= 1e6 keyframes");
  if (!is_finite(T_target_source)) return fail("T_target_source must be finite");
  return true;
}

SlamMapPair simulate_road_pair(const RoadSimOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("road simulator options: " + why);
  SlamMapPair pair;
  pair.T_target_source = options.T_target_source;
  const double L = options.stretch_length_m;
  pair.target = simulate_session(options, (1.0 - options.overlap) * L, mix(options.seed + 1));
  const Map source_world = simulate_session(options, 0.0, mix(options.seed + 2));
  pair.source = transform_map(source_world, options.T_target_source.inverse());
  return pair;
}

}  // namespace lmalign::sim
