// The RGB-D visual-odometry map builder (include/lmalign/vo/map_builder.hpp,
// docs/map-builder.md). OpenCV (ORB, PnP RANSAC, image I/O) and Ceres (sliding-window BA,
// covariances) stay private to this file.
#include "lmalign/vo/map_builder.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <unordered_map>
#include <unordered_set>

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"

namespace lmalign::vo {

namespace fs = std::filesystem;

bool MapBuilderOptions::is_valid(std::string* why) const {
  auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!camera.is_valid(why)) return false;
  if (orb_features < 10) return fail("orb_features must be >= 10");
  if (!(orb_scale_factor > 1.0) || orb_levels < 1) return fail("bad ORB pyramid settings");
  if (max_descriptor_distance < 0 || max_descriptor_distance > 256) {
    return fail("max_descriptor_distance must be in [0, 256]");
  }
  if (!(match_ratio > 0.0 && match_ratio <= 1.0)) return fail("match_ratio must be in (0, 1]");
  if (!(search_radius_px > 0.0)) return fail("search_radius_px must be > 0");
  if (!(ransac_threshold_px > 0.0) || ransac_iterations < 1) return fail("bad RANSAC settings");
  if (min_inliers < 6) return fail("min_inliers must be >= 6");
  if (!(min_depth_m > 0.0 && max_depth_m > min_depth_m)) {
    return fail("depth range must satisfy 0 < min_depth_m < max_depth_m");
  }
  if (!(keyframe_translation_m > 0.0) || !(keyframe_rotation_deg > 0.0) ||
      !(keyframe_min_tracked_fraction >= 0.0 && keyframe_min_tracked_fraction <= 1.0)) {
    return fail("bad keyframe thresholds");
  }
  if (window_keyframes < 2) return fail("window_keyframes must be >= 2");
  if (ba_iterations < 1) return fail("ba_iterations must be >= 1");
  if (!(pixel_sigma_px > 0.0) || !(depth_sigma_coeff > 0.0)) {
    return fail("pixel_sigma_px and depth_sigma_coeff must be > 0");
  }
  return true;
}

namespace {

using Descriptor = std::array<std::uint64_t, 4>;  // 256-bit ORB

int hamming(const Descriptor& a, const Descriptor& b) {
  int d = 0;
  for (int i = 0; i < 4; ++i) d += __builtin_popcountll(a[i] ^ b[i]);
  return d;
}

struct Obs {
  int keyframe = 0;
  double u = 0.0, v = 0.0;
  double depth_m = 0.0;  // <= 0: no valid depth
  int octave = 0;
  bool outlier = false;
};

struct LandmarkState {
  double p[3] = {0, 0, 0};
  Descriptor desc{};
  std::vector<Obs> obs;
  Mat3 cov = Mat3::Zero();
  bool cov_from_ba = false;
  bool optimised = false;
};

struct KeyframeState {
  double timestamp_s = 0.0;
  double pose[6] = {0, 0, 0, 0, 0, 0};  // T_camera_world: angle-axis, translation
  std::vector<int> landmarks;
};

struct FrameData {
  cv::Mat gray;
  cv::Mat depth;  // CV_16UC1
  std::vector<cv::KeyPoint> keypoints;
  std::vector<double> u, v;  // keypoint pixels: the float values' shortest decimal, as doubles
  std::vector<Descriptor> descriptors;
  std::vector<double> depth_m;  // per keypoint, 0 if invalid
};

// 345.6f -> 345.6 (not 345.6000061035156): the map file then shows the pixel ORB computed.
double float_to_double(float x) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof(buf), x);
  double d = 0.0;
  std::from_chars(buf, r.ptr, d);
  return d;
}

Isometry3 pose_from_block(const double* b) {
  const Eigen::Vector3d aa(b[0], b[1], b[2]);
  Isometry3 T_cw = Isometry3::Identity();
  const double angle = aa.norm();
  if (angle > 0) T_cw.linear() = Eigen::AngleAxisd(angle, aa / angle).toRotationMatrix();
  T_cw.translation() = Vec3(b[3], b[4], b[5]);
  return T_cw.inverse();  // T_world_camera
}

void block_from_pose(const Isometry3& T_wc, double* b) {
  const Isometry3 T_cw = T_wc.inverse();
  const Eigen::AngleAxisd aa(T_cw.rotation());
  const Vec3 v = aa.axis() * aa.angle();
  for (int i = 0; i < 3; ++i) b[i] = v[i];
  for (int i = 0; i < 3; ++i) b[3 + i] = T_cw.translation()[i];
}

