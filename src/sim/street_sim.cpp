// Aperiodic streets seen by a KITTI-like stereo camera (street_sim.hpp). The world comes from one
// std::mt19937_64 seeded by the seed alone, the drive's keyframes from a second, and each window's
// noise and landmark selection from its own; every draw goes through the explicit formulas of
// draws.hpp, in a fixed order.
#include "lmalign/sim/street_sim.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "draws.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"

namespace lmalign::sim {

namespace {

using detail::gauss;
using detail::mix;
using detail::uniform01;

constexpr double kImageWidthPx = 1242.0;
constexpr double kImageHeightPx = 375.0;
constexpr double kPathStepM = 0.25;        // sampling of the centre line
constexpr double kLaneM = 1.75;            // the camera's lane centre, right of the centre line
constexpr double kMinDisparityPx = 1.0;    // a noisier observation is not made
constexpr double kDetectionDepthM = 10.0;  // detection weight min(1, (10 m / z)^2)
constexpr double kInnerLimit = 0.6;        // nothing nearer a curve's centre than 0.6 radius
constexpr double kDeg = M_PI / 180.0;

// Salts of the independent streams.
constexpr std::uint64_t kWorldStream = 0x5354524545545701ULL;
constexpr std::uint64_t kDriveStream = 0x5354524545545702ULL;
constexpr std::uint64_t kWindowStream = 0x5354524545545703ULL;

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return lo + (hi - lo) * uniform01(rng);
}

// ----------------------------------------------------------------------------- the centre line

struct Segment {
  double start_s = 0.0;
  double length = 0.0;
  double curvature = 0.0;  // d heading / ds, 1/m; > 0 turns toward +x (the right)
  double start_heading = 0.0;
};

// The road's centre line: samples every kPathStepM of arc length (position on y = 0, heading
// about +y from +z, curvature), from segments drawn by the world's stream.
class CentreLine {
 public:
  CentreLine(std::uint64_t stream_seed, double length_m) {
    std::mt19937_64 rng(stream_seed);
    // The headings allowed: [-45, 90] deg or its mirror, per world; so the road never comes
    // back across the view of its earlier keyframes (no U around a block).
    const double bias = uniform01(rng) < 0.5 ? -1.0 : 1.0;
    auto allowed = [&](double h) {
      return bias * h >= -45.0 * kDeg - 1e-9 && bias * h <= 90.0 * kDeg + 1e-9;
    };
    double s = 0.0, heading = 0.0;
    bool straight_next = false;
    while (s < length_m + kPathStepM) {
      Segment g;
      g.start_s = s;
      g.start_heading = heading;
      const double kind = uniform01(rng);
      const double a = uniform01(rng), b = uniform01(rng), c = uniform01(rng);
      const bool turn = kind >= 0.8;
      const double radius = turn ? 10.0 + 6.0 * a : 60.0 + 190.0 * a;
      const double angle = turn ? 90.0 * kDeg : (10.0 + 35.0 * b) * kDeg;
      double sign = c < 0.5 ? -1.0 : 1.0;
      if (!allowed(heading + sign * angle)) sign = -sign;
      if (straight_next || kind < 0.45 || !allowed(heading + sign * angle)) {
        // A straight (also where neither way of a turn keeps the heading allowed).
        g.length = straight_next ? 30.0 + 50.0 * a : 20.0 + 60.0 * a;
        straight_next = false;
      } else {
        g.length = radius * angle;
        g.curvature = sign / radius;
        heading += sign * angle;
        straight_next = turn;
      }
      s += g.length;
      segments_.push_back(g);
    }
    const auto n = static_cast<std::size_t>(std::floor(length_m / kPathStepM)) + 2;
    x_.resize(n);
    z_.resize(n);
    for (std::size_t i = 1; i < n; ++i) {  // midpoint heading: exact chords on straights
      const double mid = heading_at((static_cast<double>(i) - 0.5) * kPathStepM);
      x_[i] = x_[i - 1] + kPathStepM * std::sin(mid);
      z_[i] = z_[i - 1] + kPathStepM * std::cos(mid);
    }
  }

