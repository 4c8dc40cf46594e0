// Candidate pairs of a merge (include/lmalign/merge/candidates.hpp).
#include "lmalign/merge/candidates.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <set>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/merge/manifest.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/stages/complete_search.hpp"
#include "lmalign/registration/stages/correspondence_search.hpp"
#include "lmalign/registration/stages/data_scales.hpp"
#include "lmalign/registration/stages/landmark_descriptors.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

namespace {

// q-quantiles (q = 1/(n+1) .. n/(n+1)) of values (sorted in place).
std::vector<double> quantiles(std::vector<double>& values, std::size_t n) {
  std::vector<double> out(n, 0.0);
  if (values.empty()) return out;
  std::sort(values.begin(), values.end());
  for (std::size_t k = 0; k < n; ++k) {
    const double q = static_cast<double>(k + 1) / static_cast<double>(n + 1);
    out[k] = values[static_cast<std::size_t>(q * static_cast<double>(values.size() - 1))];
  }
  return out;
}

double worst_sd(const Mat3& C) {
  Eigen::SelfAdjointEigenSolver<Mat3> eig(C);
  return std::sqrt(std::max(0.0, eig.eigenvalues().maxCoeff()));
}

// A map needs this many descriptors to be retrieved by its words.
constexpr std::size_t kMinWords = 8;

// The retrieval's words of one map (MapSummary::local_descriptors, local_regions).
void describe_for_retrieval(const Points3& p, const Vec3& up, const CandidateOptions& options,
                            MapSummary* s) {
  if (p.size() < 8) return;
  const KdTree tree(p);
  std::vector<std::uint32_t> sample;
  const std::size_t want = std::min<std::size_t>(512, p.size());
  for (std::size_t j = 0; j < want; ++j)
    sample.push_back(static_cast<std::uint32_t>(j * p.size() / want));
  const double radius = descriptor_radius(p, tree, options.descriptor_neighbours, sample);
  if (!(radius > 0.0) || !std::isfinite(radius)) return;
  // The main horizontal axis: the largest eigenvector of the horizontal scatter.
  Mat3 scatter = Mat3::Zero();
  for (const Vec3& x : p) {
    Vec3 d = x - s->centroid;
    d -= d.dot(up) * up;
    scatter += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(scatter);
  const Vec3 axis = eig.eigenvectors().col(2);
  const std::size_t m = std::min(options.retrieval_landmarks, p.size());
  std::vector<double> along;
  float desc[kLandmarkDescriptorDims];
  for (std::size_t j = 0; j < m; ++j) {
    const std::size_t i = j * p.size() / m;
    if (!describe_landmark(p, tree, i, up, radius, 4 * options.descriptor_neighbours, desc)) {
      continue;
    }
    s->local_descriptors.insert(s->local_descriptors.end(), desc, desc + kLandmarkDescriptorDims);
    along.push_back((p[i] - s->centroid).dot(axis));
  }
  std::vector<double> sorted = along;
  if (sorted.empty()) return;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2),
                   sorted.end());
  const double median = sorted[sorted.size() / 2];
  for (double a : along) s->local_regions.push_back(a >= median ? 1 : 0);
}

