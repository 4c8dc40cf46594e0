#include "lmalign/sim/slam_sim.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "draws.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/map/camera.hpp"

namespace lmalign::sim {

namespace {

constexpr double kWidthM = 2.0;         // corridor width (walls at y = 0 and y = kWidthM)
constexpr double kWallHeightM = 2.2;    // walls from z = 0 to this
constexpr double kFrameStepM = 0.2;     // keyframe spacing along the corridor
constexpr double kMinLookAheadM = 0.3;  // a frame observes landmarks 0.3 .. 3 m ahead of it
constexpr double kMaxLookAheadM = 3.0;

// A rectangle in the world: origin + a * u + b * v for a, b in [0, 1].
struct Patch {
  Vec3 origin;
  Vec3 u;
  Vec3 v;
  double area_m2;
};

using detail::mix;
using detail::place_with_ray_noise;

Patch patch(const Vec3& o, const Vec3& u, const Vec3& v) { return {o, u, v, u.cross(v).norm()}; }

// The surfaces of corridor metre m (x in [m, m + 1]): floor, both walls, and 1-2 boxes whose
// sizes and places depend only on (seed, m).
void metre_patches(std::int64_t m, std::uint64_t seed, std::vector<Patch>& out) {
  const double x0 = static_cast<double>(m);
  out.push_back(patch({x0, 0, 0}, {1, 0, 0}, {0, kWidthM, 0}));             // floor
  out.push_back(patch({x0, 0, 0}, {1, 0, 0}, {0, 0, kWallHeightM}));        // wall y = 0
  out.push_back(patch({x0, kWidthM, 0}, {1, 0, 0}, {0, 0, kWallHeightM}));  // wall y = W
  std::mt19937_64 rng(mix(seed ^ mix(static_cast<std::uint64_t>(m) + 0x51ed270b)));
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const int boxes = 1 + (u(rng) < 0.5 ? 1 : 0);
  for (int b = 0; b < boxes; ++b) {
    const double bx = x0 + 0.5 * u(rng), len = 0.15 + 0.35 * u(rng);
    const double depth = 0.25 + 0.35 * u(rng), h = 0.35 + 0.9 * u(rng);
    const bool left = u(rng) < 0.5;  // against wall y = 0, or y = W
    const double y_front = left ? depth : kWidthM - depth;
    const double y_wall = left ? 0.0 : kWidthM;
    const double y_lo = std::min(y_front, y_wall);
    out.push_back(patch({bx, y_lo, h}, {len, 0, 0}, {0, depth, 0}));      // top
    out.push_back(patch({bx, y_front, 0}, {len, 0, 0}, {0, 0, h}));       // front
    out.push_back(patch({bx, y_lo, 0}, {0, depth, 0}, {0, 0, h}));        // side facing -x
    out.push_back(patch({bx + len, y_lo, 0}, {0, depth, 0}, {0, 0, h}));  // side facing +x
  }
}

// Camera-to-world pose of the keyframe at corridor position x: near the middle, 1.3 m high,
// looking ahead and swinging +-34 degrees to both walls.
Isometry3 keyframe_pose(double x) {
  const double yaw = 0.6 * std::sin(0.5 * x), pitch = -0.15;
  const Vec3 forward(std::cos(yaw) * std::cos(pitch), std::sin(yaw) * std::cos(pitch),
                     std::sin(pitch));
  const Vec3 right = forward.cross(Vec3::UnitZ()).normalized();
  const Vec3 down = forward.cross(right);
  Isometry3 T = Isometry3::Identity();
  T.linear().col(0) = right;
  T.linear().col(1) = down;
  T.linear().col(2) = forward;
  T.translation() =
      Vec3(x, 0.5 * kWidthM + 0.25 * std::sin(0.7 * x), 1.3 + 0.1 * std::sin(1.3 * x));
  return T;
}

// One session: the stretch of corridor from x_start that holds `n` landmarks at the density.
// `world_seed` fixes the furniture (the same for both sessions), `session_seed` the draws.
Map simulate_session(double x_start, std::size_t n, double density, std::uint64_t world_seed,
                     std::uint64_t session_seed) {
  // Surfaces, metre by metre, until their area holds n landmarks.
  std::vector<Patch> patches;
  std::vector<double> cumulative;
  double area = 0.0;
  const auto m0 = static_cast<std::int64_t>(std::floor(x_start));
  std::int64_t m = m0;
  while (area * density < static_cast<double>(n) || m == m0) {
    std::vector<Patch> ps;
    metre_patches(m, world_seed, ps);
    for (Patch& p : ps) {
      area += p.area_m2;
      patches.push_back(p);
      cumulative.push_back(area);
    }
    ++m;
  }
  const double x_end = static_cast<double>(m);

  // Keyframes from kMaxLookAheadM before the stretch to its end.
  Map map;
  const double first_frame_x = static_cast<double>(m0) - kMaxLookAheadM;
  const auto num_frames = static_cast<std::size_t>((x_end - first_frame_x) / kFrameStepM) + 1;
  std::vector<Isometry3> T_world_camera(num_frames);
  map.frames.resize(num_frames);
  for (std::size_t f = 0; f < num_frames; ++f) {
    T_world_camera[f] = keyframe_pose(first_frame_x + kFrameStepM * static_cast<double>(f));
    map.frames[f].id = static_cast<Id>(f);
    map.frames[f].q_world_camera = Quat(T_world_camera[f].linear());
    map.frames[f].p_world_camera = T_world_camera[f].translation();
  }

  const PinholeIntrinsics K = PinholeIntrinsics::tum_fr1();
  std::mt19937_64 rng(mix(session_seed));
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::poisson_distribution<int> extra_obs(1.5);
  std::vector<std::pair<std::size_t, Landmark>> made;  // (last frame, landmark)
  made.reserve(n);
  while (made.size() < n) {
    // A true point on a surface, uniform over the area.
    const double pick = unit(rng) * area;
    const std::size_t pi = static_cast<std::size_t>(
        std::upper_bound(cumulative.begin(), cumulative.end(), pick) - cumulative.begin());
    const Patch& p = patches[std::min(pi, patches.size() - 1)];
    const Vec3 P = p.origin + unit(rng) * p.u + unit(rng) * p.v;

    // Observed by 2..8 consecutive keyframes 0.3 .. 3 m behind it.
    const double lo_x = P.x() - kMaxLookAheadM, hi_x = P.x() - kMinLookAheadM;
    const auto f_lo = static_cast<std::size_t>(std::ceil((lo_x - first_frame_x) / kFrameStepM));
    const auto f_hi = static_cast<std::size_t>(std::floor((hi_x - first_frame_x) / kFrameStepM));
    const std::size_t window = f_hi - f_lo + 1;
    const std::size_t nobs = std::min<std::size_t>(2 + std::min(6, extra_obs(rng)), window);
    const std::size_t first =
        f_lo + static_cast<std::size_t>(unit(rng) * static_cast<double>(window - nobs + 1));
    Landmark lm;
    for (std::size_t f = first; f < first + nobs; ++f) {
      const Vec3 pc = T_world_camera[f].inverse() * P;
      Eigen::Vector2d px = pc.z() > 0.05 ? K.project(pc) : Eigen::Vector2d(K.cx_px, K.cy_px);
      px += Eigen::Vector2d(0.5 * gauss(rng), 0.5 * gauss(rng));
      lm.observations.push_back({static_cast<Id>(f), px.x(), px.y()});
    }
    // Position: back-projected from the last observation, with RGB-D depth noise along the ray.
    const Isometry3& T_last = T_world_camera[first + nobs - 1];
    const Vec3 ray = (P - T_last.translation()).normalized();
    const double z = std::max(0.3, (P - T_last.translation()).norm());
    const double sigma_z = 0.0012 + 0.0019 * (z - 0.4) * (z - 0.4);
    const double sigma_l = z * 1.5 / K.fx_px;
    place_with_ray_noise(lm, P, ray, sigma_l, sigma_z, [&] { return gauss(rng); });
    made.emplace_back(first + nobs - 1, std::move(lm));
  }
  // Creation order, as a SLAM system would number them: by the frame that made them.
  std::stable_sort(made.begin(), made.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  map.landmarks.reserve(n);
  for (std::size_t i = 0; i < made.size(); ++i) {
    made[i].second.id = static_cast<Id>(i);
    map.landmarks.push_back(std::move(made[i].second));
  }
  return map;
}

// The length of corridor a session of n landmarks covers from x = 0.
double session_length(std::size_t n, double density, std::uint64_t seed) {
  double area = 0.0;
  std::int64_t m = 0;
  std::vector<Patch> ps;
  while (area * density < static_cast<double>(n) || m == 0) {
    ps.clear();
    metre_patches(m, seed, ps);
    for (const Patch& p : ps) area += p.area_m2;
    ++m;
  }
  // Interpolate within the last metre.
  const double last = [&] {
    double a = 0.0;
    for (const Patch& p : ps) a += p.area_m2;
    return a;
  }();
  const double excess = area * density - static_cast<double>(n);
  return static_cast<double>(m) - std::clamp(excess / (last * density), 0.0, 1.0);
}

}  // namespace

bool SlamSimOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& msg) {
    if (why != nullptr) *why = msg;
    return false;
  };
  if (num_landmarks < 10) return fail("num_landmarks must be >= 10");
  if (!(density_per_m2 > 0.0) || !std::isfinite(density_per_m2)) {
    return fail("density_per_m2 must be > 0");
  }
  if (!(overlap > 0.0 && overlap <= 1.0)) return fail("overlap must be in (0, 1]");
  if (!is_finite(T_target_source)) return fail("T_target_source must be finite");
  return true;
}

SlamMapPair simulate_map_pair(const SlamSimOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("slam simulator options: " + why);
  const double length = session_length(options.num_landmarks, options.density_per_m2, options.seed);
  SlamMapPair pair;
  pair.T_target_source = options.T_target_source;
  // Target session (world frame) from x = 0; source session starts where the overlap begins.
  pair.target = simulate_session(0.0, options.num_landmarks, options.density_per_m2, options.seed,
                                 mix(options.seed + 1));
  const Map source_world =
      simulate_session((1.0 - options.overlap) * length, options.num_landmarks,
                       options.density_per_m2, options.seed, mix(options.seed + 2));
  pair.source = transform_map(source_world, options.T_target_source.inverse());
  return pair;
}

}  // namespace lmalign::sim