struct ReprojectionCost {
  ReprojectionCost(double u, double v, double inv_sigma, const PinholeIntrinsics& k)
      : u(u), v(v), inv_sigma(inv_sigma), k(k) {}
  template <typename T>
  bool operator()(const T* pose, const T* point, T* r) const {
    T pc[3];
    ceres::AngleAxisRotatePoint(pose, point, pc);
    for (int i = 0; i < 3; ++i) pc[i] += pose[3 + i];
    r[0] = (T(k.fx_px) * pc[0] / pc[2] + T(k.cx_px) - T(u)) * T(inv_sigma);
    r[1] = (T(k.fy_px) * pc[1] / pc[2] + T(k.cy_px) - T(v)) * T(inv_sigma);
    return true;
  }
  double u, v, inv_sigma;
  PinholeIntrinsics k;
};

struct DepthCost {
  DepthCost(double depth, double inv_sigma) : depth(depth), inv_sigma(inv_sigma) {}
  template <typename T>
  bool operator()(const T* pose, const T* point, T* r) const {
    T pc[3];
    ceres::AngleAxisRotatePoint(pose, point, pc);
    r[0] = (pc[2] + pose[5] - T(depth)) * T(inv_sigma);
    return true;
  }
  double depth, inv_sigma;
};

class Builder {
 public:
  explicit Builder(const MapBuilderOptions& o) : o_(o), k_(o.camera.pinhole) {
    orb_ = cv::ORB::create(o.orb_features, static_cast<float>(o.orb_scale_factor), o.orb_levels);
  }

  double pixel_sigma(int octave) const {
    return o_.pixel_sigma_px * std::pow(o_.orb_scale_factor, octave);
  }
  double depth_sigma(double d) const { return std::max(0.001, o_.depth_sigma_coeff * d * d); }

  FrameData load(const RgbdFrameRef& ref) const {
    FrameData f;
    auto read = [](const std::string& path, const char* what) {
      if (!fs::exists(path)) {
        throw IoError(std::string("cannot read ") + what + " image '" + path +
                      "': file does not exist");
      }
      cv::Mat m = cv::imread(path, cv::IMREAD_UNCHANGED);
      if (m.empty()) {
        throw IoError(std::string("cannot read ") + what + " image '" + path +
                      "': not a readable image");
      }
      return m;
    };
    cv::Mat rgb = read(ref.rgb_path, "RGB");
    if (rgb.depth() != CV_8U) {
      throw ParseError(ref.rgb_path, 0, "RGB image is not 8-bit per channel");
    }
    if (rgb.cols != o_.camera.width_px || rgb.rows != o_.camera.height_px) {
      throw ParseError(ref.rgb_path, 0,
                       "RGB image is " + std::to_string(rgb.cols) + "x" + std::to_string(rgb.rows) +
                           ", the camera is " + std::to_string(o_.camera.width_px) + "x" +
                           std::to_string(o_.camera.height_px));
    }
    if (rgb.channels() == 3) {
      cv::cvtColor(rgb, f.gray, cv::COLOR_BGR2GRAY);
    } else if (rgb.channels() == 4) {
      cv::cvtColor(rgb, f.gray, cv::COLOR_BGRA2GRAY);
    } else {
      f.gray = rgb;
    }
    f.depth = read(ref.depth_path, "depth");
    if (f.depth.type() != CV_16UC1) {
      throw ParseError(ref.depth_path, 0,
                       "depth image is " + std::to_string(8 * f.depth.elemSize1()) + "-bit with " +
                           std::to_string(f.depth.channels()) +
                           " channel(s), expected 16-bit single-channel (TUM: 5000 units per "
                           "metre)");
    }
    if (f.depth.size() != rgb.size()) {
      throw ParseError(ref.depth_path, 0,
                       "depth image is " + std::to_string(f.depth.cols) + "x" +
                           std::to_string(f.depth.rows) + ", the RGB image " + ref.rgb_path +
                           " is " + std::to_string(rgb.cols) + "x" + std::to_string(rgb.rows));
    }
    cv::Mat desc;
    orb_->detectAndCompute(f.gray, cv::noArray(), f.keypoints, desc);
    f.descriptors.resize(f.keypoints.size());
    f.depth_m.assign(f.keypoints.size(), 0.0);
    for (std::size_t i = 0; i < f.keypoints.size(); ++i) {
      std::memcpy(f.descriptors[i].data(), desc.ptr(static_cast<int>(i)), 32);
      f.u.push_back(float_to_double(f.keypoints[i].pt.x));
      f.v.push_back(float_to_double(f.keypoints[i].pt.y));
      const int u = static_cast<int>(std::lround(f.keypoints[i].pt.x));
      const int v = static_cast<int>(std::lround(f.keypoints[i].pt.y));
      if (u < 0 || v < 0 || u >= f.depth.cols || v >= f.depth.rows) continue;
      const double d = f.depth.at<std::uint16_t>(v, u) / o_.camera.depth_units_per_m;
      if (d >= o_.min_depth_m && d <= o_.max_depth_m) f.depth_m[i] = d;
    }
    return f;
  }