// The retrieval (see the header): a vocabulary learned by k-means over the maps' descriptors
// (at most 20,000 of them, evenly strided over the maps in order; initial centres evenly
// strided among those; 10 Lloyd iterations; ties to the lower word), each map's tf-idf bags of
// words for the whole map and its two halves, and the distance 1 - the best cosine over the
// nine pairs of bags. Deterministic (the parallel loops write one slot each).
class Retrieval {
 public:
  Retrieval(const std::vector<MapSummary>& maps, std::size_t words) : n_(maps.size()) {
    constexpr int D = kLandmarkDescriptorDims;
    std::vector<const float*> all;
    for (const MapSummary& m : maps) {
      if (m.local_descriptors.size() / D < kMinWords) continue;
      for (std::size_t i = 0; i < m.local_descriptors.size(); i += D) {
        all.push_back(&m.local_descriptors[i]);
      }
    }
    const std::size_t want = std::min<std::size_t>(all.size(), 20000);
    if (want < 2) return;
    std::vector<const float*> train(want);
    for (std::size_t j = 0; j < want; ++j) train[j] = all[j * all.size() / want];
    k_ = std::min(words, want);
    centres_.resize(k_ * D);
    for (std::size_t c = 0; c < k_; ++c) {
      std::copy(train[c * want / k_], train[c * want / k_] + D, &centres_[c * D]);
    }
    std::vector<std::uint32_t> label(want);
    for (int iteration = 0; iteration < 10; ++iteration) {
#pragma omp parallel for schedule(static)
      for (std::ptrdiff_t j = 0; j < static_cast<std::ptrdiff_t>(want); ++j) {
        label[j] = word(train[j]);
      }
      std::vector<double> sum(k_ * D, 0.0);
      std::vector<std::size_t> count(k_, 0);
      for (std::size_t j = 0; j < want; ++j) {
        ++count[label[j]];
        for (int x = 0; x < D; ++x) sum[label[j] * D + x] += train[j][x];
      }
      for (std::size_t c = 0; c < k_; ++c) {
        if (count[c] == 0) continue;  // an empty word keeps its centre
        for (int x = 0; x < D; ++x) {
          centres_[c * D + x] = static_cast<float>(sum[c * D + x] / static_cast<double>(count[c]));
        }
      }
    }
    // Bags of words: whole, half 0, half 1.
    bags_.assign(n_ * 3, std::vector<double>(k_, 0.0));
    has_.assign(n_, 0);
#pragma omp parallel for schedule(dynamic)
    for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n_); ++i) {
      const MapSummary& m = maps[i];
      const std::size_t count = m.local_descriptors.size() / D;
      if (count < kMinWords || m.local_regions.size() != count) continue;
      has_[i] = 1;
      for (std::size_t d = 0; d < count; ++d) {
        const std::uint32_t w = word(&m.local_descriptors[d * D]);
        bags_[i * 3][w] += 1.0;
        bags_[i * 3 + 1 + m.local_regions[d]][w] += 1.0;
      }
    }
    std::vector<double> idf(k_, 0.0);
    std::size_t retrieved = 0;
    for (std::size_t i = 0; i < n_; ++i) {
      if (!has_[i]) continue;
      ++retrieved;
      for (std::size_t w = 0; w < k_; ++w) idf[w] += bags_[i * 3][w] > 0.0 ? 1.0 : 0.0;
    }
    for (std::size_t w = 0; w < k_; ++w) {
      idf[w] = std::log((static_cast<double>(retrieved) + 1.0) / (idf[w] + 1.0));
    }
    for (std::vector<double>& bag : bags_) {
      double norm = 0.0;
      for (std::size_t w = 0; w < k_; ++w) {
        bag[w] *= idf[w];
        norm += bag[w] * bag[w];
      }
      if (norm > 0.0) {
        for (double& v : bag) v /= std::sqrt(norm);
      }
    }
  }

  /// Whether map i has words.
  bool has(std::size_t i) const { return i < has_.size() && has_[i] != 0; }

  /// 1 - the best cosine between the bags of maps i and j (both with words), in [0, 1].
  double distance(std::size_t i, std::size_t j) const {
    double best = 0.0;
    for (std::size_t a = 0; a < 3; ++a) {
      for (std::size_t b = 0; b < 3; ++b) {
        const std::vector<double>& x = bags_[i * 3 + a];
        const std::vector<double>& y = bags_[j * 3 + b];
        double dot = 0.0;
        for (std::size_t w = 0; w < k_; ++w) dot += x[w] * y[w];
        best = std::max(best, dot);
      }
    }
    return 1.0 - std::min(best, 1.0);
  }

 private:
  std::uint32_t word(const float* d) const {
    constexpr int D = kLandmarkDescriptorDims;
    std::uint32_t best = 0;
    float best_d = std::numeric_limits<float>::infinity();
    for (std::size_t c = 0; c < k_; ++c) {
      float e = 0.0f;
      for (int x = 0; x < D; ++x) {
        const float t = d[x] - centres_[c * D + x];
        e += t * t;
      }
      if (e < best_d) {
        best_d = e;
        best = static_cast<std::uint32_t>(c);
      }
    }
    return best;
  }

  std::size_t n_ = 0;
  std::size_t k_ = 0;
  std::vector<float> centres_;
  std::vector<std::vector<double>> bags_;
  std::vector<char> has_;
};

// The geometric verification's correspondence search: yaw-invariant descriptors (see
// verified_matches), only the largest clique counts.
CorrespondenceSearchOptions verification_options() {
  CorrespondenceSearchOptions o;
  o.oriented = false;
  o.seeds = 16;
  o.hypotheses = 4;
  o.refits = 0;  // only the clique's size counts here, not its pose
  return o;
}

