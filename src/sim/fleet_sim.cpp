// The synthetic multi-robot fleet (include/lmalign/sim/fleet_sim.hpp).
#include "lmalign/sim/fleet_sim.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <unordered_map>
#include <unordered_set>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"

namespace lmalign::sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kFocalPx = 500.0;  // pinhole of the keyframes (640 x 480 px, centred)
constexpr int kRingKeyframes = 8;
constexpr int kRoamingKeyframes = 24;
// FleetViews::kRoaming: a keyframe sees a landmark at most about 84 deg from its surface's
// normal (cosine 0.1).
constexpr double kMinFacing = 0.1;

struct WorldPoint {
  Vec3 p;
  Id id;
  Vec3 n = Vec3::UnitZ();  ///< outward unit normal of the surface the landmark lies on
};

Isometry3 yaw_pose(double yaw_rad, const Vec3& t) {
  Isometry3 T = Isometry3::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_rad, Vec3::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

double terrain(double x, double y) { return 0.15 * std::sin(x / 7.0) + 0.1 * std::cos(y / 9.0); }

}  // namespace

bool FleetSimOptions::is_valid(std::string* why) const {
  auto bad = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (num_maps < 2 || num_maps > 100000) return bad("num_maps must be in [2, 100000]");
  if (!(map_radius_m > 0.0) || !std::isfinite(map_radius_m)) return bad("map_radius_m must be > 0");
  if (!(spacing_factor >= 0.3 && spacing_factor <= 2.0)) {
    return bad("spacing_factor must be in [0.3, 2]");
  }
  if (!(ground_density_per_m2 >= 0.0 && ground_density_per_m2 < 1e4)) {
    return bad("ground_density_per_m2 must be in [0, 1e4)");
  }
  if (!(object_density_per_m2 >= 0.0 && object_density_per_m2 < 10.0)) {
    return bad("object_density_per_m2 must be in [0, 10)");
  }
  if (!(surface_density_per_m2 >= 0.0 && surface_density_per_m2 < 1e4)) {
    return bad("surface_density_per_m2 must be in [0, 1e4)");
  }
  if (!(detection_probability > 0.0 && detection_probability <= 1.0)) {
    return bad("detection_probability must be in (0, 1]");
  }
  if (!(position_sigma_m > 0.0) || !std::isfinite(position_sigma_m)) {
    return bad("position_sigma_m must be > 0");
  }
  const bool no_prior = prior_sigma_deg == 0.0 && prior_sigma_m == 0.0;
  const bool prior = prior_sigma_deg > 0.0 && prior_sigma_m > 0.0 &&
                     std::isfinite(prior_sigma_deg) && std::isfinite(prior_sigma_m);
  if (!no_prior && !prior) return bad("prior_sigma_deg and prior_sigma_m must both be 0 or > 0");
  if (!(min_overlap > 0.0 && min_overlap <= 1.0)) return bad("min_overlap must be in (0, 1]");
  if (views != FleetViews::kRing && views != FleetViews::kRoaming) {
    return bad("views must be kRing or kRoaming");
  }
  return true;
}

namespace {

// The draws of one simulate_fleet(), in their order (same seed, same scene): the uniform and the
// normal distribution (the latter keeps a second value between draws).
struct Draws {
  explicit Draws(std::uint64_t seed) : rng(seed) {}
  std::mt19937_64 rng;
  std::uniform_real_distribution<double> u01_dist{0.0, 1.0};
  std::normal_distribution<double> gauss_dist{0.0, 1.0};
  double u01() { return u01_dist(rng); }
  double gauss() { return gauss_dist(rng); }
};

// Map centres on a jittered grid.
std::vector<Vec3> map_centres(const FleetSimOptions& o, Draws& d) {
  const double r = o.map_radius_m;
  const std::size_t n = o.num_maps;
  const std::size_t cols = static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(n))));
  const double spacing = o.spacing_factor * r;
  std::vector<Vec3> centres(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double jx = (d.u01() - 0.5) * 0.4 * spacing;
    const double jy = (d.u01() - 0.5) * 0.4 * spacing;
    centres[i] = Vec3(static_cast<double>(i % cols) * spacing + jx,
                      static_cast<double>(i / cols) * spacing + jy, 0.0);
  }
  return centres;
}