  // Landmarks of the sliding window (the local map), in index order.
  std::vector<int> local_map() const {
    std::vector<int> out;
    const int first = std::max(0, static_cast<int>(kfs_.size()) - o_.window_keyframes);
    for (int k = first; k < static_cast<int>(kfs_.size()); ++k) {
      out.insert(out.end(), kfs_[k].landmarks.begin(), kfs_[k].landmarks.end());
    }
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    return out;
  }

  // Matches local-map landmarks to keypoints (projection-guided within radius, or by descriptor
  // alone if radius is infinite). Returns (keypoint, landmark) pairs.
  std::vector<std::pair<int, int>> match(const FrameData& f, const std::vector<int>& local,
                                         const Isometry3& T_wc_pred, double radius) const {
    const Isometry3 T_cw = T_wc_pred.inverse();
    const double r2 = radius * radius;
    std::vector<int> best_lm(f.keypoints.size(), -1);
    std::vector<int> best_dist(f.keypoints.size(), std::numeric_limits<int>::max());
    for (int l : local) {
      const auto& lm = lms_[l];
      Eigen::Vector2d uv(0, 0);
      const bool guided = std::isfinite(radius);
      if (guided) {
        const Vec3 pc = T_cw * Vec3(lm.p[0], lm.p[1], lm.p[2]);
        if (pc.z() < o_.min_depth_m) continue;
        uv = k_.project(pc);
        if (uv.x() < -radius || uv.y() < -radius || uv.x() > o_.camera.width_px + radius ||
            uv.y() > o_.camera.height_px + radius) {
          continue;
        }
      }
      int best = std::numeric_limits<int>::max(), second = best, best_i = -1;
      for (std::size_t i = 0; i < f.keypoints.size(); ++i) {
        if (guided) {
          const double du = f.keypoints[i].pt.x - uv.x(), dv = f.keypoints[i].pt.y - uv.y();
          if (du * du + dv * dv > r2) continue;
        }
        const int d = hamming(lm.desc, f.descriptors[i]);
        if (d < best) {
          second = best;
          best = d;
          best_i = static_cast<int>(i);
        } else if (d < second) {
          second = d;
        }
      }
      if (best_i < 0 || best > o_.max_descriptor_distance) continue;
      if (second != std::numeric_limits<int>::max() && best > o_.match_ratio * second) continue;
      if (best < best_dist[best_i]) {
        best_dist[best_i] = best;
        best_lm[best_i] = l;
      }
    }
    std::vector<std::pair<int, int>> out;
    for (std::size_t i = 0; i < best_lm.size(); ++i) {
      if (best_lm[i] >= 0) out.emplace_back(static_cast<int>(i), best_lm[i]);
    }
    return out;
  }

  // PnP RANSAC on the matches; returns the inlier pairs and sets T_wc.
  std::vector<std::pair<int, int>> solve_pnp(const FrameData& f,
                                             const std::vector<std::pair<int, int>>& matches,
                                             Isometry3& T_wc, std::size_t frame_index) const {
    if (static_cast<int>(matches.size()) < o_.min_inliers) return {};
    std::vector<cv::Point3d> obj;
    std::vector<cv::Point2d> img;
    for (const auto& [i, l] : matches) {
      obj.emplace_back(lms_[l].p[0], lms_[l].p[1], lms_[l].p[2]);
      img.emplace_back(f.u[i], f.v[i]);
    }
    const cv::Matx33d K(k_.fx_px, 0, k_.cx_px, 0, k_.fy_px, k_.cy_px, 0, 0, 1);
    const Isometry3 T_cw = T_wc.inverse();
    const Eigen::AngleAxisd aa(T_cw.rotation());
    const Vec3 r = aa.axis() * aa.angle();
    cv::Mat rvec = (cv::Mat_<double>(3, 1) << r.x(), r.y(), r.z());
    cv::Mat tvec = (cv::Mat_<double>(3, 1) << T_cw.translation().x(), T_cw.translation().y(),
                    T_cw.translation().z());
    cv::theRNG() = cv::RNG(o_.seed * 1000003ULL + frame_index);
    std::vector<int> inliers;
    const bool ok = cv::solvePnPRansac(
        obj, img, K, cv::noArray(), rvec, tvec, true, o_.ransac_iterations,
        static_cast<float>(o_.ransac_threshold_px), 0.999, inliers, cv::SOLVEPNP_ITERATIVE);
    if (!ok || static_cast<int>(inliers.size()) < o_.min_inliers) return {};
    // Refine on the inliers (Levenberg-Marquardt), then re-select inliers with the final pose.
    std::vector<cv::Point3d> obj_in;
    std::vector<cv::Point2d> img_in;
    for (int i : inliers) {
      obj_in.push_back(obj[i]);
      img_in.push_back(img[i]);
    }
    cv::solvePnPRefineLM(obj_in, img_in, K, cv::noArray(), rvec, tvec);
    Isometry3 T = Isometry3::Identity();
    const Vec3 rv(rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2));
    if (rv.norm() > 0) T.linear() = Eigen::AngleAxisd(rv.norm(), rv / rv.norm()).toRotationMatrix();
    T.translation() = Vec3(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
    if (!is_finite(T)) return {};
    std::vector<std::pair<int, int>> out;
    for (std::size_t m = 0; m < matches.size(); ++m) {
      const Vec3 pc = T * Vec3(obj[m].x, obj[m].y, obj[m].z);
      if (pc.z() <= 0) continue;
      const Eigen::Vector2d uv = k_.project(pc);
      if ((uv - Eigen::Vector2d(img[m].x, img[m].y)).norm() <= o_.ransac_threshold_px) {
        out.push_back(matches[m]);
      }
    }
    if (static_cast<int>(out.size()) < o_.min_inliers) return {};
    T_wc = T.inverse();
    return out;
  }