// The geometric verification's sketch of one map (MapSummary::sketch_*): the landmarks
// describe_for_retrieval describes (the same stride), with their covariances and viewing
// directions, and the sketch's covariance floor (its spacing's half where no covariance is known).
void sketch_for_verification(const Map& map, const std::vector<std::size_t>& kept, const Points3& p,
                             const Vec3& up, const CandidateOptions& options, MapSummary* s) {
  if (p.size() < 8) return;
  const std::vector<Vec3> views = map.view_directions();
  const std::size_t m = std::min(options.retrieval_landmarks, p.size());
  for (std::size_t j = 0; j < m; ++j) {
    const std::size_t i = j * p.size() / m;
    const Landmark& l = map.landmarks[kept[i]];
    s->sketch_points.push_back(p[i]);
    s->sketch_covariances_m2.push_back(l.covariance_unknown ? Mat3::Zero() : l.cov_world_m2);
    s->sketch_view_directions.push_back(kept[i] < views.size() ? views[kept[i]] : Vec3::Zero());
  }
  s->up = up;
  const DataScales d = estimate_data_scales(s->sketch_points, &s->sketch_covariances_m2);
  s->floor_m = d.floor_m > 0.0 ? d.floor_m : 0.5 * d.spacing_m;
  s->sketch_radius_m = search_descriptor_radius(s->sketch_points, verification_options());
}

// A sketch described for the verification (plan_candidates): as the target of a search, and as
// its source when the source's keypoints differ from those (else empty: the target's serve).
struct DescribedSketch {
  DescribedLandmarks as_target;
  DescribedLandmarks as_source;
  const DescribedLandmarks& source() const {
    return as_source.keys.empty() ? as_target : as_source;
  }
};

DescribedSketch describe_sketch(const MapSummary& m, double radius_m) {
  DescribedSketch d;
  if (m.sketch_points.size() < 8 || !(radius_m > 0.0) || !std::isfinite(radius_m)) return d;
  const CorrespondenceSearchOptions o = verification_options();
  d.as_target = describe_search_landmarks(m.sketch_points, &m.sketch_view_directions, m.up,
                                          radius_m, false, o);
  if (strided_indices(m.sketch_points.size(), o.keypoints) != d.as_target.keys) {
    d.as_source = describe_search_landmarks(m.sketch_points, &m.sketch_view_directions, m.up,
                                            radius_m, true, o);
  }
  return d;
}

// The matches in the correspondence search's largest clique between the sketches of maps a
// (source) and b (target), described beforehand (describe_sketch); 0 when either has no sketch.
// Yaw-invariant descriptors only: on the synthetic fleet the oriented ones separated overlapping
// from unrelated pairs no better, at twice the time (15 against 33 ms a pair, docs/merge.md).
std::size_t verified_matches(const MapSummary& a, const DescribedSketch& da, const MapSummary& b,
                             const DescribedSketch& db) {
  if (a.sketch_points.size() < 8 || b.sketch_points.size() < 8 || !(a.floor_m > 0.0) ||
      !(b.floor_m > 0.0) || da.as_target.keys.empty() || db.as_target.keys.empty()) {
    return 0;
  }
  PreparedTarget target(b.sketch_points);
  target.set_covariances(b.sketch_covariances_m2);
  target.set_view_directions(b.sketch_view_directions);
  target.set_up_axis(b.up);
  CorrespondenceSearchInput in;
  in.source.points = &a.sketch_points;
  in.source.covariances_m2 = &a.sketch_covariances_m2;
  in.source.view_directions = &a.sketch_view_directions;
  in.target = &target;
  in.floor_m = std::max(a.floor_m, b.floor_m);
  std::size_t best = 0;
  for (const CorrespondenceHypothesis& h :
       correspondence_search_described(in, da.source(), db.as_target, verification_options())
           .hypotheses) {
    best = std::max(best, h.inliers);
  }
  return best;
}

}  // namespace

