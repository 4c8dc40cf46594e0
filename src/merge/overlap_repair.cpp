// The merge repaired by its own overlap check (include/lmalign/merge/overlap_repair.hpp).
#include "lmalign/merge/overlap_repair.hpp"

#include <algorithm>
#include <numeric>
#include <utility>

#include "lmalign/core/error.hpp"

namespace lmalign {

namespace {

bool kept(const MergeResult& r, std::size_t e) { return r.edges[e].used && !r.edges[e].rejected; }

// Maps in the largest part.
std::size_t largest_part(const MergeResult& r) {
  std::vector<std::size_t> size(r.num_components, 0);
  for (const MapPose& p : r.maps) {
    if (p.component < size.size()) ++size[p.component];
  }
  return size.empty() ? 0 : *std::max_element(size.begin(), size.end());
}

// A spanning forest of the kept edges, Kruskal by decreasing inliers (ties: edge order): the
// tree edges at each map.
std::vector<std::vector<std::size_t>> spanning_forest(const std::vector<Edge>& edges,
                                                      const MergeResult& r, std::size_t n) {
  std::vector<std::size_t> order;
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (kept(r, e)) order.push_back(e);
  }
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return edges[a].num_inliers > edges[b].num_inliers;
  });
  std::vector<std::size_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](std::size_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  std::vector<std::vector<std::size_t>> tree(n);
  for (const std::size_t e : order) {
    const std::size_t ri = find(edges[e].source), rj = find(edges[e].target);
    if (ri == rj) continue;
    parent[std::max(ri, rj)] = std::min(ri, rj);
    tree[edges[e].source].push_back(e);
    tree[edges[e].target].push_back(e);
  }
  return tree;
}

std::size_t other_end(const Edge& e, std::size_t a) { return e.source == a ? e.target : e.source; }

// The tree edges on the path from a to b (none if they are not connected).
std::vector<std::size_t> tree_path(const std::vector<Edge>& edges,
                                   const std::vector<std::vector<std::size_t>>& tree, std::size_t a,
                                   std::size_t b) {
  std::vector<std::optional<std::size_t>> via(tree.size());
  std::vector<bool> seen(tree.size(), false);
  std::vector<std::size_t> queue{a};
  seen[a] = true;
  for (std::size_t h = 0; h < queue.size() && !seen[b]; ++h) {
    for (const std::size_t t : tree[queue[h]]) {
      const std::size_t c = other_end(edges[t], queue[h]);
      if (seen[c]) continue;
      seen[c] = true;
      via[c] = t;
      queue.push_back(c);
    }
  }
  std::vector<std::size_t> path;
  if (!seen[b]) return path;
  for (std::size_t c = b; c != a; c = other_end(edges[*via[c]], c)) path.push_back(*via[c]);
  return path;
}

// The side of the tree cut at tree edge `cut` that holds cut's source.
std::vector<bool> one_side(const std::vector<Edge>& edges,
                           const std::vector<std::vector<std::size_t>>& tree, std::size_t cut) {
  std::vector<bool> side(tree.size(), false);
  std::vector<std::size_t> queue{edges[cut].source};
  side[edges[cut].source] = true;
  for (std::size_t h = 0; h < queue.size(); ++h) {
    for (const std::size_t t : tree[queue[h]]) {
      if (t == cut) continue;
      const std::size_t c = other_end(edges[t], queue[h]);
      if (side[c]) continue;
      side[c] = true;
      queue.push_back(c);
    }
  }
  return side;
}

struct Trial {
  std::vector<std::size_t> group;
  MergeResult result;
  OverlapCheck check;
};

}  // namespace

bool OverlapRepairOptions::is_valid(std::string* why) const {
  auto bad = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (max_rounds < 1) return bad("max_rounds must be >= 1");
  if (trials_per_round < 1) return bad("trials_per_round must be >= 1");
  return true;
}

