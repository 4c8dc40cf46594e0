#include "lmalign/registration/stages/mahalanobis_gate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <omp.h>

#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"
#include "lmalign/core/geometry.hpp"

namespace lmalign {

namespace {

constexpr int kMaxK = 64;

// Whether r' S^-1 r may lie below `bound` (S symmetric), told from S's adjugate without the
// inverse's division: false only when det(S) > 0 and r' adj(S) r >= bound det(S) (1 + 1e-6).
// The margin is far above the rounding that separates this form from r' (S^-1 r) for any S the
// floor keeps within a condition number of about 1e9 (the gate's S is at least floor^2 in every
// direction), so a candidate it drops is one whose d2 (as gate_one computes it) is not below
// the bound. The cofactors are invert_spd's, written out again: one helper for both cost the
// whole alignment 2% more instructions (3,000-landmark street, 2026-11-29).
bool may_be_below(const Mat3& S, const Vec3& r, double bound) {
  const double a = S(0, 0), b = S(0, 1), c = S(0, 2), d = S(1, 1), e = S(1, 2), f = S(2, 2);
  const double A = d * f - e * e, B = c * e - b * f, C = b * e - c * d;
  const double det = a * A + b * B + c * C;
  if (!(det > 0.0) || !(bound < std::numeric_limits<double>::infinity())) return true;
  const double D = a * f - c * c, E = b * c - a * e, F = a * d - b * b;
  const double x = r(0), y = r(1), z = r(2);
  const double q = A * x * x + D * y * y + F * z * z + 2.0 * (B * x * y + C * x * z + E * y * z);
  return q < bound * det * (1.0 + 1e-6);
}

// S^-1 of a symmetric positive-definite 3x3 (the floor keeps it so), by the adjugate; false when
// the determinant is not positive and finite.
bool invert_spd(const Mat3& S, Mat3* out) {
  const double a = S(0, 0), b = S(0, 1), c = S(0, 2), d = S(1, 1), e = S(1, 2), f = S(2, 2);
  const double A = d * f - e * e, B = c * e - b * f, C = b * e - c * d;
  const double det = a * A + b * B + c * C;
  if (!(det > 0.0) || !std::isfinite(det)) return false;
  const double inv = 1.0 / det;
  (*out)(0, 0) = A * inv;
  (*out)(0, 1) = (*out)(1, 0) = B * inv;
  (*out)(0, 2) = (*out)(2, 0) = C * inv;
  (*out)(1, 1) = (a * f - c * c) * inv;
  (*out)(1, 2) = (*out)(2, 1) = (b * c - a * e) * inv;
  (*out)(2, 2) = (a * d - b * b) * inv;
  return out->allFinite();
}

void check_inputs(const GateSide& source, const PreparedTarget& target, double floor_m,
                  const PoseSigma& sigma, const MahalanobisGateOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("Mahalanobis gate: " + why);
  if (source.points == nullptr) throw InvalidArgument("Mahalanobis gate: no source points");
  if (source.covariances_m2 != nullptr && !source.covariances_m2->empty() &&
      source.covariances_m2->size() != source.points->size()) {
    throw InvalidArgument("Mahalanobis gate: " + std::to_string(source.covariances_m2->size()) +
                          " source covariances for " + std::to_string(source.points->size()) +
                          " source landmarks");
  }
  if (source.view_directions != nullptr && !source.view_directions->empty() &&
      source.view_directions->size() != source.points->size()) {
    throw InvalidArgument("Mahalanobis gate: " + std::to_string(source.view_directions->size()) +
                          " source viewing directions for " +
                          std::to_string(source.points->size()) + " source landmarks");
  }
  if (!(floor_m > 0.0) || !std::isfinite(floor_m)) {
    throw InvalidArgument("Mahalanobis gate: floor_m must be > 0 and finite");
  }
  if (!(sigma.translation_m >= 0.0) || !std::isfinite(sigma.translation_m) ||
      !(sigma.rotation_rad >= 0.0) || !std::isfinite(sigma.rotation_rad) ||
      !sigma.pivot_m.allFinite()) {
    throw InvalidArgument("Mahalanobis gate: pose sigma must be finite and >= 0");
  }
  (void)target;
}

// One source landmark's slot of a GateNeighbourCache.
struct CacheSlot {
  PointIndex* indices;
  std::uint8_t* count;
  double* reach_m2;
  Vec3* at_m;
  std::size_t width;
};

constexpr std::size_t kMaxWidth = 2 * kMaxK;

// The k nearest target landmarks of x (exactly KdTree::knn's, in its total order) into idx,
// d2e (room for kMaxWidth + 1), served from and written back to `slot` (see
// GateNeighbourCache); returns how many.
std::size_t nearest(const Vec3& x, const PreparedTarget& target, std::size_t k, CacheSlot* slot,
                    PointIndex* idx, double* d2e) {
  if (slot == nullptr) return target.tree().knn(x, k, idx, d2e);
  const std::size_t n = *slot->count;
  std::size_t found = 0;
  if (n > 0) {
    // Re-evaluate the cached neighbours at x and sort them in the tree's total order (distance,
    // index).
    for (std::size_t c = 0; c < n; ++c) {
      idx[c] = slot->indices[c];
      d2e[c] = squared_distance(x, target.points()[idx[c]]);
    }
    for (std::size_t a = 1; a < n; ++a) {
      const PointIndex ia = idx[a];
      const double da = d2e[a];
      std::size_t b = a;
      while (b > 0 && (d2e[b - 1] > da || (d2e[b - 1] == da && idx[b - 1] > ia))) {
        idx[b] = idx[b - 1];
        d2e[b] = d2e[b - 1];
        --b;
      }
      idx[b] = ia;
      d2e[b] = da;
    }
    // Every target landmark cached, or none left out can come as near as the k-th: a landmark
    // left out is at least sqrt(reach) - moved from x (strictly farther, with a margin for the
    // rounding of the square roots).
    if (n == target.size()) return std::min(k, n);
    if (n >= k) {
      const double moved = (x - *slot->at_m).norm();
      const double reach = std::sqrt(*slot->reach_m2);
      if (std::sqrt(d2e[k - 1]) + moved + 1e-9 * (1.0 + reach) < reach) return k;
    }
    found = target.tree().knn_seeded(x, slot->width + 1, idx, d2e, n, idx, d2e);
  } else {
    found = target.tree().knn(x, slot->width + 1, idx, d2e);
  }
  const std::size_t keep = std::min(found, slot->width);
  std::copy_n(idx, keep, slot->indices);
  *slot->count = static_cast<std::uint8_t>(keep);
  *slot->reach_m2 =
      found > slot->width ? d2e[slot->width] : std::numeric_limits<double>::infinity();
  *slot->at_m = x;
  return std::min(k, found);
}

// A hint that *address will be read soon (nothing on compilers without the builtin).
inline void prefetch(const void* address) {
#if defined(__GNUC__)
  __builtin_prefetch(address);
#else
  (void)address;
#endif
}

// Asks the memory for the target landmarks (positions, covariances) that source landmark i's
// GateNeighbourCache slot holds, a few landmarks before the gate reaches it: the gate waits on
// them more than it computes (docs/performance.md, "The gate's memory"). Changes no result.
constexpr std::size_t kPrefetchAhead = 2;
void prefetch_cached(const GateNeighbourCache& cache, std::size_t i, const PreparedTarget& target,
                     const std::vector<Mat3>* C_t) {
  const PointIndex* ids = &cache.indices[i * static_cast<std::size_t>(cache.width)];
  for (std::size_t c = 0; c < cache.counts[i]; ++c) {
    prefetch(&target.points()[ids[c]]);
    if (C_t != nullptr) {
      const char* cov = reinterpret_cast<const char*>(&(*C_t)[ids[c]]);
      prefetch(cov);
      prefetch(cov + 64);  // a Mat3 (72 bytes) spans two cache lines
    }
  }
}

// The best target landmark of one source landmark; false when none passes the gate.
// `slot` (may be null): the landmark's GateNeighbourCache slot.
// `view_t`: the target's viewing directions (null: none); `view_s`: the source landmark's,
// rotated into the target frame (zero: unknown); `min_cos`: the cosine of the largest angle.
bool gate_one(const Vec3& p_s, const Mat3* C_s, const Isometry3& T, const PreparedTarget& target,
              const std::vector<Mat3>* C_t, double iso_base_m2, const PoseSigma& sigma, int k,
              double chi2, const std::vector<Vec3>* view_t, const Vec3& view_s, double min_cos,
              const EvidenceScales* evidence, GatedPair* out, CacheSlot* slot) {
  const Vec3 x = T * p_s;
  PointIndex idx[kMaxWidth + 1];
  double d2e[kMaxWidth + 1];
  const std::size_t found = nearest(x, target, static_cast<std::size_t>(k), slot, idx, d2e);
  if (found == 0) return false;
  const double lever2 = (x - sigma.pivot_m).squaredNorm();
  const double iso = iso_base_m2 + sigma.rotation_rad * sigma.rotation_rad * lever2;
  Mat3 S_src = Mat3::Zero();
  if (C_s != nullptr) S_src = T.linear() * (*C_s) * T.linear().transpose();
  double best = std::numeric_limits<double>::infinity();
  const bool check_view = view_t != nullptr && !view_s.isZero();
  for (std::size_t c = 0; c < found; ++c) {
    // Seen from incompatible directions (an unknown target direction, zero, passes).
    if (check_view) {
      const Vec3& v_t = (*view_t)[idx[c]];
      if (!v_t.isZero() && view_s.dot(v_t) < min_cos) continue;
    }
    const Vec3 r = target.points()[idx[c]] - x;
    Mat3 S = S_src;
    if (C_t != nullptr) S += (*C_t)[idx[c]];
    S.diagonal().array() += iso;
    // Most candidates can neither beat the best so far nor pass the gate (89-94% of them on
    // simulated streets, measured 2026-11-29): they are dropped before the inverse. The pairs,
    // their d2 and their information matrices are those of inverting every candidate.
    if (!may_be_below(S, r, std::min(best, chi2))) continue;
    Mat3 info;
    if (!invert_spd(S, &info)) continue;
    const double d2 = r.dot(info * r);
    if (d2 < best) {
      best = d2;
      out->target_index = idx[c];
      out->d2 = d2;
      out->moved_source_m = x;
      out->information = info;
    }
  }
  if (!(best < chi2)) return false;
  // The pair's own combined covariance, without the pose term, each map's part in units of its
  // evidence scale (pair_evidence).
  if (evidence != nullptr) {
    const double is2 = 1.0 / (evidence->source_m * evidence->source_m);
    const double it2 = 1.0 / (evidence->target_m * evidence->target_m);
    Mat3 S = S_src * is2;
    if (C_t != nullptr) S += (*C_t)[out->target_index] * it2;
    S.diagonal().array() += evidence->floor_source_m * evidence->floor_source_m * is2 +
                            evidence->floor_target_m * evidence->floor_target_m * it2;
    out->evidence_det = S.determinant();
  }
  return true;
}

}  // namespace

bool MahalanobisGateOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  if (k < 1 || k > kMaxK) return fail("k must be in [1, 64], got " + std::to_string(k));
  if (!(chi2_threshold > 0.0) || !std::isfinite(chi2_threshold)) {
    return fail("chi2_threshold must be > 0 and finite");
  }
  if (!(max_view_angle_deg > 0.0 && max_view_angle_deg <= 180.0)) {
    return fail("max_view_angle_deg must be in (0, 180]");
  }
  return true;
}