bool CandidateOptions::is_valid(std::string* why) const {
  auto bad = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (all_pairs_max_maps < 2) return bad("all_pairs_max_maps must be >= 2");
  if (keep_per_map < 1) return bad("keep_per_map must be >= 1");
  if (!(prior_sigmas > 0.0) || !std::isfinite(prior_sigmas)) return bad("prior_sigmas must be > 0");
  if (!(radius_quantile > 0.0 && radius_quantile <= 1.0)) {
    return bad("radius_quantile must be in (0, 1]");
  }
  if (bins < 2 || bins > 1024) return bad("bins must be in [2, 1024]");
  if (distance_samples < 16) return bad("distance_samples must be >= 16");
  if (retrieval_landmarks < 8) return bad("retrieval_landmarks must be >= 8");
  if (descriptor_neighbours < 4 || descriptor_neighbours > 256) {
    return bad("descriptor_neighbours must be in [4, 256]");
  }
  if (vocabulary_words < 2 || vocabulary_words > 4096) {
    return bad("vocabulary_words must be in [2, 4096]");
  }
  if (verify_per_map > 100000) return bad("verify_per_map must be in [0, 100000]");
  return true;
}

MapSummary summarise_map(const Map& map, const CandidateOptions& options, std::uint64_t seed) {
  MapSummary s;
  s.metric = map.header.scale == MapScale::kMetric;
  s.covariance_assumed = map.header.covariance_assumed;
  // The landmarks the edges align (core/supported_range.hpp: those beyond it are left out).
  Points3 p;
  std::vector<std::size_t> kept;
  for (std::size_t i = 0; i < map.landmarks.size(); ++i) {
    if (within_supported_range(map.landmarks[i].p_world)) {
      p.push_back(map.landmarks[i].p_world);
      kept.push_back(i);
    }
  }
  s.num_landmarks = p.size();
  if (p.empty()) return s;
  for (const Vec3& x : p) s.centroid += x;
  s.centroid /= static_cast<double>(p.size());
  std::vector<double> dist;
  dist.reserve(p.size());
  for (const Vec3& x : p) dist.push_back((x - s.centroid).norm());
  std::sort(dist.begin(), dist.end());
  s.radius_m = dist[static_cast<std::size_t>(options.radius_quantile *
                                             static_cast<double>(dist.size() - 1))];
  // Heights along the up axis, relative to the median camera height (median landmark height
  // without frames).
  const Vec3 up = estimate_up_axis(map).value_or(Vec3::UnitZ());
  std::vector<double> ref;
  for (const Frame& f : map.frames) ref.push_back(f.p_world_camera.dot(up));
  if (ref.empty()) {
    for (const Vec3& x : p) ref.push_back(x.dot(up));
  }
  std::nth_element(ref.begin(), ref.begin() + static_cast<std::ptrdiff_t>(ref.size() / 2),
                   ref.end());
  const double h0 = ref[ref.size() / 2];
  std::vector<double> heights;
  heights.reserve(p.size());
  for (const Vec3& x : p) heights.push_back(x.dot(up) - h0);
  // Distances between seeded random landmark pairs.
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, p.size() - 1);
  std::vector<double> pair_dist;
  pair_dist.reserve(options.distance_samples);
  for (std::size_t k = 0; k < options.distance_samples; ++k) {
    pair_dist.push_back((p[pick(rng)] - p[pick(rng)]).norm());
  }
  s.descriptor = quantiles(heights, options.bins);
  const std::vector<double> dq = quantiles(pair_dist, options.bins);
  s.descriptor.insert(s.descriptor.end(), dq.begin(), dq.end());
  describe_for_retrieval(p, up, options, &s);
  if (options.verify_per_map > 0) sketch_for_verification(map, kept, p, up, options, &s);
  return s;
}

