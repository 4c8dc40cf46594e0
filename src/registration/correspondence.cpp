#include "lmalign/registration/correspondence.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <omp.h>

#include "lmalign/core/error.hpp"

namespace lmalign {

namespace {
constexpr PointIndex kNoMatch = std::numeric_limits<PointIndex>::max();
constexpr int kMaxK = 4096;
}  // namespace

std::string to_string(CorrespondenceKind kind) {
  return kind == CorrespondenceKind::kNearest ? "nearest" : "weighted_knn";
}

bool CorrespondenceOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& msg) {
    if (why != nullptr) *why = msg;
    return false;
  };
  if (k < 1 || k > kMaxK) {
    return fail("k must be in [1, " + std::to_string(kMaxK) + "], got " + std::to_string(k));
  }
  if (std::isnan(max_distance_m) || max_distance_m <= 0.0) {
    return fail("max_distance_m must be > 0 (or infinite), got " + std::to_string(max_distance_m));
  }
  return true;
}

CorrespondenceFinder::CorrespondenceFinder(const KdTree& target, std::vector<double> target_weights,
                                           const CorrespondenceOptions& options)
    : target_(&target), weights_(std::move(target_weights)), options_(options) {
  std::string why;
  if (!options_.is_valid(&why)) throw InvalidArgument("correspondence options: " + why);
  if (options_.kind == CorrespondenceKind::kWeightedKnn && weights_.size() != target.size()) {
    throw InvalidArgument("correspondence: " + std::to_string(weights_.size()) +
                          " target weights for " + std::to_string(target.size()) +
                          " target points");
  }
  for (std::size_t i = 0; i < weights_.size(); ++i) {
    if (!std::isfinite(weights_[i]) || weights_[i] < 0.0) {
      throw InvalidArgument("correspondence: target weight " + std::to_string(i) +
                            " must be finite and >= 0");
    }
  }
  // Squared threshold; an infinite (or huge) distance stays infinite.
  max_distance_sq_m2_ = std::isinf(options_.max_distance_m) || options_.max_distance_m > 1e150
                            ? std::numeric_limits<double>::infinity()
                            : options_.max_distance_m * options_.max_distance_m;
}

void CorrespondenceFinder::find(const Points3& source_points, Correspondences& out) const {
  const std::size_t n = source_points.size();
  const bool weighted = options_.kind == CorrespondenceKind::kWeightedKnn;
  const std::size_t k = weighted ? static_cast<std::size_t>(options_.k) : 1;

  // One slot per source point, filled in parallel, then compacted in source order: the result
  // does not depend on the thread count or schedule.
  std::vector<PointIndex> match(n, kNoMatch);
  std::vector<double> match_dist(n, 0.0);

#pragma omp parallel
  {
    std::vector<PointIndex> idx(k);
    std::vector<double> dist(k);
#pragma omp for schedule(static)
    for (std::ptrdiff_t s = 0; s < static_cast<std::ptrdiff_t>(n); ++s) {
      const Vec3& q = source_points[static_cast<std::size_t>(s)];
      if (!q.allFinite()) continue;
      const std::size_t found = target_->knn(q, k, idx.data(), dist.data());
      if (!weighted) {
        if (found == 1 && dist[0] <= max_distance_sq_m2_) {
          match[s] = idx[0];
          match_dist[s] = dist[0];
        }
        continue;
      }
      // Eq. 6: argmax of the target weight over candidates within range; candidates come nearest
      // first, so a strict '>' keeps the nearer one on equal weights. Weight 0 never matches.
      double best_w = 0.0;
      for (std::size_t j = 0; j < found; ++j) {
        if (dist[j] > max_distance_sq_m2_) break;
        const double w = weights_[idx[j]];
        if (w > best_w) {
          best_w = w;
          match[s] = idx[j];
          match_dist[s] = dist[j];
        }
      }
    }
  }

  out.clear();
  out.reserve(n);
  for (std::size_t s = 0; s < n; ++s) {
    if (match[s] != kNoMatch) {
      out.push_back({static_cast<PointIndex>(s), match[s], match_dist[s]});
    }
  }
}

}  // namespace lmalign