OverlapRepair repair_overlaps(const std::vector<Map>& maps,
                              const std::vector<std::optional<MapPrior>>& priors,
                              const std::vector<Edge>& edges, const PoseGraphOptions& graph,
                              const std::vector<bool>& scale_free,
                              const OverlapCheckOptions& overlaps,
                              const OverlapRepairOptions& options, MergeResult* result,
                              OverlapCheck* check) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("overlap repair options: " + why);
  if (result->edges.size() != edges.size() || result->maps.size() != maps.size()) {
    throw InvalidArgument("repair_overlaps: the merge result does not match the maps and edges");
  }
  const std::size_t n = maps.size();
  OverlapRepair out;
  out.contradicted_before = check->num_contradicted();
  std::vector<Edge> current = edges;
  std::vector<std::string> reasons(edges.size());
  while (out.rounds < options.max_rounds && check->num_contradicted() > 0) {
    ++out.rounds;
    const std::vector<std::vector<std::size_t>> tree = spanning_forest(current, *result, n);
    std::vector<std::size_t> crossed(edges.size(), 0);
    for (const OverlapPair& p : check->pairs) {
      if (!p.contradicted) continue;
      for (const std::size_t t : tree_path(current, tree, p.a, p.b)) ++crossed[t];
    }
    std::vector<std::size_t> candidates;
    for (std::size_t e = 0; e < edges.size(); ++e) {
      if (crossed[e] > 0) candidates.push_back(e);
    }
    std::stable_sort(candidates.begin(), candidates.end(),
                     [&](std::size_t a, std::size_t b) { return crossed[a] > crossed[b]; });
    if (candidates.size() > static_cast<std::size_t>(options.trials_per_round)) {
      candidates.resize(static_cast<std::size_t>(options.trials_per_round));
    }
    const std::size_t parts = result->num_components;
    const std::size_t largest = largest_part(*result);
    std::optional<Trial> best;
    for (const std::size_t cut : candidates) {
      ++out.trials;
      const std::vector<bool> side = one_side(current, tree, cut);
      Trial t;
      std::vector<Edge> trial_edges = current;
      for (std::size_t e = 0; e < edges.size(); ++e) {
        if (!kept(*result, e) || side[current[e].source] == side[current[e].target]) continue;
        t.group.push_back(e);
        trial_edges[e].trusted = false;
      }
      t.result = solve_pose_graph(n, priors, trial_edges, graph, scale_free);
      if (t.result.num_components > parts || largest_part(t.result) < largest) continue;
      t.check = check_overlaps(maps, t.result, trial_edges, overlaps);
      const std::size_t bar = best ? best->check.num_contradicted() : check->num_contradicted();
      if (t.check.num_contradicted() < bar) best = std::move(t);
    }
    if (!best) break;
    const std::string reason =
        "rejected by the overlap check: with it, " + std::to_string(check->num_contradicted()) +
        " pair(s) of maps overlapped where their landmarks disagree; without its group of " +
        std::to_string(best->group.size()) + " edge(s), " +
        std::to_string(best->check.num_contradicted());
    for (const std::size_t e : best->group) {
      current[e].trusted = false;
      reasons[e] = reason;
      out.dropped.push_back(e);
    }
    *result = std::move(best->result);
    *check = std::move(best->check);
  }
  // A group may hold edges that agree with the repaired part too (a true edge between two folded
  // maps): each dropped edge is tried again, in the order dropped, and taken back when the graph
  // keeps it and it adds no contradicted pair, no part, and leaves the largest part as large.
  std::vector<std::size_t> still;
  for (const std::size_t e : out.dropped) {
    ++out.trials;
    std::vector<Edge> trial_edges = current;
    trial_edges[e].trusted = edges[e].trusted;
    MergeResult r = solve_pose_graph(n, priors, trial_edges, graph, scale_free);
    if (!kept(r, e) || r.num_components > result->num_components ||
        largest_part(r) < largest_part(*result)) {
      still.push_back(e);
      continue;
    }
    OverlapCheck c = check_overlaps(maps, r, trial_edges, overlaps);
    if (c.num_contradicted() > check->num_contradicted()) {
      still.push_back(e);
      continue;
    }
    current = std::move(trial_edges);
    *result = std::move(r);
    *check = std::move(c);
  }
  out.dropped = std::move(still);
  for (const std::size_t e : out.dropped) {
    EdgeReport& r = result->edges[e];
    r.used = true;
    r.rejected = true;
    r.skip_reason.clear();
    r.reject_reason = reasons[e];
  }
  return out;
}

}  // namespace lmalign