// The world: ground landmarks and boxes over the maps' extent, heights from a smooth random
// field; ids from 0.
std::vector<WorldPoint> world_points(const FleetSimOptions& o, const std::vector<Vec3>& centres,
                                     Draws& d, Id* next_id_out) {
  const double r = o.map_radius_m;
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (const Vec3& c : centres) {
    x0 = std::min(x0, c.x() - 2.0 * r);
    y0 = std::min(y0, c.y() - 2.0 * r);
    x1 = std::max(x1, c.x() + 2.0 * r);
    y1 = std::max(y1, c.y() + 2.0 * r);
  }
  const double area = (x1 - x0) * (y1 - y0);

  // The world: ground landmarks and boxes, heights from a smooth random field.
  std::vector<WorldPoint> world;
  Id& next_id = *next_id_out;
  const std::size_t num_ground = static_cast<std::size_t>(o.ground_density_per_m2 * area);
  for (std::size_t k = 0; k < num_ground; ++k) {
    const double x = x0 + d.u01() * (x1 - x0);
    const double y = y0 + d.u01() * (y1 - y0);
    world.push_back({Vec3(x, y, terrain(x, y)), next_id++, Vec3::UnitZ()});
  }
  const double ph1 = 2.0 * kPi * d.u01(), ph2 = 2.0 * kPi * d.u01();
  const double ph3 = 2.0 * kPi * d.u01();
  auto height_field = [&](double x, double y) {
    const double s = 0.5 + 0.2 * std::sin(x / (1.7 * r) + ph1) +
                     0.2 * std::cos(y / (1.3 * r) + ph2) +
                     0.1 * std::sin((x + y) / (0.9 * r) + ph3);
    return 0.5 + 5.5 * std::clamp(s, 0.0, 1.0);
  };
  const std::size_t num_boxes = static_cast<std::size_t>(o.object_density_per_m2 * area);
  for (std::size_t b = 0; b < num_boxes; ++b) {
    const double cx = x0 + d.u01() * (x1 - x0);
    const double cy = y0 + d.u01() * (y1 - y0);
    const double sx = 0.5 + 2.0 * d.u01(), sy = 0.5 + 2.0 * d.u01();
    const double h = height_field(cx, cy) * (0.6 + 0.8 * d.u01());
    const double yaw = 2.0 * kPi * d.u01();
    const double base = terrain(cx, cy);
    const Mat3 R = Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix();
    // Four walls and the top, landmarks uniform on each face.
    const double faces[5] = {sx * h, sx * h, sy * h, sy * h, sx * sy};
    for (int f = 0; f < 5; ++f) {
      const std::size_t count =
          static_cast<std::size_t>(faces[f] * o.surface_density_per_m2 + d.u01());
      for (std::size_t k = 0; k < count; ++k) {
        const double a = d.u01() - 0.5, c = d.u01();
        Vec3 q, normal;
        switch (f) {
          case 0:
            q = Vec3(a * sx, -0.5 * sy, c * h);
            normal = -Vec3::UnitY();
            break;
          case 1:
            q = Vec3(a * sx, 0.5 * sy, c * h);
            normal = Vec3::UnitY();
            break;
          case 2:
            q = Vec3(-0.5 * sx, a * sy, c * h);
            normal = -Vec3::UnitX();
            break;
          case 3:
            q = Vec3(0.5 * sx, a * sy, c * h);
            normal = Vec3::UnitX();
            break;
          default:
            q = Vec3(a * sx, (c - 0.5) * sy, h);
            normal = Vec3::UnitZ();
            break;
        }
        world.push_back({Vec3(cx, cy, base) + R * q, next_id++, R * normal});
      }
    }
  }

  return world;
}

