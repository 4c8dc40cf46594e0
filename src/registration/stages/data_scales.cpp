#include "lmalign/registration/stages/data_scales.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <string>

#include <Eigen/Eigenvalues>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

namespace {

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  return v[mid];
}

// The mean of the two middle values (the median for an odd count): middle_of(-v) = -middle_of(v).
double middle_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const std::size_t hi = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(hi), v.end());
  if (v.size() % 2 == 1) return v[hi];
  const double upper = v[hi];
  const double lower = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(hi));
  return 0.5 * (lower + upper);
}

}  // namespace

DataScales estimate_data_scales(const Points3& points, const std::vector<Mat3>* covariances_m2,
                                std::size_t max_samples, const KdTree* tree) {
  if (points.size() < 2) {
    throw InvalidArgument("estimate_data_scales: need at least 2 landmarks, got " +
                          std::to_string(points.size()));
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) {
      throw InvalidArgument("estimate_data_scales: landmark " + std::to_string(i) +
                            " is not finite");
    }
  }
  const bool with_cov = covariances_m2 != nullptr && !covariances_m2->empty();
  if (tree != nullptr && tree->size() != points.size()) {
    throw InvalidArgument("estimate_data_scales: the tree holds " + std::to_string(tree->size()) +
                          " points, not the " + std::to_string(points.size()) + " landmarks");
  }
  if (with_cov && covariances_m2->size() != points.size()) {
    throw InvalidArgument("estimate_data_scales: " + std::to_string(covariances_m2->size()) +
                          " covariances for " + std::to_string(points.size()) + " landmarks");
  }
  const std::size_t n = points.size();
  const std::size_t m = std::max<std::size_t>(2, std::min(n, max_samples));
  DataScales s;

  // Centre and radius: the coordinate-wise median along the landmarks' principal axes (so that
  // it turns and moves with the map: along the map's own x, y and z it did not, and a map turned
  // about its up axis got another centre, radius and search resolution), then the median
  // distance to it.
  Vec3 mean = Vec3::Zero();
  for (const Vec3& p : points) mean += p;
  mean /= static_cast<double>(n);
  Mat3 scatter = Mat3::Zero();
  for (const Vec3& p : points) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Mat3> axes(scatter);
  const Mat3 E = axes.info() == Eigen::Success ? axes.eigenvectors() : Mat3::Identity();
  std::vector<double> coord(n);
  Vec3 c = Vec3::Zero();
  for (int d = 0; d < 3; ++d) {
    for (std::size_t i = 0; i < n; ++i) coord[i] = E.col(d).dot(points[i] - mean);
    c[d] = middle_of(coord);  // the same for either sign of the axis
  }
  s.centre_m = mean + E * c;
  std::vector<double> dist(n);
  for (std::size_t i = 0; i < n; ++i) dist[i] = (points[i] - s.centre_m).norm();
  s.radius_m = std::max(median_of(dist), 1e-6);

  // Spacing: nearest other landmark of every strided sample.
  std::optional<KdTree> own;
  if (tree == nullptr) tree = &own.emplace(points);
  std::vector<double> nn;
  nn.reserve(m);
  double smallest_positive = 0.0;
  for (std::size_t j = 0; j < m; ++j) {
    const std::size_t i = j * n / m;
    PointIndex idx[2];
    double d2[2];
    if (tree->knn(points[i], 2, idx, d2) == 2) {
      const double d = std::sqrt(d2[1]);
      nn.push_back(d);
      if (d > 0.0 && (smallest_positive == 0.0 || d < smallest_positive)) smallest_positive = d;
    }
  }
  s.spacing_m = median_of(nn);
  if (!(s.spacing_m > 0.0)) s.spacing_m = smallest_positive > 0.0 ? smallest_positive : 1e-6;

  // Floor: the median smallest-axis standard deviation of the covariances present; the typical
  // standard deviation: the median geometric mean of the axes' (det^(1/6)).
  std::vector<double> sd_min, sd_geo;
  std::size_t nonzero = 0;
  if (with_cov) {
    for (std::size_t j = 0; j < m; ++j) {
      const Mat3& c = (*covariances_m2)[j * n / m];
      if (!c.allFinite() || c.isZero(0.0)) continue;
      ++nonzero;
      const Eigen::SelfAdjointEigenSolver<Mat3> es(0.5 * (c + c.transpose()),
                                                   Eigen::EigenvaluesOnly);
      const Vec3 l = es.eigenvalues().cwiseMax(0.0);
      sd_min.push_back(std::sqrt(l[0]));
      sd_geo.push_back(std::cbrt(std::sqrt(l[0]) * std::sqrt(l[1]) * std::sqrt(l[2])));
    }
  }
  s.has_covariances = with_cov && 2 * nonzero >= m;
  s.sigma_m = s.has_covariances ? median_of(sd_geo) : 0.0;
  const double cov_floor = s.has_covariances ? median_of(sd_min) : 0.0;
  s.floor_m = cov_floor > 0.0 ? cov_floor : 0.5 * s.spacing_m;
  return s;
}