  const Segment& segment_at(double s) const {
    auto it = std::upper_bound(segments_.begin(), segments_.end(), s,
                               [](double v, const Segment& g) { return v < g.start_s; });
    return it == segments_.begin() ? segments_.front() : *(it - 1);
  }
  double heading_at(double s) const {
    const Segment& g = segment_at(s);
    return g.start_heading + g.curvature * (std::max(s, 0.0) - g.start_s);
  }
  double curvature_at(double s) const { return s < 0.0 ? 0.0 : segment_at(s).curvature; }
  // Centre point at arc length s (linear between samples; straight ahead before 0).
  Vec3 point_at(double s) const {
    if (s <= 0.0) return Vec3(0.0, 0.0, s);
    const double f = s / kPathStepM;
    const auto i = std::min(static_cast<std::size_t>(f), x_.size() - 2);
    const double t = f - static_cast<double>(i);
    return Vec3(x_[i] + t * (x_[i + 1] - x_[i]), 0.0, z_[i] + t * (z_[i + 1] - z_[i]));
  }

 private:
  std::vector<Segment> segments_;
  std::vector<double> x_{0.0}, z_{0.0};
};

Vec3 right_of(double heading) { return Vec3(std::cos(heading), 0.0, -std::sin(heading)); }
Vec3 ahead_of(double heading) { return Vec3(std::sin(heading), 0.0, std::cos(heading)); }

// ----------------------------------------------------------------------------- the world

struct Feature {
  Vec3 p = Vec3::Zero();
  Vec3 normal = Vec3::Zero();  // the side it is seen from; zero: from everywhere
};

class World {
 public:
  // Each kind of object on each side has its own stream, so a longer world extends a shorter
  // one of the same seed (the centre line's stream is street_centre_line()'s).
  World(std::uint64_t seed, double camera_height_m, double length_m)
      : line_(mix(seed ^ kWorldStream), length_m + 60.0), height_(camera_height_m) {
    std::uint64_t stream = mix(seed ^ kWorldStream);
    rng_.seed(++stream);
    phase_pitch_ = uniform(rng_, 0.0, 2.0 * M_PI);
    phase_roll_ = uniform(rng_, 0.0, 2.0 * M_PI);
    phase_sway_ = uniform(rng_, 0.0, 2.0 * M_PI);
    const double s0 = -30.0, s1 = length_m;
    for (const double side : {-1.0, 1.0}) {
      rng_.seed(++stream);
      lots(side, s0, s1);
      rng_.seed(++stream);
      trees(side, s0, s1);
      rng_.seed(++stream);
      poles(side, s0, s1);
      rng_.seed(++stream);
      cars(side, s0, s1);
    }
    rng_.seed(++stream);
    ground(s0, s1);
  }

  const CentreLine& line() const { return line_; }
  const std::vector<Feature>& features() const { return features_; }

  // The keyframe at arc length s: right lane, swaying; pitch and roll oscillating.
  Isometry3 camera_at(double s) const {
    const double heading = line_.heading_at(s);
    const double lateral = kLaneM + 0.2 * std::sin(2.0 * M_PI * s / 60.0 + phase_sway_);
    const double pitch = 0.4 * kDeg * std::sin(2.0 * M_PI * s / 37.0 + phase_pitch_);
    const double roll = 0.3 * kDeg * std::sin(2.0 * M_PI * s / 53.0 + phase_roll_);
    Isometry3 T = Isometry3::Identity();
    T.linear() = (Eigen::AngleAxisd(heading, Vec3::UnitY()) *
                  Eigen::AngleAxisd(pitch, Vec3::UnitX()) * Eigen::AngleAxisd(roll, Vec3::UnitZ()))
                     .toRotationMatrix();
    T.translation() = line_.point_at(s) + lateral * right_of(heading);
    return T;
  }

