// A synthetic RGB-D sequence rendered by the tests themselves: the textured walls, floor and
// ceiling of a box room, seen along a known smooth trajectory, written as a TUM RGB-D folder
// (rgb.txt, depth.txt, groundtruth.txt, PNGs) with seeded image and depth noise.
#pragma once

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <random>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "lmalign/core/geometry.hpp"
#include "lmalign/eval/trajectory.hpp"
#include "lmalign/map/camera.hpp"

namespace lmalign::test {

struct SyntheticRoom {
  // Axis-aligned box: the camera frame convention (x right, y down, z forward) at the identity.
  Vec3 lo{-2.5, -1.5, -2.0};
  Vec3 hi{2.5, 1.2, 3.0};

  // Deterministic hash -> [0, 1).
  static double hash(std::int64_t a, std::int64_t b, std::int64_t c) {
    std::uint64_t h = static_cast<std::uint64_t>(a) * 0x9E3779B97F4A7C15ULL ^
                      static_cast<std::uint64_t>(b) * 0xC2B2AE3D27D4EB4FULL ^
                      static_cast<std::uint64_t>(c) * 0x165667B19E3779F9ULL;
    h ^= h >> 33;
    h *= 0xFF51AFD7ED558CCDULL;
    h ^= h >> 33;
    h *= 0xC4CEB9FE1A85EC53ULL;
    h ^= h >> 33;
    return static_cast<double>(h >> 11) / 9007199254740992.0;
  }

  // Texture of plane `p` at in-plane coordinates (a, b), metres: random grey patches at two
  // scales, so that patch corners make strong, well-localised ORB corners.
  static double texture(int p, double a, double b) {
    const double s1 = 0.12, s2 = 0.045;
    const double c1 = hash(p, static_cast<std::int64_t>(std::floor(a / s1)),
                           static_cast<std::int64_t>(std::floor(b / s1)));
    const double c2 = hash(p + 17, static_cast<std::int64_t>(std::floor(a / s2)),
                           static_cast<std::int64_t>(std::floor(b / s2)));
    return 30.0 + 150.0 * c1 + 70.0 * c2;
  }

  // Casts the ray origin + s * dir (s > 0); returns the distance along dir and the texture value.
  bool cast(const Vec3& origin, const Vec3& dir, double& s_hit, double& value) const {
    s_hit = std::numeric_limits<double>::infinity();
    int plane = -1;
    for (int axis = 0; axis < 3; ++axis) {
      if (std::abs(dir[axis]) < 1e-12) continue;
      for (int side = 0; side < 2; ++side) {
        const double wall = side == 0 ? lo[axis] : hi[axis];
        const double s = (wall - origin[axis]) / dir[axis];
        if (s > 1e-9 && s < s_hit) {
          s_hit = s;
          plane = 2 * axis + side;
        }
      }
    }
    if (plane < 0) return false;
    const Vec3 x = origin + s_hit * dir;
    const int axis = plane / 2;
    const double a = x[(axis + 1) % 3], b = x[(axis + 2) % 3];
    value = texture(plane, a, b);
    return true;
  }
};

/// Ground-truth pose of frame i (30 Hz): a smooth sweep around the room centre.
inline Isometry3 synthetic_pose(std::size_t i) {
  const double t = static_cast<double>(i) / 30.0;
  const double w = 2.0 * M_PI / 8.0;
  const double x = 0.5 * std::sin(w * t), y = -0.1 + 0.05 * std::sin(2 * w * t),
               z = -0.4 + 0.3 * (1.0 - std::cos(w * t));
  const double yaw_deg = 25.0 * std::sin(w * t), pitch_deg = 5.0 * std::sin(1.3 * w * t);
  // Camera convention: yaw about the world y axis (down), pitch about x.
  Isometry3 T = Isometry3::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Vec3::UnitY()) *
                Eigen::AngleAxisd(pitch_deg * M_PI / 180.0, Vec3::UnitX()))
                   .toRotationMatrix();
  T.translation() = Vec3(x, y, z);
  return T;
}

inline double synthetic_timestamp(std::size_t i) { return 1000.0 + static_cast<double>(i) / 30.0; }

