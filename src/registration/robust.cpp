#include "lmalign/registration/robust.hpp"
#include "lmalign/registration/uncertainty.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/estimation.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "lmalign/registration/score.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

std::string to_string(RobustKernel kernel) { return name_of(kRobustKernelNames, kernel); }

RobustKernel parse_robust_kernel(const std::string& name) {
  return parse_enum(kRobustKernelNames, "robust kernel", name);
}

double robust_weight(RobustKernel kernel, double residual_m, double scale_m) {
  if (kernel == RobustKernel::kNone || std::isinf(scale_m)) return 1.0;
  const double r = std::abs(residual_m);
  const double u2 = (r / scale_m) * (r / scale_m);
  switch (kernel) {
    case RobustKernel::kNone:
      return 1.0;
    case RobustKernel::kHuber:
      return r <= scale_m ? 1.0 : scale_m / r;
    case RobustKernel::kCauchy:
      return cauchy_weight(u2);
    case RobustKernel::kGemanMcClure:
      return 1.0 / ((1.0 + u2) * (1.0 + u2));
  }
  return 1.0;
}

double estimate_overlap_ratio(std::vector<double> residuals_sq_m2, double min_ratio,
                              double lambda) {
  if (!(min_ratio > 0.0 && min_ratio <= 1.0)) {
    throw InvalidArgument("estimate_overlap_ratio: min_ratio must be in (0, 1], got " +
                          std::to_string(min_ratio));
  }
  if (!(lambda >= 0.0)) throw InvalidArgument("estimate_overlap_ratio: lambda must be >= 0");
  const std::size_t n = residuals_sq_m2.size();
  if (n < 2) return 1.0;
  std::sort(residuals_sq_m2.begin(), residuals_sq_m2.end());
  std::vector<double> prefix(n + 1, 0.0);
  for (std::size_t i = 0; i < n; ++i) prefix[i + 1] = prefix[i] + residuals_sq_m2[i];
  double best = std::numeric_limits<double>::infinity();
  double best_ratio = 1.0;
  const int first = static_cast<int>(std::ceil(min_ratio * 100.0 - 1e-9));
  for (int step = first; step <= 100; ++step) {
    const double xi = step / 100.0;
    const std::size_t m = std::max<std::size_t>(
        1, std::min(n, static_cast<std::size_t>(std::ceil(xi * static_cast<double>(n) - 1e-9))));
    const double e = prefix[m] / static_cast<double>(m);
    const double psi = e / std::pow(xi, 1.0 + lambda);
    if (psi < best) {
      best = psi;
      best_ratio = xi;
    }
  }
  return best_ratio;
}

void trim_correspondences(Correspondences& correspondences, double ratio) {
  if (!(ratio > 0.0 && ratio <= 1.0)) {
    throw InvalidArgument("trim_correspondences: ratio must be in (0, 1], got " +
                          std::to_string(ratio));
  }
  const std::size_t n = correspondences.size();
  const std::size_t keep =
      std::min(n, static_cast<std::size_t>(std::ceil(ratio * static_cast<double>(n) - 1e-9)));
  if (keep >= n) return;
  std::stable_sort(correspondences.begin(), correspondences.end(),
                   [](const Correspondence& a, const Correspondence& b) {
                     if (a.distance_sq_m2 != b.distance_sq_m2) {
                       return a.distance_sq_m2 < b.distance_sq_m2;
                     }
                     return a.source_index < b.source_index;
                   });
  correspondences.resize(keep);
  std::sort(correspondences.begin(), correspondences.end(),
            [](const Correspondence& a, const Correspondence& b) {
              return a.source_index < b.source_index;
            });
}

void keep_mutual(const Points3& moved_source, const Points3& target_points,
                 Correspondences& correspondences) {
  if (correspondences.empty()) return;
  const KdTree source_tree(moved_source);
  Correspondences kept;
  kept.reserve(correspondences.size());
  for (const Correspondence& c : correspondences) {
    PointIndex nearest = 0;
    double d2 = 0.0;
    if (source_tree.nearest(target_points[c.target_index], &nearest, &d2) &&
        nearest == c.source_index) {
      kept.push_back(c);
    }
  }
  correspondences.swap(kept);
}

}  // namespace lmalign