std::optional<Vec3> estimate_up_axis(const Map& map) {
  if (map.frames.size() < 2) return std::nullopt;
  Mat3 xx = Mat3::Zero();
  Vec3 minus_y = Vec3::Zero();
  for (const Frame& f : map.frames) {
    const Mat3 R = f.T_world_camera().linear();
    xx += R.col(0) * R.col(0).transpose();
    minus_y -= R.col(1);
  }
  xx /= static_cast<double>(map.frames.size());
  const Eigen::SelfAdjointEigenSolver<Mat3> es(xx);
  // Eigenvalues ascending: the near-null space of the x axes.
  Vec3 up = Vec3::Zero();
  for (int k = 0; k < 3; ++k) {
    if (es.eigenvalues()[k] < 0.05) {
      const Vec3 e = es.eigenvectors().col(k);
      up += e * e.dot(minus_y);
    }
  }
  if (!(up.norm() > 1e-9)) {
    if (!(es.eigenvalues()[0] < 0.05)) return std::nullopt;
    up = es.eigenvectors().col(0);
    if (up.dot(minus_y) < 0.0) up = -up;
  }
  up.normalize();
  if (!up.allFinite()) return std::nullopt;
  return up;
}

std::optional<Vec3> landmark_plane_normal(const Points3& points, const Vec3& up_hint,
                                          double max_flatness, std::size_t max_samples) {
  if (points.size() < 3 || max_samples < 3) return std::nullopt;
  const std::size_t n = std::min(points.size(), max_samples);
  Vec3 mean = Vec3::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3& p = points[i * points.size() / n];
    if (!p.allFinite()) return std::nullopt;
    mean += p;
  }
  mean /= static_cast<double>(n);
  Mat3 scatter = Mat3::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 d = points[i * points.size() / n] - mean;
    scatter += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Mat3> es(scatter / static_cast<double>(n));
  const Eigen::Vector3d ev = es.eigenvalues();
  if (!(ev[1] > 0.0) || !(ev[0] <= max_flatness * ev[1])) return std::nullopt;
  Vec3 normal = es.eigenvectors().col(0).normalized();
  if (normal.dot(up_hint) < 0.0) normal = -normal;
  if (!normal.allFinite()) return std::nullopt;
  return normal;
}

std::optional<Vec3> dominant_plane_normal(const Points3& points, const Vec3& up_hint,
                                          double threshold_m, double max_angle_deg,
                                          std::size_t max_samples) {
  if (points.size() < 3 || max_samples < 3 || !(threshold_m > 0.0) || !std::isfinite(threshold_m) ||
      !up_hint.allFinite() || !(up_hint.norm() > 0.0)) {
    return std::nullopt;
  }
  const std::size_t n = std::min(points.size(), max_samples);
  Points3 q(n);
  for (std::size_t i = 0; i < n; ++i) {
    q[i] = points[i * points.size() / n];
    if (!q[i].allFinite()) return std::nullopt;
  }
  const Vec3 hint = up_hint.normalized();
  const double min_cos = std::cos(max_angle_deg * kPi / 180.0);
  // RANSAC over triplets, seeded and drawn by explicit formulas (the same draws on every
  // platform); ties keep the earlier triplet.
  std::mt19937_64 rng(0x5eed);
  std::size_t best_count = 0;
  Vec3 best_n = Vec3::Zero();
  double best_d = 0.0;
  for (int it = 0; it < 256; ++it) {
    const std::size_t a = rng() % n, b = rng() % n, c = rng() % n;
    Vec3 nn = (q[b] - q[a]).cross(q[c] - q[a]);
    if (!(nn.norm() > 0.0)) continue;
    nn.normalize();
    if (std::abs(nn.dot(hint)) < min_cos) continue;  // a wall, not a floor
    const double d = nn.dot(q[a]);
    std::size_t count = 0;
    for (const Vec3& p : q) {
      if (std::abs(nn.dot(p) - d) < threshold_m) ++count;
    }
    if (count > best_count) {
      best_count = count;
      best_n = nn;
      best_d = d;
    }
  }
  if (best_count < std::max<std::size_t>(3, n / 10)) return std::nullopt;
  // The normal of the inliers' best-fitting plane.
  Vec3 mean = Vec3::Zero();
  std::size_t k = 0;
  for (const Vec3& p : q) {
    if (std::abs(best_n.dot(p) - best_d) < threshold_m) {
      mean += p;
      ++k;
    }
  }
  mean /= static_cast<double>(k);
  Mat3 scatter = Mat3::Zero();
  for (const Vec3& p : q) {
    if (std::abs(best_n.dot(p) - best_d) < threshold_m)
      scatter += (p - mean) * (p - mean).transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Mat3> es(scatter);
  Vec3 normal = es.eigenvectors().col(0).normalized();
  if (normal.dot(hint) < 0.0) normal = -normal;
  if (!normal.allFinite() || normal.dot(hint) < min_cos) return std::nullopt;
  return normal;
}

}  // namespace lmalign