 private:
  // A point d metres right of the centre line at arc length s, h metres above the ground; false
  // (nothing added) on the inside of a curve nearer its centre than kInnerLimit of its radius.
  bool at(double s, double d, double h, Vec3* p) const {
    if (line_.curvature_at(s) * d > kInnerLimit) return false;
    *p = line_.point_at(s) + d * right_of(line_.heading_at(s)) + Vec3(0.0, height_ - h, 0.0);
    return true;
  }
  void add(double s, double d, double h, int facing) {
    // facing: 0 seen from everywhere; +-1 a wall facing the road (its normal toward the centre
    // line, for a wall on side sign(d)); +-2 a side wall facing ahead (+2) or back (-2).
    Feature f;
    if (!at(s, d, h, &f.p)) return;
    const double heading = line_.heading_at(s);
    if (facing == 1) f.normal = -(d > 0 ? 1.0 : -1.0) * right_of(heading);
    if (facing == 2) f.normal = ahead_of(heading);
    if (facing == -2) f.normal = -ahead_of(heading);
    features_.push_back(f);
  }

  // A side wall at arc length s from |d| = d_near to d_far on `side`, facing ahead or back.
  void side_wall(double side, double s, double d_near, double d_far, double height, int facing) {
    const double area = (d_far - d_near) * height;
    const auto n = static_cast<int>(std::floor(0.8 * area * uniform01(rng_) + 0.5));
    for (int i = 0; i < n; ++i) {
      const double d = uniform(rng_, d_near, d_far), h = uniform(rng_, 0.2, height);
      add(s, side * d, h, facing);
    }
  }

  void lots(double side, double s0, double s1) {
    double s = s0 - 30.0 * uniform01(rng_);
    bool previous_building = false;
    double previous_setback = 0.0, previous_height = 0.0;
    while (s < s1) {
      if (uniform01(rng_) < 0.2) {  // a gap: a side street or an empty lot
        const double width = uniform(rng_, 4.0, 20.0);
        if (previous_building) {  // the last building's end wall, facing ahead into the gap
          side_wall(side, s, previous_setback, previous_setback + 8.0, previous_height, 2);
        }
        s += width;
        previous_building = false;
        continue;
      }
      const double width = uniform(rng_, 6.0, 30.0);
      const double setback = uniform(rng_, 9.0, 18.0);
      const double height = uniform(rng_, 6.0, 22.0);
      const double column = uniform(rng_, 2.2, 4.0);
      const double storey = uniform(rng_, 2.8, 3.6);
      const double window_w = std::min(uniform(rng_, 0.8, 1.6), column - 0.4);
      const double window_h = std::min(uniform(rng_, 1.0, 1.8), storey - 0.6);
      const double first = uniform(rng_, 0.8, 1.5);
      const double fill = uniform(rng_, 0.5, 0.95);
      const double texture_per_m2 = uniform(rng_, 3.0, 10.0);
      // Side walls where the setback changes (seen from behind when this one is nearer).
      if (!previous_building) {
        side_wall(side, s, setback, setback + 8.0, height, -2);
      } else if (setback < previous_setback) {
        side_wall(side, s, setback, previous_setback, height, -2);
      } else {
        side_wall(side, s, previous_setback, setback, previous_height, 2);
      }
      // Window corners, recessed 10 cm, jittered 3 cm.
      const auto columns = static_cast<int>(std::floor((width - 0.6) / column));
      const double margin = 0.5 * (width - columns * column) + 0.5 * (column - window_w);
      for (int c = 0; c < columns; ++c) {
        for (int level = 0; first + level * storey + window_h < height - 0.5; ++level) {
          if (uniform01(rng_) >= fill) continue;
          for (int corner = 0; corner < 4; ++corner) {
            const double cs = s + margin + c * column + ((corner & 1) != 0 ? window_w : 0.0);
            const double ch = first + level * storey + ((corner & 2) != 0 ? window_h : 0.0);
            add(cs + uniform(rng_, -0.03, 0.03), side * (setback + 0.1),
                ch + uniform(rng_, -0.03, 0.03), 1);
          }
        }
      }
      // Texture anywhere on the facade.
      const auto texture = static_cast<int>(std::floor(texture_per_m2 * width * height + 0.5));
      for (int i = 0; i < texture; ++i) {
        add(s + width * uniform01(rng_), side * setback, height * uniform01(rng_), 1);
      }
      // The facade's vertical edges and its roof line, a point every 0.5-1 m.
      for (const double edge : {s, s + width}) {
        for (double h = uniform(rng_, 0.0, 0.5); h < height; h += uniform(rng_, 0.5, 1.0)) {
          add(edge, side * setback, h, 1);
        }
      }
      for (double t = uniform(rng_, 0.0, 0.5); t < width; t += uniform(rng_, 0.5, 1.0)) {
        add(s + t, side * setback, height, 1);
      }
      s += width;
      previous_building = true;
      previous_setback = setback;
      previous_height = height;
    }
  }