// Twins: the world around map b replaced by a turned copy of the world around map a.
void plant_twins(const FleetSimOptions& o, const std::vector<Vec3>& centres, Draws& d,
                 std::vector<WorldPoint>* world_io, Id* next_id_io, FleetScene* scene_out) {
  const double r = o.map_radius_m;
  const std::size_t n = o.num_maps;
  std::vector<WorldPoint>& world = *world_io;
  Id& next_id = *next_id_io;
  FleetScene& scene = *scene_out;
  const double twin_radius = 1.6 * r;
  std::vector<std::size_t> used;
  for (std::size_t t = 0; t < o.num_twins; ++t) {
    bool placed = false;
    for (int attempt = 0; attempt < 200 && !placed; ++attempt) {
      std::size_t a = static_cast<std::size_t>(d.u01() * static_cast<double>(n)) % n;
      std::size_t b = static_cast<std::size_t>(d.u01() * static_cast<double>(n)) % n;
      if ((centres[a] - centres[b]).norm() <= 2.0 * twin_radius) continue;
      bool clear = true;
      for (std::size_t u : used) {
        if ((centres[u] - centres[a]).norm() <= 2.0 * twin_radius ||
            (centres[u] - centres[b]).norm() <= 2.0 * twin_radius) {
          clear = false;
        }
      }
      if (!clear) continue;
      const Vec3 ca = centres[a], cb = centres[b];
      const Mat3 R = Eigen::AngleAxisd(2.0 * kPi * d.u01(), Vec3::UnitZ()).toRotationMatrix();
      std::vector<WorldPoint> kept, copies;
      for (const WorldPoint& w : world) {
        const double da = (w.p - ca).head<2>().norm();
        const double db = (w.p - cb).head<2>().norm();
        if (db > twin_radius) kept.push_back(w);
        if (da <= twin_radius) {
          Vec3 q = R * (w.p - ca) + cb;
          q.z() = w.p.z();
          copies.push_back({q, next_id++, R * w.n});
        }
      }
      kept.insert(kept.end(), copies.begin(), copies.end());
      world = std::move(kept);
      used.push_back(a);
      used.push_back(b);
      scene.twins.emplace_back(std::min(a, b), std::max(a, b));
      placed = true;
    }
  }
  std::sort(scene.twins.begin(), scene.twins.end());
}

// Each map: what it sees, in its own frame (`seen`: the world ids it holds).
void observe_maps(const FleetSimOptions& o, const std::vector<Vec3>& centres,
                  const std::vector<WorldPoint>& world, Draws& d, FleetScene* scene_out,
                  std::vector<std::unordered_set<Id>>* seen_out) {
  const double r = o.map_radius_m;
  const std::size_t n = o.num_maps;
  FleetScene& scene = *scene_out;
  std::vector<std::unordered_set<Id>>& seen = *seen_out;
  scene.maps.resize(n);
  scene.names.resize(n);
  scene.T_world_map.resize(n);
  seen.assign(n, {});
  for (std::size_t i = 0; i < n; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "map_%03zu", i);
    scene.names[i] = name;
    const Vec3 c = centres[i];
    const Isometry3 T_world_map =
        yaw_pose(2.0 * kPi * d.u01() - kPi,
                 c + Vec3(10.0 * (d.u01() - 0.5), 10.0 * (d.u01() - 0.5), d.u01() - 0.5));
    scene.T_world_map[i] = T_world_map;
    const Isometry3 T_map_world = T_world_map.inverse();
    Map& m = scene.maps[i];
    const bool roaming = o.views == FleetViews::kRoaming;
    const int num_keyframes = roaming ? kRoamingKeyframes : kRingKeyframes;
    std::vector<Isometry3> cameras(num_keyframes, Isometry3::Identity());  // T_world_camera
    for (int k = 0; k < num_keyframes; ++k) {
      // kRing: on a circle of 0.3 r, looking out; kRoaming: uniform over the disc of 0.7 r,
      // any heading (three draws per keyframe).
      const double a = 2.0 * kPi * k / num_keyframes;
      Vec3 at = c + 0.3 * r * Vec3(std::cos(a), std::sin(a), 0.0);
      Vec3 heading(std::cos(a), std::sin(a), 0.0);
      if (roaming) {
        const double rho = 0.7 * r * std::sqrt(d.u01());
        const double phi = 2.0 * kPi * d.u01();
        const double yaw = 2.0 * kPi * d.u01();
        at = c + rho * Vec3(std::cos(phi), std::sin(phi), 0.0);
        heading = Vec3(std::cos(yaw), std::sin(yaw), 0.0);
      }
      Mat3 R;  // camera axes in the world: x right, y down, z forward
      R.col(2) = heading;
      R.col(1) = -Vec3::UnitZ();
      R.col(0) = R.col(1).cross(R.col(2));
      Frame f;
      f.id = k;
      const Vec3 p = at + Vec3(0, 0, terrain(c.x(), c.y()) + 1.5);
      cameras[k].linear() = R;
      cameras[k].translation() = p;
      f.p_world_camera = T_map_world * p;
      f.q_world_camera = Quat(T_map_world.linear() * R);
      m.frames.push_back(f);
    }
    const Mat3 cov = Mat3::Identity() * (o.position_sigma_m * o.position_sigma_m);
    for (const WorldPoint& w : world) {
      if ((w.p - c).head<2>().norm() > r) continue;
      if (d.u01() >= o.detection_probability) continue;
      Landmark l;
      l.id = w.id;
      const Vec3 noise(d.gauss(), d.gauss(), d.gauss());
      l.p_world = T_map_world * (w.p + o.position_sigma_m * noise);
      l.cov_world_m2 = T_map_world.linear() * cov * T_map_world.linear().transpose();
      // Two observations: the two keyframes looking most directly at it (pinhole pixels of the
      // true point; maps need >= 2 observations per landmark to be read). kRoaming: a keyframe
      // sees it only from the front of its surface.
      std::vector<std::pair<double, int>> facing;
      for (int k = 0; k < num_keyframes; ++k) {
        const Vec3 q = cameras[k].inverse() * w.p;
        if (!(q.z() > 0.1)) continue;
        if (roaming) {
          const Vec3 to_camera = cameras[k].translation() - w.p;
          if (!(to_camera.dot(w.n) > kMinFacing * to_camera.norm())) continue;
        }
        facing.emplace_back(-q.z() / q.norm(), k);
      }
      if (facing.size() < 2) continue;
      std::partial_sort(facing.begin(), facing.begin() + 2, facing.end());
      for (int v = 0; v < 2; ++v) {
        const Vec3 q = cameras[facing[v].second].inverse() * w.p;
        l.observations.push_back(
            {facing[v].second, kFocalPx * q.x() / q.z() + 320.0, kFocalPx * q.y() / q.z() + 240.0});
      }
      m.landmarks.push_back(l);
      seen[i].insert(w.id);
    }
  }
}