void gate_correspondences(const GateSide& source, const PreparedTarget& target,
                          const Isometry3& T_target_source, double floor_m,
                          const PoseSigma& pose_sigma, const MahalanobisGateOptions& options,
                          const std::vector<std::uint32_t>* subset, std::vector<GatedPair>* pairs,
                          GateNeighbourCache* cache, const EvidenceScales* evidence) {
  check_inputs(source, target, floor_m, pose_sigma, options);
  if (evidence != nullptr && !evidence->on()) evidence = nullptr;
  if (cache != nullptr &&
      (cache->k != options.k || cache->counts.size() != source.points->size())) {
    cache->k = options.k;
    cache->width = std::max(8, 2 * options.k);
    const std::size_t n = source.points->size();
    cache->counts.assign(n, 0);
    cache->indices.assign(n * static_cast<std::size_t>(cache->width), 0);
    cache->reach_m2.assign(n, 0.0);
    cache->at_m.assign(n, Vec3::Zero());
  }
  const Points3& P = *source.points;
  const bool src_cov = source.covariances_m2 != nullptr && !source.covariances_m2->empty();
  const std::vector<Mat3>* tgt_cov =
      target.has_covariances() && target.size() > 0 ? &target.covariances_m2() : nullptr;
  const std::size_t n = subset != nullptr ? subset->size() : P.size();
  const double iso_base = floor_m * floor_m + pose_sigma.translation_m * pose_sigma.translation_m;
  // The viewing-direction test, when both sides have directions and it is on.
  const bool views = options.max_view_angle_deg < 180.0 && source.view_directions != nullptr &&
                     !source.view_directions->empty() && !target.view_directions().empty();
  const std::vector<Vec3>* view_t = views ? &target.view_directions() : nullptr;
  const double min_cos = std::cos(options.max_view_angle_deg * kPi / 180.0);
  const Mat3 R = T_target_source.linear();
  // Each thread gates one contiguous range of the landmarks into a list of its own, and the
  // lists are joined in order: the pairs come in the landmarks' order for any thread count. One
  // thread (or a call inside a parallel region) writes straight into *pairs, reusing its
  // capacity: a slot per landmark, written and copied again, was 1.8 MB a call at 15,000
  // landmarks.
  const std::size_t ranges =
      omp_in_parallel() ? 1 : static_cast<std::size_t>(std::max(1, omp_get_max_threads()));
  std::vector<std::vector<GatedPair>> lists(ranges);
  pairs->clear();
  lists[0].swap(*pairs);
  FirstException error;  // an exception may not leave the parallel loop
#pragma omp parallel for schedule(static, 1) if (ranges > 1)
  for (std::ptrdiff_t b = 0; b < static_cast<std::ptrdiff_t>(ranges); ++b) {
    const std::size_t first = n * static_cast<std::size_t>(b) / ranges;
    const std::size_t last = n * static_cast<std::size_t>(b + 1) / ranges;
    std::vector<GatedPair>& out = lists[static_cast<std::size_t>(b)];
    for (std::size_t j = first; j < last; ++j) {
      error.capture([&] {
        const std::size_t i = subset != nullptr ? (*subset)[j] : j;
        GatedPair g;
        g.source_index = static_cast<std::uint32_t>(i);
        CacheSlot cached{};
        if (cache != nullptr) {
          const std::size_t ahead = j + kPrefetchAhead;
          if (ahead < last) {
            prefetch_cached(*cache, subset != nullptr ? (*subset)[ahead] : ahead, target, tgt_cov);
          }
          const std::size_t w = static_cast<std::size_t>(cache->width);
          cached = CacheSlot{&cache->indices[i * w], &cache->counts[i], &cache->reach_m2[i],
                             &cache->at_m[i], w};
        }
        if (gate_one(P[i], src_cov ? &(*source.covariances_m2)[i] : nullptr, T_target_source,
                     target, tgt_cov, iso_base, pose_sigma, options.k, options.chi2_threshold,
                     view_t, views ? Vec3(R * (*source.view_directions)[i]) : Vec3::Zero(), min_cos,
                     evidence, &g, cache != nullptr ? &cached : nullptr)) {
          out.push_back(g);
        }
      });
    }
  }
  error.rethrow();
  lists[0].swap(*pairs);
  for (std::size_t b = 1; b < ranges; ++b) {
    pairs->insert(pairs->end(), lists[b].begin(), lists[b].end());
  }
}