  void trees(double side, double s0, double s1) {
    for (double block = s0; block < s1; block += 50.0) {
      const bool has_trees = uniform01(rng_) < 0.5;
      if (!has_trees) continue;
      for (double s = block + uniform(rng_, 0.0, 12.0); s < block + 50.0;
           s += uniform(rng_, 6.0, 18.0)) {
        const double d = side * uniform(rng_, 6.0, 6.8);
        for (int i = 0; i < 5; ++i) {  // the trunk
          add(s + uniform(rng_, -0.2, 0.2), d + uniform(rng_, -0.2, 0.2), uniform(rng_, 0.3, 2.5),
              0);
        }
        const auto crown = static_cast<int>(uniform(rng_, 100.0, 250.0));
        const double radius = uniform(rng_, 1.5, 3.0), centre = uniform(rng_, 4.0, 6.0);
        for (int i = 0; i < crown;) {  // uniform in an ellipsoid (0.8 radius high)
          const double a = uniform(rng_, -1.0, 1.0), b = uniform(rng_, -1.0, 1.0),
                       c = uniform(rng_, -1.0, 1.0);
          if (a * a + b * b + c * c > 1.0) continue;
          add(s + radius * a, d + radius * b, centre + 0.8 * radius * c, 0);
          ++i;
        }
      }
    }
  }

  void poles(double side, double s0, double s1) {
    for (double s = s0 + uniform(rng_, 0.0, 30.0); s < s1; s += uniform(rng_, 25.0, 45.0)) {
      const double d = side * uniform(rng_, 5.8, 6.0), height = uniform(rng_, 6.0, 9.0);
      for (double h = uniform(rng_, 0.2, 0.8); h < height; h += uniform(rng_, 0.6, 1.0)) {
        add(s, d, h, 0);
      }
      for (int i = 1; i <= 3; ++i) add(s, d - side * 0.6 * i, height, 0);  // the lamp arm
    }
  }

  void cars(double side, double s0, double s1) {
    for (double block = s0; block < s1; block += 40.0) {
      if (uniform01(rng_) >= 0.6) continue;
      for (double s = block + uniform(rng_, 0.0, 8.0); s < block + 40.0;) {
        const double length = uniform(rng_, 3.8, 5.0), height = uniform(rng_, 1.4, 1.7);
        const double centre = uniform(rng_, 4.5, 4.7);
        const auto points = static_cast<int>(uniform(rng_, 80.0, 160.0));
        const bool in_turn = std::abs(line_.curvature_at(s)) > 1.0 / 30.0;
        for (int i = 0; i < points; ++i) {  // on the box: its road side, top, ends
          const double face = uniform01(rng_), a = uniform01(rng_), b = uniform01(rng_);
          double ds = a * length, dd = -0.9, h = 0.3 + b * (height - 0.3);
          if (face >= 0.6 && face < 0.8) {
            dd = -0.9 + 1.8 * b;
            h = height;
          } else if (face >= 0.8) {
            ds = a < 0.5 ? 0.0 : length;
            dd = -0.9 + 1.8 * b;
            h = 0.3 + uniform01(rng_) * (height - 0.3);
          }
          if (!in_turn) add(s + ds, side * (centre + dd), h, 0);
        }
        s += length + uniform(rng_, 0.5, 8.0);
      }
    }
  }