  Mat3 propagated_covariance(const LandmarkState& lm, const Obs& ob) const {
    // p_c = d * ((u - cx) / fx, (v - cy) / fy, 1); noise in u, v (pixels) and d (metres).
    const double d = ob.depth_m;
    Mat3 J;
    J.col(0) = Vec3(d / k_.fx_px, 0, 0);
    J.col(1) = Vec3(0, d / k_.fy_px, 0);
    J.col(2) = Vec3((ob.u - k_.cx_px) / k_.fx_px, (ob.v - k_.cy_px) / k_.fy_px, 1.0);
    const double sp = pixel_sigma(ob.octave), sd = depth_sigma(d);
    const Mat3 S = Vec3(sp * sp, sp * sp, sd * sd).asDiagonal();
    const Mat3 R = pose_from_block(kfs_[ob.keyframe].pose).linear();
    (void)lm;
    return R * J * S * J.transpose() * R.transpose();
  }

  void add_keyframe(const FrameData& f, double timestamp, const Isometry3& T_wc,
                    const std::vector<std::pair<int, int>>& tracked) {
    KeyframeState kf;
    kf.timestamp_s = timestamp;
    block_from_pose(T_wc, kf.pose);
    const int k = static_cast<int>(kfs_.size());
    kfs_.push_back(kf);
    std::vector<char> used(f.keypoints.size(), 0);
    auto& kfl = kfs_.back().landmarks;
    for (const auto& [i, l] : tracked) {
      used[i] = 1;
      lms_[l].obs.push_back({k, f.u[i], f.v[i], f.depth_m[i], f.keypoints[i].octave, false});
      lms_[l].desc = f.descriptors[i];
      kfl.push_back(l);
    }
    for (std::size_t i = 0; i < f.keypoints.size(); ++i) {
      if (used[i] || f.depth_m[i] <= 0.0) continue;
      LandmarkState lm;
      const double u = f.u[i], v = f.v[i];
      const Vec3 pw = T_wc * (f.depth_m[i] * k_.unproject(u, v));
      for (int j = 0; j < 3; ++j) lm.p[j] = pw[j];
      lm.desc = f.descriptors[i];
      lm.obs.push_back({k, u, v, f.depth_m[i], f.keypoints[i].octave, false});
      lm.cov = propagated_covariance(lm, lm.obs.front());
      lms_.push_back(lm);
      kfl.push_back(static_cast<int>(lms_.size()) - 1);
    }
    bundle_adjust();
  }

