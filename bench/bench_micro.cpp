// Micro-benchmarks of the pieces (Google Benchmark; built when it is found): kd-tree queries,
// plain and seeded, and one correspondence pass with and without the exact reuse, on the real
// pair. Not part of `make bench`'s table; run build/bench/lmalign_bench_micro directly.
#include <benchmark/benchmark.h>

#include "common.hpp"
#include "lmalign/registration/correspondence.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign::bench {
namespace {

const RealPair& pair() {
  static const RealPair p = load_real_pair();
  return p;
}

void BM_KdTreeBuild(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(KdTree(pair().target));
}
BENCHMARK(BM_KdTreeBuild);

void BM_Knn(benchmark::State& state) {
  const KdTree tree(pair().target);
  const std::size_t k = static_cast<std::size_t>(state.range(0));
  std::vector<PointIndex> idx(k);
  std::vector<double> d2(k);
  for (auto _ : state) {
    for (const Vec3& q : pair().source)
      benchmark::DoNotOptimize(tree.knn(q, k, idx.data(), d2.data()));
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(pair().source.size()));
}
BENCHMARK(BM_Knn)->Arg(1)->Arg(6)->Arg(8);

// One ICP correspondence pass at a pose 1 mm / 0.05 deg from the previous one.
void BM_FindAfterSmallMotion(benchmark::State& state) {
  const KdTree tree(pair().target);
  CorrespondenceOptions o;
  o.kind = CorrespondenceKind::kWeightedKnn;
  o.k = 5;
  const CorrespondenceFinder finder(tree, pair().target_weights, o);
  const bool reuse = state.range(0) != 0;
  CorrespondenceWorkspace ws;
  Points3 moved;
  Correspondences c;
  const Isometry3 a = Isometry3::Identity();
  const Isometry3 b = pose_from_xyz_rpy_deg(0.001, 0, 0, 0, 0, 0.05);
  bool flip = false;
  for (auto _ : state) {
    finder.find(pair().source, flip ? a : b, moved, c, ws, reuse);
    flip = !flip;
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(pair().source.size()));
}
BENCHMARK(BM_FindAfterSmallMotion)->Arg(0)->Arg(1);

}  // namespace
}  // namespace lmalign::bench

BENCHMARK_MAIN();