  void ground(double s0, double s1) {
    // Lane-centre dashes (3 m every 9 m, the phase drawn per 60 m), their four corners; edge lines
    // and kerbs, a corner every 1-6 m; road texture at a density drawn per 10 m.
    for (double block = s0; block < s1; block += 60.0) {
      const double phase = uniform(rng_, 0.0, 9.0);
      for (double s = block + phase; s < block + 60.0; s += 9.0) {
        for (int corner = 0; corner < 4; ++corner) {
          add(s + ((corner & 1) != 0 ? 3.0 : 0.0), (corner & 2) != 0 ? 0.075 : -0.075, 0.0, 0);
        }
      }
    }
    for (const double d : {-5.6, -3.5, 3.5, 5.6}) {
      const double h = std::abs(d) > 5.0 ? 0.15 : 0.0;  // kerb top
      for (double s = s0 + uniform(rng_, 0.0, 3.0); s < s1; s += uniform(rng_, 1.0, 6.0)) {
        add(s, d + uniform(rng_, -0.05, 0.05), h, 0);
      }
    }
    for (double block = s0; block < s1; block += 10.0) {
      const double density = uniform(rng_, 0.5, 3.0);
      const auto n = static_cast<int>(std::floor(density * 10.0 * 11.2 + 0.5));
      for (int i = 0; i < n; ++i) {
        add(block + 10.0 * uniform01(rng_), uniform(rng_, -5.6, 5.6), 0.0, 0);
      }
    }
  }

