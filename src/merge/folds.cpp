// Folds a merge could not rule out (include/lmalign/merge/folds.hpp).
#include "lmalign/merge/folds.hpp"

#include <algorithm>
#include <cmath>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"

namespace lmalign {

namespace {

// A map's landmark centroid (map frame) and extent: the median distance of its landmarks from
// the centroid (0 without landmarks).
struct Extent {
  Vec3 centre_map = Vec3::Zero();
  double radius = 0.0;
};

Extent extent_of(const Map& map) {
  Extent e;
  if (map.landmarks.empty()) return e;
  for (const Landmark& l : map.landmarks) e.centre_map += l.p_world;
  e.centre_map /= static_cast<double>(map.landmarks.size());
  std::vector<double> d;
  d.reserve(map.landmarks.size());
  for (const Landmark& l : map.landmarks) d.push_back((l.p_world - e.centre_map).norm());
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  e.radius = d[d.size() / 2];
  return e;
}

// How far motion m moves points within radius r of c (world units): |m c - c| + angle r +
// |log scale| r.
double motion_size(const Similarity3& m, const Vec3& c, double r) {
  const double angle_rad = rotation_angle_deg(m.rigid.linear()) * kPi / 180.0;
  return (m * c - c).norm() + (angle_rad + std::abs(std::log(m.scale))) * r;
}

}  // namespace

bool FoldOptions::is_valid(std::string* why) const {
  auto bad = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (min_edges < 2) return bad("min_edges must be >= 2");
  if (!(tolerance > 0.0 && tolerance <= 1.0)) return bad("tolerance must be in (0, 1]");
  return true;
}

std::vector<SuspectedFold> suspected_folds(const std::vector<Map>& maps,
                                           const std::vector<Edge>& edges,
                                           const MergeResult& result, const FoldOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("fold options: " + why);
  if (result.maps.size() != maps.size() || result.edges.size() != edges.size()) {
    throw InvalidArgument("suspected_folds: the merge result does not match the maps and edges");
  }
  for (const Edge& e : edges) {
    if (e.source >= maps.size() || e.target >= maps.size()) {
      throw InvalidArgument("suspected_folds: an edge names a map out of range");
    }
  }
  // The rejected trusted edges within one part, by decreasing inliers (ties: edge order).
  std::vector<std::size_t> rejected;
  for (std::size_t e = 0; e < edges.size(); ++e) {
    const EdgeReport& r = result.edges[e];
    if (edges[e].trusted && r.used && r.rejected &&
        result.maps[edges[e].source].component == result.maps[edges[e].target].component) {
      rejected.push_back(e);
    }
  }
  std::stable_sort(rejected.begin(), rejected.end(), [&](std::size_t a, std::size_t b) {
    return edges[a].num_inliers > edges[b].num_inliers;
  });
  std::vector<Extent> extents(maps.size());
  std::vector<bool> measured(maps.size(), false);
  struct Cluster {
    Similarity3 motion;
    std::vector<std::size_t> edges;
  };
  std::vector<Cluster> clusters;
  for (const std::size_t e : rejected) {
    const Edge& ed = edges[e];
    if (!measured[ed.source]) {
      extents[ed.source] = extent_of(maps[ed.source]);
      measured[ed.source] = true;
    }
    // Where the edge puts its source, against where the graph put it: the world motion
    // S_target * S_edge * S_source^-1 (identity when they agree).
    const Similarity3 S_source = result.maps[ed.source].similarity();
    const Similarity3 wanted =
        result.maps[ed.target].similarity() * Similarity3{ed.scale, ed.T_target_source};
    const Similarity3 motion = wanted * S_source.inverse();
    if (!motion.rigid.matrix().allFinite() || !std::isfinite(motion.scale)) continue;
    const Vec3 c = S_source * extents[ed.source].centre_map;
    const double r = S_source.scale * extents[ed.source].radius;
    const double tol = options.tolerance * r;
    bool joined = false;
    for (Cluster& k : clusters) {
      // The same motion, or its inverse (the other end of the edge is the one moved).
      if (motion_size(k.motion.inverse() * motion, c, r) <= tol ||
          motion_size(k.motion * motion, c, r) <= tol) {
        k.edges.push_back(e);
        joined = true;
        break;
      }
    }
    if (!joined) clusters.push_back({motion, {e}});
  }
  std::vector<SuspectedFold> out;
  for (const Cluster& k : clusters) {
    if (k.edges.size() < options.min_edges) continue;
    SuspectedFold f;
    f.edges = k.edges;
    for (const std::size_t e : k.edges) {
      f.maps.push_back(edges[e].source);
      f.maps.push_back(edges[e].target);
    }
    std::sort(f.maps.begin(), f.maps.end());
    f.maps.erase(std::unique(f.maps.begin(), f.maps.end()), f.maps.end());
    f.S_world_moved = k.motion;
    const Edge& first = edges[k.edges.front()];
    const Vec3 c = result.maps[first.source].similarity() * extents[first.source].centre_map;
    f.motion_m = (k.motion * c - c).norm();
    f.motion_deg = rotation_angle_deg(k.motion.rigid.linear());
    out.push_back(std::move(f));
  }
  std::stable_sort(out.begin(), out.end(), [](const SuspectedFold& a, const SuspectedFold& b) {
    return a.edges.size() > b.edges.size();
  });
  return out;
}

}  // namespace lmalign
