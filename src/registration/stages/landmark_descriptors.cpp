// Yaw-invariant neighbourhood descriptors (include/lmalign/registration/stages/
// landmark_descriptors.hpp).
#include "lmalign/registration/stages/landmark_descriptors.hpp"

#include <algorithm>
#include <cmath>

namespace lmalign {

namespace {
constexpr int kRadialBins = 4;
constexpr int kHeightBins = 5;
static_assert(kRadialBins * kHeightBins == kLandmarkDescriptorDims, "descriptor layout");
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
  std::vector<PointIndex> idx(max_neighbours + 1);
  std::vector<double> d2(max_neighbours + 1);
  const std::size_t found = tree.knn(points[i], max_neighbours + 1, idx.data(), d2.data());
  double total = 0.0;
  const double r2 = radius_m * radius_m;
  for (std::size_t j = 0; j < found; ++j) {
    if (idx[j] == i || d2[j] > r2) continue;
    const Vec3 d = points[idx[j]] - points[i];
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

}  // namespace lmalign