double gated_inlier_score(const GateSide& source, const PreparedTarget& target,
                          const Isometry3& T_target_source, double floor_m,
                          const MahalanobisGateOptions& options,
                          const std::vector<std::uint32_t>* subset, std::size_t* num_inliers) {
  std::vector<GatedPair> pairs;
  gate_correspondences(source, target, T_target_source, floor_m, PoseSigma{}, options, subset,
                       &pairs);
  if (num_inliers != nullptr) *num_inliers = pairs.size();
  return gated_inlier_score(pairs, options);
}

double evidence_weight(const GatedPair& pair) {
  // rho^-3 = 1 / sqrt(det), rho = det^(1/6).
  const double det = pair.evidence_det;
  if (!(det > 0.0) || !std::isfinite(det)) return 1.0;
  return std::min(1.0, 1.0 / std::sqrt(det));
}

double pair_evidence(const GatedPair& pair, double chi2_threshold) {
  return (1.0 - pair.d2 / chi2_threshold) * evidence_weight(pair);
}

double gated_inlier_score(const std::vector<GatedPair>& pairs,
                          const MahalanobisGateOptions& options) {
  double score = 0.0;
  for (const GatedPair& g : pairs) score += pair_evidence(g, options.chi2_threshold);
  return score;
}

double expected_gated_d2(double chi2_threshold) {
  if (!(chi2_threshold > 0.0) || !std::isfinite(chi2_threshold)) {
    throw InvalidArgument("expected_gated_d2: chi2_threshold must be > 0 and finite");
  }
  const double c = chi2_threshold;
  const double cdf3 = std::erf(std::sqrt(0.5 * c)) - std::sqrt(2.0 * c / kPi) * std::exp(-0.5 * c);
  const double cdf5 = cdf3 - std::pow(0.5 * c, 1.5) * std::exp(-0.5 * c) / std::tgamma(2.5);
  return 3.0 * cdf5 / cdf3;
}

}  // namespace lmalign