Isometry3 relative_prior(const MapPrior& source, const MapPrior& target, Mat6* covariance) {
  const Isometry3 T_target_world = target.T_world_map.inverse();
  if (covariance != nullptr) {
    // T_wj^-1 Exp(-xi_j) Exp(xi_i) T_wi ~= Exp(Ad(T_jw) (xi_i - xi_j)) T_ji.
    const Mat6 A = se3_adjoint(T_target_world);
    *covariance = A * (source.covariance + target.covariance) * A.transpose();
  }
  Isometry3 T_target_source = T_target_world * source.T_world_map;
  // Priors are accepted with rotations orthonormal to 1e-6 (is_rigid_transform, as the manifest
  // reads them); two such compose to one that may be off by more, which the edge's alignment would
  // refuse as an initial guess. Then the nearest rotation (exact rotations are left as they are).
  const Mat3 R = T_target_source.linear();
  if (!((R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff() <= 1e-12)) {
    const Eigen::JacobiSVD<Mat3> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
    T_target_source.linear() = svd.matrixU() * svd.matrixV().transpose();
  }
  return T_target_source;
}

std::vector<CandidatePair> plan_candidates(const std::vector<MapSummary>& summaries,
                                           const std::vector<std::optional<MapPrior>>& priors,
                                           const CandidateOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("candidate options: " + why);
  const std::size_t n = summaries.size();
  if (priors.size() != n) {
    throw InvalidArgument("plan_candidates: " + std::to_string(priors.size()) + " priors for " +
                          std::to_string(n) + " maps");
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (priors[i]) check_prior_in_supported_range(*priors[i], "prior of map " + std::to_string(i));
  }
  std::vector<CandidatePair> with_prior;
  std::vector<std::pair<std::size_t, std::size_t>> without;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      if (priors[i] && priors[j]) {
        CandidatePair c;
        c.source = i;
        c.target = j;
        Mat6 C;
        const Isometry3 T_ji = relative_prior(*priors[i], *priors[j], &C);
        const double sd_t = worst_sd(C.block<3, 3>(0, 0));
        const double sd_r = worst_sd(C.block<3, 3>(3, 3));  // rad
        const Vec3 ci = T_ji * summaries[i].centroid;       // in j's frame
        const double gap = (ci - summaries[j].centroid).norm();
        const double reach = summaries[i].radius_m + summaries[j].radius_m +
                             options.prior_sigmas * (sd_t + sd_r * summaries[i].radius_m);
        if (!(gap <= reach)) continue;
        // Priors that put the maps beyond the supported range of each other: not a candidate.
        if (!within_supported_range(T_ji.translation())) continue;
        c.rank = gap / std::max(reach, 1e-12);
        c.initial_guess = T_ji;
        // Sigmas beyond the supported range say no more than those at its edge (3 sigma then
        // covers every rotation and the whole range).
        PriorSigma ps;
        ps.rotation_deg = std::clamp(sd_r / kRadPerDeg, 1e-3, kMaxAngleDeg);
        ps.translation_m = std::clamp(sd_t, 1e-4, kMaxCoordinateM);
        c.prior = ps;
        c.prior_complete_search = n <= options.all_pairs_max_maps ? "rescue" : "check";
        with_prior.push_back(c);
      } else {
        without.emplace_back(i, j);
      }
    }
  }
  std::vector<CandidatePair> out = with_prior;
  if (n <= options.all_pairs_max_maps) {
    for (const auto& [i, j] : without) out.push_back(CandidatePair{i, j, 0.0, {}, {}});
  } else if (!without.empty()) {
    const Retrieval retrieval(summaries, options.vocabulary_words);
    // Retrieved pairs rank by 1 - cosine, in [0, 1]; a pair with a map without words by the
    // histograms' L1 distance, after them.
    auto distance = [&](std::size_t i, std::size_t j) {
      if (retrieval.has(i) && retrieval.has(j)) return retrieval.distance(i, j);
      const auto& a = summaries[i].descriptor;
      const auto& b = summaries[j].descriptor;
      if (a.size() != b.size() || a.empty()) return std::numeric_limits<double>::infinity();
      double d = 0.0;
      for (std::size_t k = 0; k < a.size(); ++k) d += std::abs(a[k] - b[k]);
      return 1.0 + d / static_cast<double>(a.size());
    };
    // Per map: its keep_per_map nearest partners among the pairs without priors.
    std::vector<std::vector<std::pair<double, std::size_t>>> near(n);
    std::vector<double> pair_distance(without.size());
    for (std::size_t k = 0; k < without.size(); ++k) {
      const auto [i, j] = without[k];
      pair_distance[k] = distance(i, j);
      near[i].emplace_back(pair_distance[k], j);
      near[j].emplace_back(pair_distance[k], i);
    }
    // Geometric verification: each map's verify_per_map most similar partners, each pair once
    // (in (source, target) order; one slot per pair, so any thread count gives the same).
    std::map<std::pair<std::size_t, std::size_t>, std::size_t> verified;
    if (options.verify_per_map > 0) {
      for (std::size_t i = 0; i < n; ++i) {
        auto& v = near[i];
        const std::size_t m = std::min(options.verify_per_map, v.size());
        std::partial_sort(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m), v.end());
        for (std::size_t k = 0; k < m; ++k) {
          verified.emplace(std::make_pair(std::min(i, v[k].second), std::max(i, v[k].second)), 0);
        }
      }
      std::vector<std::pair<std::size_t, std::size_t>> todo;
      for (const auto& [ij, count] : verified) todo.push_back(ij);
      std::vector<std::size_t> counts(todo.size(), 0);
      // Every sketch described once, at one radius for all: the median of the maps' own (a
      // search describes both maps at the target's radius; the median stands in for it).
      std::vector<double> radii;
      for (const MapSummary& m : summaries) {
        if (m.sketch_radius_m > 0.0 && std::isfinite(m.sketch_radius_m)) {
          radii.push_back(m.sketch_radius_m);
        }
      }
      std::vector<DescribedSketch> described(n);
      FirstException error;  // an exception may not leave the parallel loop
      if (!radii.empty()) {
        std::nth_element(radii.begin(),
                         radii.begin() + static_cast<std::ptrdiff_t>(radii.size() / 2),
                         radii.end());
        const double radius = radii[radii.size() / 2];
#pragma omp parallel for schedule(dynamic, 1)
        for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n); ++i) {
          error.capture([&] {
            described[static_cast<std::size_t>(i)] =
                describe_sketch(summaries[static_cast<std::size_t>(i)], radius);
          });
        }
        error.rethrow();
      }