  // Landmark marginal covariances of the BA (the inverse of the Gauss-Newton Hessian J^T J at the
  // solution, robust loss applied, constant poses fixed), by the Schur complement on the poses:
  //   S = H_pp - sum_l W_l H_ll^-1 W_l^T,  Cov_l = H_ll^-1 + H_ll^-1 W_l^T S^-1 W_l H_ll^-1.
  // These are the blocks ceres::Covariance would return, at a fraction of the cost (S is at most
  // 6W x 6W).
  template <typename Blocks>
  void marginal_covariances(ceres::Problem& problem, const Blocks& blocks,
                            const std::vector<int>& kf_list, int first, const std::vector<int>& lms,
                            const std::vector<char>& wanted) {
    std::unordered_map<int, int> slot;
    for (int k : kf_list) {
      if (k > first) slot.emplace(k, static_cast<int>(slot.size()));
    }
    const int P = 6 * static_cast<int>(slot.size());
    Eigen::MatrixXd Hpp = Eigen::MatrixXd::Zero(P, P);
    std::unordered_map<int, Mat3> Hll;
    std::unordered_map<int, Eigen::MatrixXd> W;  // P x 3 per landmark
    for (int l : lms) {
      Hll[l] = Mat3::Zero();
      W[l] = Eigen::MatrixXd::Zero(P, 3);
    }
    for (const auto& b : blocks) {
      double cost = 0.0, r[2];
      Eigen::Matrix<double, 2, 6, Eigen::RowMajor> Jp =
          Eigen::Matrix<double, 2, 6, Eigen::RowMajor>::Zero();
      Eigen::Matrix<double, 2, 3, Eigen::RowMajor> Jl =
          Eigen::Matrix<double, 2, 3, Eigen::RowMajor>::Zero();
      const bool variable = slot.count(b.keyframe) > 0;
      // Ceres refuses a Jacobian for a constant block: pass nullptr there.
      double* jac[2] = {variable ? Jp.data() : nullptr, Jl.data()};
      if (!problem.EvaluateResidualBlock(b.id, true, &cost, r, jac)) return;
      const Eigen::MatrixXd Jpd = Jp.topRows(b.dim);
      const Eigen::MatrixXd Jld = Jl.topRows(b.dim);
      Hll[b.landmark] += Jld.transpose() * Jld;
      if (!variable) continue;
      const int o = 6 * slot.at(b.keyframe);
      Hpp.block(o, o, 6, 6) += Jpd.transpose() * Jpd;
      W[b.landmark].block(o, 0, 6, 3) += Jpd.transpose() * Jld;
    }
    Eigen::MatrixXd S = Hpp;
    std::unordered_map<int, Mat3> Hll_inv;
    for (int l : lms) {
      Eigen::SelfAdjointEigenSolver<Mat3> es(Hll[l]);
      if (es.eigenvalues()(0) <= 1e-12 * std::max(1.0, es.eigenvalues()(2))) continue;
      Hll_inv[l] = es.eigenvectors() * es.eigenvalues().cwiseInverse().asDiagonal() *
                   es.eigenvectors().transpose();
      if (P > 0) S -= W[l] * Hll_inv[l] * W[l].transpose();
    }
    Eigen::MatrixXd S_inv = Eigen::MatrixXd::Zero(P, P);
    if (P > 0) {
      Eigen::LDLT<Eigen::MatrixXd> ldlt(0.5 * (S + S.transpose()));
      if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().array() > 0.0).all()) return;
      S_inv = ldlt.solve(Eigen::MatrixXd::Identity(P, P));
    }
    for (int l : lms) {
      if (!wanted[l]) continue;
      const auto it = Hll_inv.find(l);
      if (it == Hll_inv.end()) continue;
      const Mat3& A = it->second;
      Mat3 C = A;
      if (P > 0) C += A * W[l].transpose() * S_inv * W[l] * A;
      C = 0.5 * (C + C.transpose());
      if (!C.allFinite()) continue;
      lms_[l].cov = C;
      lms_[l].cov_from_ba = true;
    }
  }

  void bundle_adjust(bool final_ba = false) {
    const int n = static_cast<int>(kfs_.size());
    if (n < 2) return;
    const int first = std::max(0, n - o_.window_keyframes);
    std::vector<int> lms;
    for (int l : local_map()) {
      int good = 0;
      for (const auto& ob : lms_[l].obs) good += ob.outlier ? 0 : 1;
      if (good >= 2) lms.push_back(l);
    }
    if (lms.empty()) return;
    ++stats_.ba_runs;

    for (int pass = 0; pass < 2; ++pass) {
      if (pass == 1) {
        // Landmarks left with fewer than 2 inlier observations leave the BA.
        std::vector<int> kept;
        for (int l : lms) {
          int good = 0;
          for (const auto& ob : lms_[l].obs) good += ob.outlier ? 0 : 1;
          if (good >= 2) kept.push_back(l);
        }
        lms.swap(kept);
        if (lms.empty()) return;
      }
      ceres::Problem::Options po;
      po.enable_fast_removal = false;
      ceres::Problem problem(po);
      std::unordered_set<int> used_kfs;
      struct Block {
        ceres::ResidualBlockId id;
        int dim, keyframe, landmark;
      };
      std::vector<Block> blocks;
      for (int l : lms) {
        auto& lm = lms_[l];
        for (const auto& ob : lm.obs) {
          if (ob.outlier) continue;
          double* pose = kfs_[ob.keyframe].pose;
          const double sp = pixel_sigma(ob.octave);
          auto* reprojection = new ceres::AutoDiffCostFunction<ReprojectionCost, 2, 6, 3>(
              new ReprojectionCost(ob.u, ob.v, 1.0 / sp, k_));
          blocks.push_back({problem.AddResidualBlock(
                                reprojection, new ceres::HuberLoss(std::sqrt(5.991)), pose, lm.p),
                            2, ob.keyframe, l});
          if (ob.depth_m > 0.0) {
            auto* depth = new ceres::AutoDiffCostFunction<DepthCost, 1, 6, 3>(
                new DepthCost(ob.depth_m, 1.0 / depth_sigma(ob.depth_m)));
            blocks.push_back({problem.AddResidualBlock(
                                  depth, new ceres::HuberLoss(std::sqrt(3.841)), pose, lm.p),
                              1, ob.keyframe, l});
          }
          used_kfs.insert(ob.keyframe);
        }
      }
      std::vector<int> kf_list(used_kfs.begin(), used_kfs.end());
      std::sort(kf_list.begin(), kf_list.end());
      for (int k : kf_list) {
        if (k <= first) problem.SetParameterBlockConstant(kfs_[k].pose);
      }
      ceres::Solver::Options so;
      so.linear_solver_type = ceres::SPARSE_SCHUR;
      so.num_threads = 1;
      so.max_num_iterations = o_.ba_iterations;
      so.logging_type = ceres::SILENT;
      so.minimizer_progress_to_stdout = false;
      ceres::Solver::Summary summary;
      ceres::Solve(so, &problem, &summary);

      // Outliers: whitened reprojection chi2 > 5.991 (2 dof, 95%) or depth chi2 > 3.841 would
      // be too strict for the kept set; use 99% bounds.
      for (int l : lms) {
        auto& lm = lms_[l];
        for (auto& ob : lm.obs) {
          if (ob.outlier) continue;
          const Isometry3 T_cw = pose_from_block(kfs_[ob.keyframe].pose).inverse();
          const Vec3 pc = T_cw * Vec3(lm.p[0], lm.p[1], lm.p[2]);
          if (pc.z() <= 0) {
            ob.outlier = true;
            continue;
          }
          const double sp = pixel_sigma(ob.octave);
          const double e2 =
              (k_.project(pc) - Eigen::Vector2d(ob.u, ob.v)).squaredNorm() / (sp * sp);
          double ed2 = 0.0;
          if (ob.depth_m > 0) {
            const double sd = depth_sigma(ob.depth_m);
            ed2 = (pc.z() - ob.depth_m) * (pc.z() - ob.depth_m) / (sd * sd);
          }
          if (e2 > 9.21 || ed2 > 6.63) ob.outlier = true;
        }
      }
      if (pass == 1 && o_.compute_covariances) {
        // Marginals only for the landmarks this BA may be the last to see: those not observed by
        // the newest keyframe (they are leaving the window), and every one in the final BA. A
        // landmark seen again later is re-estimated and gets a new marginal then.
        std::vector<char> wanted(lms_.size(), 0);
        for (int l : lms) {
          const bool seen_by_newest = lms_[l].obs.back().keyframe == n - 1;
          if (final_ba || !seen_by_newest) wanted[l] = 1;
        }
        marginal_covariances(problem, blocks, kf_list, first, lms, wanted);
      }
      for (int l : lms) lms_[l].optimised = true;
    }
  }

  // A tracked frame: its slot in the frame trajectory, its keyframe (or kNoKeyframe), and its
  // inlier matches (landmark, pixel).
  struct FrameMatch {
    int landmark;
    double u, v;
  };
  struct TrackedFrame {
    std::size_t slot;
    std::size_t keyframe;
    std::vector<FrameMatch> matches;
  };
  static constexpr std::size_t kNoKeyframe = static_cast<std::size_t>(-1);

  // The frame trajectory, final: keyframes take their bundle-adjusted poses; every other frame
  // is refined by Levenberg-Marquardt (motion only) against the final, bundle-adjusted landmark
  // positions, from its tracked pose. At tracking time the young landmarks near the start only
  // had their depth-initialised positions. A refinement that does not lower the reprojection
  // error is not kept.
  void refine_frames(const std::vector<TrackedFrame>& frames, Trajectory& trajectory) const {
    const cv::Matx33d K(k_.fx_px, 0, k_.cx_px, 0, k_.fy_px, k_.cy_px, 0, 0, 1);
    for (const TrackedFrame& fr : frames) {
      if (fr.keyframe != kNoKeyframe) {
        trajectory[fr.slot].T_world_camera = pose_from_block(kfs_[fr.keyframe].pose);
        continue;
      }
      if (static_cast<int>(fr.matches.size()) < o_.min_inliers) continue;
      std::vector<cv::Point3d> obj;
      std::vector<cv::Point2d> img;
      for (const FrameMatch& m : fr.matches) {
        const auto& p = lms_[static_cast<std::size_t>(m.landmark)].p;
        obj.emplace_back(p[0], p[1], p[2]);
        img.emplace_back(m.u, m.v);
      }
      const Isometry3 T_cw = trajectory[fr.slot].T_world_camera.inverse();
      auto rms = [&](const Isometry3& T) {
        double sum = 0.0;
        for (std::size_t j = 0; j < obj.size(); ++j) {
          const Vec3 pc = T * Vec3(obj[j].x, obj[j].y, obj[j].z);
          if (pc.z() <= 0) return std::numeric_limits<double>::infinity();
          sum += (k_.project(pc) - Eigen::Vector2d(img[j].x, img[j].y)).squaredNorm();
        }
        return sum / static_cast<double>(obj.size());
      };
      const Eigen::AngleAxisd aa(T_cw.rotation());
      const Vec3 r = aa.axis() * aa.angle();
      cv::Mat rvec = (cv::Mat_<double>(3, 1) << r.x(), r.y(), r.z());
      cv::Mat tvec = (cv::Mat_<double>(3, 1) << T_cw.translation().x(), T_cw.translation().y(),
                      T_cw.translation().z());
      cv::solvePnPRefineLM(obj, img, K, cv::noArray(), rvec, tvec);
      Isometry3 T = Isometry3::Identity();
      const Vec3 rv(rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2));
      if (rv.norm() > 0) {
        T.linear() = Eigen::AngleAxisd(rv.norm(), rv / rv.norm()).toRotationMatrix();
      }
      T.translation() = Vec3(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
      if (is_finite(T) && rms(T) <= rms(T_cw)) trajectory[fr.slot].T_world_camera = T.inverse();
    }
  }

  MapBuilderResult run(const TumSequence& seq, const ProgressCallback& progress) {
    MapBuilderResult result;
    const std::size_t total =
        o_.max_frames > 0 ? std::min(o_.max_frames, seq.frames.size()) : seq.frames.size();
    Isometry3 init = Isometry3::Identity();
    if (o_.init_from_ground_truth) {
      if (!seq.ground_truth || seq.ground_truth->empty()) {
        throw InvalidArgument("--init-from-groundtruth: the sequence '" + seq.folder +
                              "' has no groundtruth.txt");
      }
      Trajectory first{{seq.frames.front().rgb_timestamp_s, Isometry3::Identity()}};
      const auto pairs = associate_trajectories(first, *seq.ground_truth, 0.02);
      if (pairs.empty()) {
        throw InvalidArgument("--init-from-groundtruth: " + seq.ground_truth_path +
                              " has no pose within 0.02 s of the first frame (t=" +
                              std::to_string(seq.frames.front().rgb_timestamp_s) + ")");
      }
      init = (*seq.ground_truth)[pairs.front().ground_truth_index].T_world_camera;
    }
    Isometry3 T_wc = init, velocity = Isometry3::Identity();
    // Every tracked frame's 2-D/3-D matches, so that its pose can be refined at the end against
    // the bundle-adjusted landmarks (see refine_frames()).
    std::vector<TrackedFrame> tracked_frames;
    bool have_pose = false;
    std::size_t ref_tracked = 0;
    bool ref_set = false;
    for (std::size_t fi = 0; fi < total; ++fi) {
      const RgbdFrameRef& ref = seq.frames[fi];
      const FrameData f = load(ref);
      ++stats_.frames;
      if (kfs_.empty()) {
        std::size_t valid = 0;
        for (double d : f.depth_m) valid += d > 0 ? 1 : 0;
        if (static_cast<int>(valid) >= o_.min_inliers) {
          add_keyframe(f, ref.rgb_timestamp_s, T_wc, {});
          tracked_frames.push_back({result.frame_trajectory.size(), kfs_.size() - 1, {}});
          result.frame_trajectory.push_back({ref.rgb_timestamp_s, T_wc});
          have_pose = true;
          ref_set = false;
        } else {
          ++stats_.frames_lost;
        }
        if (progress) progress(fi + 1, total);
        continue;
      }
      const std::vector<int> local = local_map();
      Isometry3 T_pred = have_pose ? T_wc * velocity : T_wc;
      Isometry3 T_est = T_pred;
      auto tracked = solve_pnp(f, match(f, local, T_pred, o_.search_radius_px), T_est, fi);
      if (tracked.empty()) {
        T_est = T_pred;
        tracked = solve_pnp(f, match(f, local, T_pred, std::numeric_limits<double>::infinity()),
                            T_est, fi);
      }
      if (tracked.empty()) {
        ++stats_.frames_lost;
        velocity = Isometry3::Identity();
        if (progress) progress(fi + 1, total);
        continue;
      }
      velocity = T_wc.inverse() * T_est;
      T_wc = T_est;
      have_pose = true;
      if (!ref_set) {
        ref_tracked = tracked.size();
        ref_set = true;
      }
      const Isometry3 T_last = pose_from_block(kfs_.back().pose);
      const Isometry3 rel = T_last.inverse() * T_wc;
      const bool moved = rel.translation().norm() > o_.keyframe_translation_m ||
                         rotation_angle_deg(rel.linear()) > o_.keyframe_rotation_deg;
      const bool weak = static_cast<double>(tracked.size()) <
                        o_.keyframe_min_tracked_fraction * static_cast<double>(ref_tracked);
      TrackedFrame record{result.frame_trajectory.size(), kNoKeyframe, {}};
      for (const auto& [i, l] : tracked) record.matches.push_back({l, f.u[i], f.v[i]});
      if (moved || weak) {
        add_keyframe(f, ref.rgb_timestamp_s, T_wc, tracked);
        record.keyframe = kfs_.size() - 1;
        // The BA refined the new keyframe: continue from its refined pose.
        const Isometry3 refined = pose_from_block(kfs_.back().pose);
        velocity = velocity * (T_wc.inverse() * refined);
        T_wc = refined;
        ref_set = false;
      }
      tracked_frames.push_back(std::move(record));
      result.frame_trajectory.push_back({ref.rgb_timestamp_s, T_wc});
      if (progress) progress(fi + 1, total);
    }
    if (kfs_.size() >= 2) bundle_adjust(true);  // marginals of the last window
    refine_frames(tracked_frames, result.frame_trajectory);
    if (kfs_.empty()) {
      throw InvalidArgument("TUM sequence '" + seq.folder +
                            "': tracking never started (no frame with enough valid depth)");
    }

    Map& map = result.map;
    for (std::size_t k = 0; k < kfs_.size(); ++k) {
      Frame fr;
      fr.id = static_cast<Id>(k);
      const Isometry3 T = pose_from_block(kfs_[k].pose);
      Quat q(T.rotation());
      if (q.w() < 0) q.coeffs() = -q.coeffs();
      fr.q_world_camera = q.normalized();
      fr.p_world_camera = T.translation();
      map.frames.push_back(fr);
      result.keyframe_trajectory.push_back({kfs_[k].timestamp_s, T});
    }
    std::size_t total_obs = 0;
    for (std::size_t l = 0; l < lms_.size(); ++l) {
      const auto& lm = lms_[l];
      Landmark out;
      out.id = static_cast<Id>(l);
      out.p_world = Vec3(lm.p[0], lm.p[1], lm.p[2]);
      for (const auto& ob : lm.obs) {
        if (!ob.outlier) out.observations.push_back({static_cast<Id>(ob.keyframe), ob.u, ob.v});
      }
      if (out.observations.empty()) continue;
      out.cov_world_m2 = lm.cov;
      if (!lm.cov_from_ba) {
        // Never in a successful BA: propagate from the observation that created it. Its position
        // is that observation's back-projection unless a BA moved it.
        out.cov_world_m2 = propagated_covariance(lm, lm.obs.front());
      }
      out.cov_world_m2 = 0.5 * (out.cov_world_m2 + out.cov_world_m2.transpose());
      if (!out.p_world.allFinite() || !out.cov_world_m2.allFinite()) continue;
      stats_.landmarks_ba_covariance += lm.cov_from_ba ? 1 : 0;
      stats_.landmarks_two_plus += out.observations.size() >= 2 ? 1 : 0;
      total_obs += out.observations.size();
      map.landmarks.push_back(std::move(out));
    }
    stats_.keyframes = kfs_.size();
    stats_.landmarks = map.landmarks.size();
    stats_.mean_observations =
        map.landmarks.empty()
            ? 0.0
            : static_cast<double>(total_obs) / static_cast<double>(map.landmarks.size());
    result.stats = stats_;
    return result;
  }

 private:
  MapBuilderOptions o_;
  PinholeIntrinsics k_;
  cv::Ptr<cv::ORB> orb_;
  std::vector<KeyframeState> kfs_;
  std::vector<LandmarkState> lms_;
  MapBuilderStats stats_;
};

}  // namespace

MapBuilderResult build_map(const TumSequence& sequence, const MapBuilderOptions& options,
                           const ProgressCallback& progress) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("map builder options: " + why);
  if (sequence.frames.empty()) {
    throw InvalidArgument("TUM sequence '" + sequence.folder + "' has no frames");
  }
  Builder builder(options);
  return builder.run(sequence, progress);
}

}  // namespace lmalign::vo