// Noisy priors of the maps' poses (when asked).
void add_priors(const FleetSimOptions& o, Draws& d, FleetScene* scene_out) {
  const std::size_t n = o.num_maps;
  FleetScene& scene = *scene_out;
  if (o.prior_sigma_m > 0.0) {
    // Noise about the map's own origin (a GPS-like heading error turns a map about itself):
    // T_prior = T_true * Exp(xi_map), reported in the world-frame left convention,
    // C_world = Ad(T_prior) C_map Ad(T_prior)^T.
    const double sr = o.prior_sigma_deg * kPi / 180.0;
    Mat6 C_map = Mat6::Zero();
    C_map.diagonal() << Vec3::Constant(o.prior_sigma_m * o.prior_sigma_m), Vec3::Constant(sr * sr);
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3 rho(d.gauss(), d.gauss(), d.gauss());
      const Vec3 phi(d.gauss(), d.gauss(), d.gauss());
      Isometry3 E = Isometry3::Identity();
      const Vec3 phi_rad = sr * phi;
      if (phi_rad.norm() > 0.0) {
        E.linear() = Eigen::AngleAxisd(phi_rad.norm(), phi_rad.normalized()).toRotationMatrix();
      }
      E.translation() = o.prior_sigma_m * rho;
      const Isometry3 T_prior = scene.T_world_map[i] * E;
      const Mat6 A = se3_adjoint(T_prior);
      const Mat6 C = A * C_map * A.transpose();
      scene.prior_T_world_map.push_back(T_prior);
      scene.prior_covariance.push_back(0.5 * (C + C.transpose()));
    }
  }
}

// True overlaps (shared landmark ids) between maps whose discs intersect.
void true_overlaps(const FleetSimOptions& o, const std::vector<Vec3>& centres,
                   const std::vector<std::unordered_set<Id>>& seen, FleetScene* scene_out) {
  const double r = o.map_radius_m;
  const std::size_t n = o.num_maps;
  FleetScene& scene = *scene_out;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      if ((centres[i] - centres[j]).head<2>().norm() >= 2.0 * r) continue;
      std::size_t shared = 0;
      for (Id id : seen[i]) shared += seen[j].count(id);
      const std::size_t smaller = std::min(seen[i].size(), seen[j].size());
      if (smaller == 0) continue;
      const double f = static_cast<double>(shared) / static_cast<double>(smaller);
      if (f >= o.min_overlap) scene.overlaps.push_back({i, j, f});
    }
  }
}

}  // namespace

FleetScene simulate_fleet(const FleetSimOptions& o) {
  std::string why;
  if (!o.is_valid(&why)) throw InvalidArgument("FleetSimOptions: " + why);
  Draws d(o.seed);
  const std::vector<Vec3> centres = map_centres(o, d);
  Id next_id = 0;
  std::vector<WorldPoint> world = world_points(o, centres, d, &next_id);
  FleetScene scene;
  plant_twins(o, centres, d, &world, &next_id, &scene);
  std::vector<std::unordered_set<Id>> seen;
  observe_maps(o, centres, world, d, &scene, &seen);
  add_priors(o, d, &scene);
  true_overlaps(o, centres, seen, &scene);
  return scene;
}

}  // namespace lmalign::sim
