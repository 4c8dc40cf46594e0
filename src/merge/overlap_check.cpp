// The merged map checked against itself (include/lmalign/merge/overlap_check.hpp).
#include "lmalign/merge/overlap_check.hpp"

#include <omp.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <memory>
#include <set>
#include <utility>

#include "lmalign/core/error.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

namespace {

// chi^2 quantile, 3 degrees of freedom, 0.99: the gate of one landmark pair.
constexpr double kGateChi2 = 11.345;

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h), v.end());
  return v[h];
}

// One placed map in the world frame: its landmarks, their variances, its spacing and box.
struct PlacedMap {
  std::unique_ptr<KdTree> tree;
  std::vector<double> sigma2;  // per landmark, world units^2 (a third of the covariance's trace)
  double spacing = 0.0;        // median nearest-neighbour distance, world units
  double footprint = 0.0;      // the footprint radius, world units
  Eigen::AlignedBox3d box;
};

PlacedMap place(const Map& map, const MapPose& pose, const OverlapCheckOptions& o) {
  PlacedMap out;
  const Similarity3 S = pose.similarity();
  const double s2 = S.scale * S.scale;
  Points3 points;
  points.reserve(map.landmarks.size());
  std::vector<double> known;
  out.sigma2.resize(map.landmarks.size(), -1.0);
  for (std::size_t k = 0; k < map.landmarks.size(); ++k) {
    const Landmark& l = map.landmarks[k];
    points.push_back(S * l.p_world);
    out.box.extend(points.back());
    if (!l.covariance_unknown) {
      const double v = s2 * l.cov_world_m2.trace() / 3.0;
      if (std::isfinite(v) && v >= 0.0) {
        out.sigma2[k] = v;
        known.push_back(v);
      }
    }
  }
  out.tree = std::make_unique<KdTree>(std::move(points));
  std::vector<double> nn;
  nn.reserve(out.tree->size());
  PointIndex idx[2];
  double d2[2];
  for (const Vec3& p : out.tree->points()) {
    if (out.tree->knn(p, 2, idx, d2) == 2) nn.push_back(std::sqrt(d2[1]));
  }
  out.spacing = median(nn);
  const double fallback = known.empty() ? std::pow(0.1 * out.spacing, 2) : median(known);
  for (double& v : out.sigma2) {
    if (v < 0.0) v = fallback;
  }
  const double typical_gate = std::sqrt(kGateChi2 * 2.0 * median(out.sigma2));
  out.footprint = std::max(o.footprint_spacings * out.spacing, 3.0 * typical_gate);
  return out;
}

// Landmarks of `a` in the footprint of `b`, and how many of them agree with b's nearest.
std::pair<std::size_t, std::size_t> one_direction(const PlacedMap& a, const PlacedMap& b) {
  std::size_t in = 0, agree = 0;
  const double r2 = b.footprint * b.footprint;
  const Points3& pa = a.tree->points();
  for (std::size_t k = 0; k < pa.size(); ++k) {
    PointIndex j = 0;
    double d2 = 0.0;
    if (!b.tree->nearest(pa[k], &j, &d2) || d2 > r2) continue;
    ++in;
    if (d2 <= kGateChi2 * (a.sigma2[k] + b.sigma2[j])) ++agree;
  }
  return {in, agree};
}

}  // namespace

bool OverlapCheckOptions::is_valid(std::string* why) const {
  auto bad = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(footprint_spacings > 0.0) || !std::isfinite(footprint_spacings))
    return bad("footprint_spacings must be finite and > 0");
  if (min_landmarks < 1) return bad("min_landmarks must be >= 1");
  if (!(contradiction_ratio > 0.0 && contradiction_ratio < 1.0))
    return bad("contradiction_ratio must be in (0, 1)");
  if (threads < 0) return bad("threads must be >= 0");
  return true;
}

std::size_t OverlapCheck::num_contradicted() const {
  return static_cast<std::size_t>(std::count_if(
      pairs.begin(), pairs.end(), [](const OverlapPair& p) { return p.contradicted; }));
}

OverlapCheck check_overlaps(const std::vector<Map>& maps, const MergeResult& result,
                            const std::vector<Edge>& edges, const OverlapCheckOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("overlap check options: " + why);
  if (result.maps.size() != maps.size() || result.edges.size() != edges.size()) {
    throw InvalidArgument("check_overlaps: the merge result does not match the maps and edges");
  }
  const std::size_t n = maps.size();
  OverlapCheck out;
  out.ran = true;
  out.contradicted_per_map.assign(n, 0);
  out.contradicted_per_component.assign(result.num_components, 0);
  std::set<std::pair<std::size_t, std::size_t>> joined;
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (!result.edges[e].used || result.edges[e].rejected) continue;
    joined.emplace(std::min(edges[e].source, edges[e].target),
                   std::max(edges[e].source, edges[e].target));
  }
  const int threads = options.threads > 0 ? options.threads : omp_get_max_threads();
  std::vector<PlacedMap> placed(n);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n); ++i) {
    const auto k = static_cast<std::size_t>(i);
    placed[k] = place(maps[k], result.maps[k], options);
  }
  // Pairs of one component whose boxes, grown by the footprint, meet.
  std::vector<std::pair<std::size_t, std::size_t>> todo;
  for (std::size_t a = 0; a < n; ++a) {
    if (placed[a].tree->size() < options.min_landmarks) continue;
    for (std::size_t b = a + 1; b < n; ++b) {
      if (result.maps[a].component != result.maps[b].component) continue;
      if (placed[b].tree->size() < options.min_landmarks) continue;
      const double grow = std::max(placed[a].footprint, placed[b].footprint);
      Eigen::AlignedBox3d box = placed[a].box;
      box.min().array() -= grow;
      box.max().array() += grow;
      if (box.intersects(placed[b].box)) todo.emplace_back(a, b);
    }
  }
  std::vector<OverlapPair> judged(todo.size());
  std::vector<char> counted(todo.size(), 0);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (std::ptrdiff_t t = 0; t < static_cast<std::ptrdiff_t>(todo.size()); ++t) {
    const auto k = static_cast<std::size_t>(t);
    const auto [a, b] = todo[k];
    const auto ab = one_direction(placed[a], placed[b]);
    if (ab.first < options.min_landmarks) continue;
    const auto ba = one_direction(placed[b], placed[a]);
    if (ba.first < options.min_landmarks) continue;
    OverlapPair& p = judged[k];
    p.a = a;
    p.b = b;
    p.component = result.maps[a].component;
    p.in_footprint = std::min(ab.first, ba.first);
    p.agreement = std::min(static_cast<double>(ab.second) / static_cast<double>(ab.first),
                           static_cast<double>(ba.second) / static_cast<double>(ba.first));
    p.joined_by_edge = joined.count({a, b}) > 0;
    counted[k] = 1;
  }
  std::vector<double> reference;
  for (std::size_t k = 0; k < todo.size(); ++k) {
    if (!counted[k]) continue;
    out.pairs.push_back(judged[k]);
    if (judged[k].joined_by_edge) reference.push_back(judged[k].agreement);
  }
  out.reference_agreement = median(reference);
  const double threshold = options.contradiction_ratio * out.reference_agreement;
  for (OverlapPair& p : out.pairs) {
    p.contradicted = p.agreement < threshold;
    if (!p.contradicted) continue;
    ++out.contradicted_per_map[p.a];
    ++out.contradicted_per_map[p.b];
    if (p.component < out.contradicted_per_component.size()) {
      ++out.contradicted_per_component[p.component];
    }
  }
  return out;
}

}  // namespace lmalign