#pragma omp parallel for schedule(dynamic, 1)
      for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(todo.size()); ++k) {
        error.capture([&] {
          const auto [i, j] = todo[static_cast<std::size_t>(k)];
          counts[static_cast<std::size_t>(k)] =
              verified_matches(summaries[i], described[i], summaries[j], described[j]);
        });
      }
      error.rethrow();
      for (std::size_t k = 0; k < todo.size(); ++k) verified[todo[k]] = counts[k];
    }
    auto matches_of = [&](std::size_t i, std::size_t j) -> std::size_t {
      const auto it = verified.find({std::min(i, j), std::max(i, j)});
      return it == verified.end() ? 0 : it->second;
    };
    // Each map keeps its keep_per_map best: the largest verified cliques first, then the most
    // similar (without verification: the most similar).
    std::set<std::pair<std::size_t, std::size_t>> keep;
    for (std::size_t i = 0; i < n; ++i) {
      auto& v = near[i];
      // The verified shortlist (the most similar) first, by its cliques; after it, by similarity.
      const std::size_t sorted =
          std::min(std::max(options.verify_per_map, options.keep_per_map), v.size());
      std::partial_sort(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(sorted), v.end());
      const std::size_t shortlist = std::min(options.verify_per_map, v.size());
      std::stable_sort(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(shortlist),
                       [&](const auto& x, const auto& y) {
                         const std::size_t mx = matches_of(i, x.second);
                         const std::size_t my = matches_of(i, y.second);
                         if (mx != my) return mx > my;
                         return x < y;
                       });
      const std::size_t m = std::min(options.keep_per_map, v.size());
      for (std::size_t k = 0; k < m; ++k)
        keep.emplace(std::min(i, v[k].second), std::max(i, v[k].second));
    }
    for (std::size_t k = 0; k < without.size(); ++k) {
      if (keep.count(without[k]) != 0) {
        const std::size_t count = matches_of(without[k].first, without[k].second);
        CandidatePair c{without[k].first,
                        without[k].second,
                        pair_distance[k] / (1.0 + static_cast<double>(count)),
                        {},
                        {}};
        c.verified_matches = count;
        out.push_back(c);
      }
    }
  }
  for (CandidatePair& c : out) {
    if (!c.prior) c.complete_search = n <= options.all_pairs_max_maps ? "rescue" : "check";
    c.source_metric = summaries[c.source].metric;
    c.target_metric = summaries[c.target].metric;
    c.covariances_assumed =
        summaries[c.source].covariance_assumed || summaries[c.target].covariance_assumed;
  }
  // Best ranked first (stable: ties keep the (source, target) order), then the budget.
  std::stable_sort(out.begin(), out.end(),
                   [](const CandidatePair& a, const CandidatePair& b) { return a.rank < b.rank; });
  if (options.max_pairs > 0 && out.size() > options.max_pairs) out.resize(options.max_pairs);
  return out;
}

}  // namespace lmalign