  CentreLine line_;
  std::mt19937_64 rng_;
  double height_;
  double phase_pitch_ = 0.0, phase_roll_ = 0.0, phase_sway_ = 0.0;
  std::vector<Feature> features_;
};

// ----------------------------------------------------------------------------- the drive

// The arc lengths of the drive's keyframes: every frame_step_m +- 10%.
std::vector<double> keyframe_arcs(const StreetSimOptions& o, std::size_t count) {
  std::mt19937_64 rng(mix(o.seed ^ kDriveStream));
  std::vector<double> s(count, 0.0);
  for (std::size_t i = 1; i < count; ++i) {
    s[i] = s[i - 1] + o.frame_step_m * (1.0 + 0.1 * (2.0 * uniform01(rng) - 1.0));
  }
  return s;
}

struct Candidate {
  std::size_t feature = 0;
  std::vector<std::size_t> frames;        // window-local keyframe indices, consecutive
  std::vector<Eigen::Vector3d> measured;  // (u, u_R, v) px, noisy
  double key = 0.0;                       // Efraimidis-Spirakis: log(u) / weight, the largest kept
};

// One window: keyframes T_world_camera (world frame) and the world; its map in the world frame,
// and each landmark's true position in *truth.
Map map_window(const StreetSimOptions& o, const World& world,
               const std::vector<Isometry3>& T_world_camera, std::uint64_t window_seed,
               Points3* truth) {
  const PinholeIntrinsics K = o.intrinsics();
  const double fb = o.fx_px * o.baseline_m;
  const std::size_t F = T_world_camera.size();
  std::vector<Isometry3> T_camera_world(F);
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (std::size_t f = 0; f < F; ++f) {
    T_camera_world[f] = T_world_camera[f].inverse();
    lo = lo.cwiseMin(T_world_camera[f].translation());
    hi = hi.cwiseMax(T_world_camera[f].translation());
  }
  // Within max_range_m of depth a point is at most this far from the camera (image corners).
  const double reach = o.max_range_m * std::sqrt(1.0 + std::pow(0.5 * kImageWidthPx / K.fx_px, 2) +
                                                 std::pow(0.5 * kImageHeightPx / K.fy_px, 2));
  lo.array() -= reach;
  hi.array() += reach;

  std::mt19937_64 rng(mix(window_seed));
  std::vector<Candidate> candidates;
  std::vector<std::size_t> visible;
  const std::vector<Feature>& features = world.features();
  for (std::size_t i = 0; i < features.size(); ++i) {
    const Feature& ft = features[i];
    if ((ft.p.array() < lo.array()).any() || (ft.p.array() > hi.array()).any()) continue;
    visible.clear();
    for (std::size_t f = 0; f < F; ++f) {
      const Vec3& centre = T_world_camera[f].translation();
      if (!ft.normal.isZero() && ft.normal.dot(centre - ft.p) <= 0.0) continue;
      const Vec3 pc = T_camera_world[f] * ft.p;
      if (pc.z() < o.min_range_m || pc.z() > o.max_range_m) continue;
      const Eigen::Vector2d px = K.project(pc);
      const double u_right = px.x() - fb / pc.z();
      if (px.x() < 0.0 || px.x() >= kImageWidthPx || u_right < 0.0 || px.y() < 0.0 ||
          px.y() >= kImageHeightPx) {
        continue;
      }
      visible.push_back(f);
    }
    // The longest run of consecutive keyframes (the first of equal ones): the feature's track.
    std::size_t best_start = 0, best_length = 0;
    for (std::size_t a = 0; a < visible.size();) {
      std::size_t b = a + 1;
      while (b < visible.size() && visible[b] == visible[b - 1] + 1) ++b;
      if (b - a > best_length) {
        best_start = a;
        best_length = b - a;
      }
      a = b;
    }
    if (best_length < 2) continue;
    const std::size_t want =
        2 + static_cast<std::size_t>(uniform01(rng) * static_cast<double>(o.max_observations - 1));
    const std::size_t n = std::min(want, best_length);
    const std::size_t start =
        best_start +
        static_cast<std::size_t>(uniform01(rng) * static_cast<double>(best_length - n + 1));
    Candidate c;
    c.feature = i;
    double last_depth = 0.0;
    for (std::size_t k = start; k < start + n; ++k) {
      const std::size_t f = visible[k];
      const Vec3 pc = T_camera_world[f] * ft.p;
      const Eigen::Vector2d px = K.project(pc);
      const Eigen::Vector3d m(px.x() + o.pixel_sigma_px * gauss(rng),
                              px.x() - fb / pc.z() + o.pixel_sigma_px * gauss(rng),
                              px.y() + o.pixel_sigma_px * gauss(rng));
      if (m.x() - m.y() < kMinDisparityPx) break;  // the track ends (stereo match lost)
      c.frames.push_back(f);
      c.measured.push_back(m);
      last_depth = pc.z();
    }
    const double u = 1.0 - uniform01(rng);  // (0, 1]
    if (c.frames.size() < 2) continue;
    const double weight = std::pow(kDetectionDepthM / std::max(last_depth, kDetectionDepthM), 2);
    c.key = std::log(u) / weight;
    candidates.push_back(std::move(c));
  }
  if (candidates.size() < o.num_landmarks) {
    throw InvalidArgument("street simulator: a window sees " + std::to_string(candidates.size()) +
                          " features, fewer than the " + std::to_string(o.num_landmarks) +
                          " landmarks asked for (fewer landmarks, or more window_frames)");
  }
  // The num_landmarks largest keys (ties: the lower feature index), then in creation order.
  std::vector<std::size_t> order(candidates.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::partial_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(o.num_landmarks),
                    order.end(), [&](std::size_t a, std::size_t b) {
                      if (candidates[a].key != candidates[b].key)
                        return candidates[a].key > candidates[b].key;
                      return a < b;
                    });
  order.resize(o.num_landmarks);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (candidates[a].frames.back() != candidates[b].frames.back())
      return candidates[a].frames.back() < candidates[b].frames.back();
    return a < b;
  });

  Map map;
  map.frames.resize(F);
  for (std::size_t f = 0; f < F; ++f) {
    map.frames[f].id = static_cast<Id>(f);
    map.frames[f].q_world_camera = Quat(T_world_camera[f].linear());
    map.frames[f].p_world_camera = T_world_camera[f].translation();
  }
  map.landmarks.reserve(order.size());
  truth->clear();
  const double sigma2 = o.pixel_sigma_px * o.pixel_sigma_px;
  for (const std::size_t ci : order) {
    const Candidate& c = candidates[ci];
    Landmark lm;
    lm.id = static_cast<Id>(map.landmarks.size());
    Mat3 information = Mat3::Zero();
    Vec3 weighted = Vec3::Zero();
    for (std::size_t k = 0; k < c.frames.size(); ++k) {
      const double u = c.measured[k].x(), u_right = c.measured[k].y(), v = c.measured[k].z();
      const double d = u - u_right;
      // Stereo back-projection p = (b (u - cx) / d, b fx (v - cy) / (fy d), fx b / d) and its
      // Jacobian with respect to (u, u_R, v).
      const double b = o.baseline_m, xu = u - K.cx_px, yv = (v - K.cy_px) * K.fx_px / K.fy_px;
      const Vec3 pc(b * xu / d, b * yv / d, fb / d);
      Mat3 J;
      J << b / d - b * xu / (d * d), b * xu / (d * d), 0.0,                  //
          -b * yv / (d * d), b * yv / (d * d), b * K.fx_px / (K.fy_px * d),  //
          -fb / (d * d), fb / (d * d), 0.0;
      const Isometry3& T = T_world_camera[c.frames[k]];
      const Mat3 R = T.linear();
      const Mat3 C = R * (sigma2 * J * J.transpose()) * R.transpose();
      const Mat3 W = C.inverse();
      information += W;
      weighted += W * (T * pc);
      lm.observations.push_back({static_cast<Id>(c.frames[k]), u, v});
    }
    Mat3 cov = information.inverse();
    cov = (0.5 * (cov + cov.transpose())).eval();
    lm.cov_world_m2 = cov;
    lm.p_world = cov * weighted;
    map.landmarks.push_back(std::move(lm));
    truth->push_back(features[c.feature].p);
  }
  return map;
}

