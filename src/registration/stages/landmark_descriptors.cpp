// Yaw-invariant neighbourhood descriptors (include/lmalign/registration/stages/
// landmark_descriptors.hpp).
#include "lmalign/registration/stages/landmark_descriptors.hpp"

#include <algorithm>
#include <cmath>

#include "lmalign/core/geometry.hpp"

namespace lmalign {

namespace {
constexpr int kRadialBins = 4;
constexpr int kHeightBins = 5;
static_assert(kRadialBins * kHeightBins == kLandmarkDescriptorDims, "descriptor layout");

// The oriented descriptor's bins, per radius.
constexpr int kOrientedRadial = 3;
constexpr int kOrientedHeight = 4;
constexpr int kOrientedAzimuth = 8;
static_assert(kOrientedRadial * kOrientedHeight * kOrientedAzimuth == kOrientedDescriptorDims,
              "oriented descriptor layout");

// Soft (bilinear) bin coordinates of x in [0, 1] over n bins, bin centres at (b + 0.5) / n:
// the lower bin and the weight of the upper one (the same bin at the ends).
struct SoftBin {
  int lo, hi;
  double w_hi;
};
SoftBin soft_bin(double x, int n) {
  const double f = std::clamp(x * n - 0.5, 0.0, n - 1.0);
  const int lo = std::min(static_cast<int>(f), n - 1);
  return {lo, std::min(lo + 1, n - 1), f - lo};
}
}  // namespace

double descriptor_radius(const Points3& points, const KdTree& tree, std::size_t neighbours,
                         const std::vector<std::uint32_t>& sample) {
  if (points.size() < 2 || sample.empty()) return 0.0;
  const std::size_t k = std::min(neighbours + 1, points.size());
  std::vector<PointIndex> idx(k);
  std::vector<double> d2(k), kth;
  for (const std::uint32_t i : sample) {
    const std::size_t f = tree.knn(points[i], k, idx.data(), d2.data());
    if (f > 0) kth.push_back(d2[f - 1]);
  }
  if (kth.empty()) return 0.0;
  std::nth_element(kth.begin(), kth.begin() + static_cast<std::ptrdiff_t>(kth.size() / 2),
                   kth.end());
  return std::sqrt(kth[kth.size() / 2]);
}

bool describe_landmark(const Points3& points, const KdTree& tree, std::size_t i, const Vec3& up,
                       double radius_m, std::size_t max_neighbours, float* out,
                       const Vec3* view_direction, float elevation_weight) {
  const int dims = kLandmarkDescriptorDims + (view_direction != nullptr ? 1 : 0);
  std::fill(out, out + dims, 0.0f);
  if (!(radius_m > 0.0)) return false;
  // The landmarks within the radius, in the tree's total order (squared distance, then index),
  // at most max_neighbours + 1 of them: exactly the (max_neighbours + 1)-nearest query's points
  // within the radius, in its order (the histogram's float sums depend on the order), for a
  // fraction of its cost (a query of 193 nearest with about 48 within the radius; issue 39).
  std::vector<PointIndex> within;
  tree.within(points[i], radius_m, &within);
  std::vector<std::pair<double, PointIndex>> near;
  near.reserve(within.size());
  for (const PointIndex j : within) near.emplace_back(squared_distance(points[i], points[j]), j);
  std::sort(near.begin(), near.end());
  if (near.size() > max_neighbours + 1) near.resize(max_neighbours + 1);
  double total = 0.0;
  for (const auto& [d2, j] : near) {
    if (j == i) continue;
    const Vec3 d = points[j] - points[i];
    const double h = d.dot(up);
    const double r = std::sqrt(std::max(d.squaredNorm() - h * h, 0.0));
    // Bilinear (soft) assignment between bin centres.
    const double fr = std::clamp(r / radius_m * kRadialBins - 0.5, 0.0, kRadialBins - 1.0);
    const double fh =
        std::clamp((h / radius_m + 1.0) * 0.5 * kHeightBins - 0.5, 0.0, kHeightBins - 1.0);
    const int r0 = std::min(static_cast<int>(fr), kRadialBins - 1);
    const int h0 = std::min(static_cast<int>(fh), kHeightBins - 1);
    const int r1 = std::min(r0 + 1, kRadialBins - 1), h1 = std::min(h0 + 1, kHeightBins - 1);
    const double ar = fr - r0, ah = fh - h0;
    out[r0 * kHeightBins + h0] += static_cast<float>((1 - ar) * (1 - ah));
    out[r1 * kHeightBins + h0] += static_cast<float>(ar * (1 - ah));
    out[r0 * kHeightBins + h1] += static_cast<float>((1 - ar) * ah);
    out[r1 * kHeightBins + h1] += static_cast<float>(ar * ah);
    total += 1.0;
  }
  if (total < 4.0) {
    std::fill(out, out + dims, 0.0f);
    return false;
  }
  for (int b = 0; b < kLandmarkDescriptorDims; ++b) {
    out[b] = std::sqrt(out[b] / static_cast<float>(total));
  }
  if (view_direction != nullptr) {
    out[kLandmarkDescriptorDims] = elevation_weight * static_cast<float>(view_direction->dot(up));
  }
  return true;
}

bool describe_landmark_oriented(const Points3& points, const KdTree& tree, std::size_t i,
                                const Vec3& up, const Vec3& view_direction, double radius_m,
                                float* out, std::vector<PointIndex>* scratch) {
  std::fill(out, out + kOrientedDescriptorDims, 0.0f);
  if (!(radius_m > 0.0) || !std::isfinite(radius_m)) return false;
  const Vec3 horizontal = view_direction - view_direction.dot(up) * up;
  if (!(horizontal.norm() >= 0.2)) return false;
  const Vec3 e1 = horizontal.normalized();
  const Vec3 e2 = up.cross(e1);
  tree.within(points[i], radius_m, scratch);
  double total = 0.0;
  for (const PointIndex j : *scratch) {
    if (j == i) continue;
    const Vec3 d = points[j] - points[i];
    const double h = d.dot(up), x = d.dot(e1), y = d.dot(e2);
    // Azimuth in turns from e1, in [0, 1); circular soft binning.
    double turn = std::atan2(y, x) / (2.0 * kPi);
    if (turn < 0.0) turn += 1.0;
    double fa = turn * kOrientedAzimuth - 0.5;
    if (fa < 0.0) fa += kOrientedAzimuth;
    const int a0 = std::min(static_cast<int>(fa), kOrientedAzimuth - 1);
    const int a1 = (a0 + 1) % kOrientedAzimuth;
    const double wa = fa - a0;
    const SoftBin rb = soft_bin(std::sqrt(x * x + y * y) / radius_m, kOrientedRadial);
    const SoftBin hb = soft_bin(0.5 * (h / radius_m + 1.0), kOrientedHeight);
    auto add = [&](int rr, int hh, double w) {
      float* cell = out + (rr * kOrientedHeight + hh) * kOrientedAzimuth;
      cell[a0] += static_cast<float>(w * (1.0 - wa));
      cell[a1] += static_cast<float>(w * wa);
    };
    add(rb.lo, hb.lo, (1.0 - rb.w_hi) * (1.0 - hb.w_hi));
    add(rb.hi, hb.lo, rb.w_hi * (1.0 - hb.w_hi));
    add(rb.lo, hb.hi, (1.0 - rb.w_hi) * hb.w_hi);
    add(rb.hi, hb.hi, rb.w_hi * hb.w_hi);
    total += 1.0;
  }
  if (total < 4.0) {
    std::fill(out, out + kOrientedDescriptorDims, 0.0f);
    return false;
  }
  for (int b = 0; b < kOrientedDescriptorDims; ++b) {
    out[b] = static_cast<float>(std::sqrt(out[b] / total));
  }
  return true;
}

}  // namespace lmalign