struct SyntheticSequenceOptions {
  std::size_t frames = 100;
  int width = 640, height = 480;
  PinholeIntrinsics k = PinholeIntrinsics::tum_fr1();
  double image_noise_sigma = 2.0;     ///< grey levels
  double depth_sigma_coeff = 0.0015;  ///< depth noise sigma = coeff * z^2, metres
  unsigned seed = 42;
};

/// Renders the sequence into `folder` (created). Depth: 16-bit PNG, 5000 units per metre.
inline void render_synthetic_sequence(const std::string& folder,
                                      const SyntheticSequenceOptions& o = {}) {
  namespace fs = std::filesystem;
  fs::create_directories(fs::path(folder) / "rgb");
  fs::create_directories(fs::path(folder) / "depth");
  const SyntheticRoom room;
  std::ofstream rgb_list(fs::path(folder) / "rgb.txt"), depth_list(fs::path(folder) / "depth.txt"),
      gt_list(fs::path(folder) / "groundtruth.txt");
  rgb_list << "# color images\n# timestamp filename\n";
  depth_list << "# depth maps\n# timestamp filename\n";
  gt_list << "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n";
  rgb_list << std::fixed << std::setprecision(6);
  depth_list << std::fixed << std::setprecision(6);
  gt_list << std::setprecision(17);
  std::mt19937 rng(o.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (std::size_t i = 0; i < o.frames; ++i) {
    const Isometry3 T = synthetic_pose(i);
    const Vec3 c = T.translation();
    const Mat3 R = T.linear();
    cv::Mat grey(o.height, o.width, CV_8UC1), depth(o.height, o.width, CV_16UC1);
    // One ray per pixel centre gives the depth and the texture; a small blur then stands in for
    // the optics' anti-aliasing, so that ORB corners localise smoothly.
    cv::Mat clean(o.height, o.width, CV_32FC1);
    for (int v = 0; v < o.height; ++v) {
      for (int u = 0; u < o.width; ++u) {
        double s = 0, value = 0;
        room.cast(c, R * o.k.unproject(u, v), s, value);  // s = depth z (unit-z ray)
        clean.at<float>(v, u) = static_cast<float>(value);
        const double z = s + o.depth_sigma_coeff * s * s * normal(rng);
        depth.at<std::uint16_t>(v, u) =
            static_cast<std::uint16_t>(std::clamp(std::lround(z * 5000.0), 0L, 65535L));
      }
    }
    cv::GaussianBlur(clean, clean, cv::Size(5, 5), 0.8);
    for (int v = 0; v < o.height; ++v) {
      for (int u = 0; u < o.width; ++u) {
        const double g = clean.at<float>(v, u) + o.image_noise_sigma * normal(rng);
        grey.at<std::uint8_t>(v, u) =
            static_cast<std::uint8_t>(std::clamp(std::lround(g), 0L, 255L));
      }
    }
    cv::Mat colour;
    cv::Mat channels[3] = {grey, grey, grey};
    cv::merge(channels, 3, colour);
    char name[64];
    std::snprintf(name, sizeof(name), "%.6f.png", synthetic_timestamp(i));
    cv::imwrite((fs::path(folder) / "rgb" / name).string(), colour);
    cv::imwrite((fs::path(folder) / "depth" / name).string(), depth);
    rgb_list << synthetic_timestamp(i) << " rgb/" << name << "\n";
    depth_list << synthetic_timestamp(i) << " depth/" << name << "\n";
    const Quat q(R);
    gt_list << synthetic_timestamp(i) << ' ' << c.x() << ' ' << c.y() << ' ' << c.z() << ' '
            << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << "\n";
  }
}

/// True surface point seen at pixel (u, v) from camera pose T_world_camera.
inline Vec3 synthetic_surface_point(const Isometry3& T_wc, const PinholeIntrinsics& k, double u,
                                    double v) {
  const SyntheticRoom room;
  double s = 0, value = 0;
  const Vec3 ray = T_wc.linear() * k.unproject(u, v);
  room.cast(T_wc.translation(), ray, s, value);
  return T_wc.translation() + s * ray;
}

}  // namespace lmalign::test