std::size_t window_stride(const StreetSimOptions& o) {
  const auto shared =
      static_cast<std::size_t>(std::llround(o.overlap * static_cast<double>(o.window_frames)));
  return std::max<std::size_t>(1, o.window_frames - shared);
}

void check(const StreetSimOptions& o) {
  std::string why;
  if (!o.is_valid(&why)) throw InvalidArgument("street simulator options: " + why);
}

std::vector<Map> simulate_windows(const StreetSimOptions& o, std::size_t num_windows,
                                  std::vector<Points3>* truth) {
  const std::size_t stride = window_stride(o);
  const std::size_t total = stride * (num_windows - 1) + o.window_frames;
  const std::vector<double> arcs = keyframe_arcs(o, total);
  // The world reaches beyond the last keyframe by more than any point a window can see.
  const double reach = o.max_range_m * std::sqrt(1.0 + std::pow(0.5 * kImageWidthPx / o.fx_px, 2) +
                                                 std::pow(0.5 * kImageHeightPx / o.fx_px, 2));
  const World world(o.seed, o.camera_height_m, arcs.back() + 1.5 * reach + 30.0);
  std::vector<Map> maps;
  truth->assign(num_windows, {});
  for (std::size_t w = 0; w < num_windows; ++w) {
    std::vector<Isometry3> T(o.window_frames);
    for (std::size_t f = 0; f < o.window_frames; ++f) T[f] = world.camera_at(arcs[w * stride + f]);
    maps.push_back(map_window(o, world, T, mix(o.seed ^ kWindowStream) + w, &(*truth)[w]));
  }
  return maps;
}

