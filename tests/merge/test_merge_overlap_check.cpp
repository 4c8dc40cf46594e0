// The merged map checked against itself (merge/overlap_check.hpp), on the synthetic fleet
// (sim/fleet_sim.hpp) without aligning anything: the true poses agree with themselves, and a map
// laid on another place is contradicted by every map it then overlaps.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/merge/merge.hpp"
#include "lmalign/merge/overlap_check.hpp"
#include "lmalign/sim/fleet_sim.hpp"

namespace lmalign {
namespace {

// A fleet of num_maps maps (seed 3) without planted look-alikes.
sim::FleetScene fleet_without_twins(std::size_t num_maps) {
  sim::FleetSimOptions o;
  o.num_maps = num_maps;
  o.seed = 3;
  o.num_twins = 0;
  return sim::simulate_fleet(o);
}

// A merge result holding the fleet's true poses in one part, and one kept edge per pair that
// shares at least 20% of its landmarks (the edges' own transforms are the truth).
MergeResult true_merge(const sim::FleetScene& scene, std::vector<Edge>* edges) {
  MergeResult r;
  r.maps.resize(scene.maps.size());
  r.num_components = 1;
  for (std::size_t i = 0; i < scene.maps.size(); ++i) {
    r.maps[i].T_world_map = scene.T_world_map[i];
    r.maps[i].component = 0;
  }
  for (const sim::FleetOverlap& v : scene.overlaps) {
    if (v.shared_fraction < 0.2) continue;
    Edge e;
    e.source = v.i;
    e.target = v.j;
    e.T_target_source = scene.T_world_map[v.j].inverse() * scene.T_world_map[v.i];
    e.trusted = true;
    edges->push_back(e);
    EdgeReport rep;
    rep.used = true;
    r.edges.push_back(rep);
  }
  return r;
}

// Measured (16 maps, seed 3, 30 edges): 39 pairs judged at the truth, the edge-joined pairs'
// agreement a median 0.64, none contradicted; map 0 laid on the place of map 15, turned by 90 deg:
// the two pairs it then forms (with maps 11 and 15) are contradicted at agreement 0, no other.
TEST(MergeOverlapCheck, TruePosesAgreeAndAMapLaidOnAnotherPlaceIsContradicted) {
  const sim::FleetScene scene = fleet_without_twins(16);
  std::vector<Edge> edges;
  MergeResult merge = true_merge(scene, &edges);
  ASSERT_GT(edges.size(), 8u);
  const OverlapCheck right = check_overlaps(scene.maps, merge, edges);
  EXPECT_TRUE(right.ran);
  EXPECT_GE(right.pairs.size(), edges.size());
  EXPECT_GT(right.reference_agreement, 0.5);
  EXPECT_EQ(right.num_contradicted(), 0u);
  ASSERT_EQ(right.contradicted_per_component.size(), 1u);
  EXPECT_EQ(right.contradicted_per_component[0], 0u);

  // Map 0 on the place of the map farthest from it.
  const std::size_t moved = 0;
  std::size_t far = 1;
  for (std::size_t j = 1; j < scene.maps.size(); ++j) {
    const double d = (scene.T_world_map[j].translation() - scene.T_world_map[moved].translation())
                         .head<2>()
                         .norm();
    const double best =
        (scene.T_world_map[far].translation() - scene.T_world_map[moved].translation())
            .head<2>()
            .norm();
    if (d > best) far = j;
  }
  Isometry3 turn = Isometry3::Identity();
  turn.linear() = Eigen::AngleAxisd(0.5 * kPi, Vec3::UnitZ()).toRotationMatrix();
  merge.maps[moved].T_world_map = scene.T_world_map[far] * turn;
  const OverlapCheck wrong = check_overlaps(scene.maps, merge, edges);
  EXPECT_GT(wrong.contradicted_per_map[moved], 0u);
  EXPECT_GT(wrong.num_contradicted(), 0u);
  EXPECT_EQ(wrong.contradicted_per_component[0], wrong.num_contradicted());
  for (const OverlapPair& p : wrong.pairs) {
    if (p.contradicted) {
      EXPECT_TRUE(p.a == moved || p.b == moved) << p.a << " " << p.b;
      EXPECT_LT(p.agreement, 0.25 * wrong.reference_agreement);
    }
  }
  // The same on one thread as on the default count.
  OverlapCheckOptions one;
  one.threads = 1;
  const OverlapCheck again = check_overlaps(scene.maps, merge, edges, one);
  ASSERT_EQ(again.pairs.size(), wrong.pairs.size());
  for (std::size_t k = 0; k < again.pairs.size(); ++k) {
    EXPECT_EQ(again.pairs[k].a, wrong.pairs[k].a);
    EXPECT_EQ(again.pairs[k].b, wrong.pairs[k].b);
    EXPECT_EQ(again.pairs[k].agreement, wrong.pairs[k].agreement);
    EXPECT_EQ(again.pairs[k].contradicted, wrong.pairs[k].contradicted);
  }
  // Maps in different parts are never compared.
  merge.maps[moved].component = 1;
  merge.num_components = 2;
  const OverlapCheck apart = check_overlaps(scene.maps, merge, edges);
  EXPECT_EQ(apart.contradicted_per_map[moved], 0u);
  EXPECT_EQ(apart.num_contradicted(), 0u);
}

// A fold (overlap_repair.hpp): 16 maps with an edge per overlapping pair, and a group of edges
// with more inliers that agree with each other but lay maps of the top row on the bottom row,
// turned by 180 deg. The cycle check keeps the group and rejects the true edges it outvotes; the
// overlap check sees the folded maps disagree, and the repair drops the group.
// Measured: 2 fold edges; without the repair maps 14 and 15 are 26 and 48 m off and 3 pairs
// contradicted; with it every map is back (within 1e-13 m) and the 2 fold edges are exactly the
// edges dropped (a true edge between the two folded maps was dropped with them, then taken
// back).
TEST(MergeOverlapRepair, AGroupOfAgreeingFalseEdgesThatFoldsThePartIsDropped) {
  const sim::FleetScene scene = fleet_without_twins(16);
  const std::size_t n = scene.maps.size();
  auto edge = [&](std::size_t i, std::size_t j, const Isometry3& T_ji, std::size_t inliers) {
    Edge e;
    e.source = i;
    e.target = j;
    e.T_target_source = T_ji;
    e.trusted = true;
    e.covariance = Mat6::Identity() * 1e-6;
    e.covariance_valid = true;
    e.num_inliers = inliers;
    return e;
  };
  // The rows by the maps' true y (the fleet's centres lie on a 4 x 4 grid).
  std::vector<std::size_t> by_y(n);
  for (std::size_t i = 0; i < n; ++i) by_y[i] = i;
  std::sort(by_y.begin(), by_y.end(), [&](std::size_t a, std::size_t b) {
    return scene.T_world_map[a].translation().y() < scene.T_world_map[b].translation().y();
  });
  std::vector<bool> top(n, false), bottom(n, false);
  for (std::size_t k = 0; k < 4; ++k) {
    bottom[by_y[k]] = true;
    top[by_y[n - 1 - k]] = true;
  }
  std::vector<Edge> edges;
  for (const sim::FleetOverlap& v : scene.overlaps) {
    if (v.shared_fraction < 0.2) continue;
    edges.push_back(edge(v.i, v.j, scene.T_world_map[v.j].inverse() * scene.T_world_map[v.i], 50));
  }
  // The fold G: a half turn about the centre of the maps, which takes the top row onto the bottom.
  Vec3 centre = Vec3::Zero();
  for (const Isometry3& T : scene.T_world_map) centre += T.translation();
  centre /= static_cast<double>(n);
  Isometry3 G = Isometry3::Identity();
  G.linear() = Eigen::AngleAxisd(kPi, Vec3::UnitZ()).toRotationMatrix();
  G.translation() = centre - G.linear() * centre;
  std::size_t fold_edges = 0;
  for (std::size_t i = 0; i < n && fold_edges < 4; ++i) {
    if (!top[i]) continue;
    for (std::size_t j = 0; j < n && fold_edges < 4; ++j) {
      if (!bottom[j]) continue;
      const Isometry3 folded = G * scene.T_world_map[i];
      if ((folded.translation() - scene.T_world_map[j].translation()).head<2>().norm() > 8.0) {
        continue;
      }
      edges.push_back(edge(i, j, scene.T_world_map[j].inverse() * folded, 500));
      ++fold_edges;
    }
  }
  ASSERT_GE(fold_edges, 2u);
  const std::vector<std::optional<MapPrior>> none(n);
  auto off_m = [&](const MergeResult& r, std::size_t i) {
    // Relative to the first bottom map, which no fold moves.
    const std::size_t ref = by_y[0];
    const Isometry3 truth = scene.T_world_map[ref].inverse() * scene.T_world_map[i];
    const Isometry3 got = r.maps[ref].T_world_map.inverse() * r.maps[i].T_world_map;
    return (truth.inverse() * got).translation().norm();
  };
  MergeOptions without;
  without.repair.enabled = false;
  const MergeGraph folded = solve_and_check(scene.maps, none, edges, without);
  EXPECT_GT(folded.overlaps.num_contradicted(), 0u);
  std::size_t off = 0;
  for (std::size_t i = 0; i < n; ++i) off += off_m(folded.result, i) > 1.0 ? 1 : 0;
  EXPECT_GT(off, 0u);

  const MergeGraph repaired = solve_and_check(scene.maps, none, edges, MergeOptions{});
  EXPECT_EQ(repaired.overlaps.num_contradicted(), 0u);
  EXPECT_EQ(repaired.repair.contradicted_before, folded.overlaps.num_contradicted());
  EXPECT_EQ(repaired.result.num_components, 1u);
  for (std::size_t i = 0; i < n; ++i) EXPECT_LT(off_m(repaired.result, i), 0.01) << i;
  ASSERT_EQ(repaired.repair.dropped.size(), fold_edges);
  for (const std::size_t e : repaired.repair.dropped) {
    EXPECT_GE(e, edges.size() - fold_edges);  // the fold's edges, none of the true ones
    EXPECT_TRUE(repaired.result.edges[e].rejected);
    EXPECT_NE(repaired.result.edges[e].reject_reason.find("overlap check"), std::string::npos);
  }
}

TEST(MergeOverlapCheck, InvalidOptionsAndSizesThrow) {
  const sim::FleetScene scene = fleet_without_twins(4);
  std::vector<Edge> edges;
  const MergeResult merge = true_merge(scene, &edges);
  for (double ratio : {0.0, 1.0, std::nan("")}) {
    OverlapCheckOptions bad;
    bad.contradiction_ratio = ratio;
    EXPECT_THROW(check_overlaps(scene.maps, merge, edges, bad), InvalidArgument);
  }
  OverlapCheckOptions bad;
  bad.footprint_spacings = 0.0;
  EXPECT_THROW(check_overlaps(scene.maps, merge, edges, bad), InvalidArgument);
  std::vector<Map> fewer(scene.maps.begin(), scene.maps.end() - 1);
  EXPECT_THROW(check_overlaps(fewer, merge, edges), InvalidArgument);
}

TEST(MergeOverlapCheck, TheModeNamesSetTheCheckAndTheRepair) {
  MergeOptions o;
  set_overlap_check_mode("off", &o);
  EXPECT_FALSE(o.overlaps.enabled);
  EXPECT_FALSE(o.repair.enabled);
  set_overlap_check_mode("check", &o);
  EXPECT_TRUE(o.overlaps.enabled);
  EXPECT_FALSE(o.repair.enabled);
  set_overlap_check_mode("repair", &o);
  EXPECT_TRUE(o.overlaps.enabled);
  EXPECT_TRUE(o.repair.enabled);
  for (const char* bad : {"", "Repair", "on"}) {
    MergeOptions before;
    before.repair.enabled = false;
    try {
      set_overlap_check_mode(bad, &before);
      ADD_FAILURE() << "no error for '" << bad << "'";
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find("expected 'repair', 'check' or 'off'"),
                std::string::npos);
    }
    EXPECT_FALSE(before.repair.enabled);  // untouched
  }
}

}  // namespace
}  // namespace lmalign