bool positive_finite(double v) { return std::isfinite(v) && v > 0.0; }

}  // namespace

bool StreetSimOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& msg) {
    if (why != nullptr) *why = msg;
    return false;
  };
  if (num_landmarks < 10 || num_landmarks > 1000000)
    return fail("num_landmarks must be in [10, 1000000]");
  if (!(overlap >= 0.0 && overlap <= 0.75)) return fail("overlap must be in [0, 0.75]");
  if (window_frames < 2 || window_frames > 100000)
    return fail("window_frames must be in [2, 100000]");
  if (!(positive_finite(frame_step_m) && frame_step_m <= 10.0))
    return fail("frame_step_m must be in (0, 10]");
  if (!positive_finite(fx_px)) return fail("fx_px must be > 0");
  if (!positive_finite(baseline_m)) return fail("baseline_m must be > 0");
  if (!positive_finite(pixel_sigma_px)) return fail("pixel_sigma_px must be > 0");
  if (!(positive_finite(camera_height_m) && camera_height_m < 100.0))
    return fail("camera_height_m must be in (0, 100)");
  if (!positive_finite(min_range_m) || !std::isfinite(max_range_m) || max_range_m <= min_range_m ||
      max_range_m > 1000.0)
    return fail("min_range_m and max_range_m must satisfy 0 < min_range_m < max_range_m <= 1000");
  if (max_observations < 2 || max_observations > 1000)
    return fail("max_observations must be in [2, 1000]");
  if (!is_finite(T_target_source)) return fail("T_target_source must be finite");
  return true;
}

SlamMapPair simulate_street_pair(const StreetSimOptions& options) {
  check(options);
  std::vector<Points3> truth;
  std::vector<Map> maps = simulate_windows(options, 2, &truth);
  SlamMapPair pair;
  pair.T_target_source = options.T_target_source;
  pair.target = std::move(maps[1]);
  pair.source = transform_map(maps[0], options.T_target_source.inverse());
  return pair;
}

StreetWindows simulate_street_windows(const StreetSimOptions& options, std::size_t num_windows) {
  check(options);
  if (num_windows < 2 || num_windows > 10000) {
    throw InvalidArgument("street simulator: num_windows must be in [2, 10000], got " +
                          std::to_string(num_windows));
  }
  StreetWindows out;
  std::vector<Points3> truth;
  std::vector<Map> maps = simulate_windows(options, num_windows, &truth);
  for (std::size_t k = 0; k < maps.size(); ++k) {
    const Isometry3 T_world_map = maps[k].frames.front().T_world_camera();
    out.maps.push_back(transform_map(maps[k], T_world_map.inverse()));
    out.T_world_map.push_back(T_world_map);
    out.true_positions.push_back(transform_points(T_world_map.inverse(), truth[k]));
  }
  return out;
}

std::vector<Vec3> street_centre_line(std::uint64_t seed, double length_m, double step_m) {
  if (!(positive_finite(length_m) && length_m <= 1e6) || !positive_finite(step_m) ||
      length_m / step_m > 1e8) {
    throw InvalidArgument("street_centre_line: length_m must be in (0, 1e6] and step_m > 0");
  }
  const CentreLine line(mix(seed ^ kWorldStream), length_m + 60.0);  // as World's
  std::vector<Vec3> out;
  for (double s = 0.0; s <= length_m + 1e-9; s += step_m) out.push_back(line.point_at(s));
  return out;
}

}  // namespace lmalign::sim
