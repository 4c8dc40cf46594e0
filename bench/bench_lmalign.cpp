// lmalign's side of `make bench`: the real pair (desk_gt_a displaced by Table 1, onto desk_gt_b)
// with N forced iterations (convergence disabled). One configuration per process (--config), so
// that each peak-memory figure is clean; bench/run_bench.py runs them all.
//
// The timed section is what a user pays from two point sets in memory to the result: building
// the target (kd-tree, weights installed) and align(), which includes the initial and final
// fitness scores.
#include <omp.h>

#include <cstdio>
#include <exception>
#include <string>

#include "common.hpp"
#include "lmalign/registration/registration.hpp"

namespace lmalign::bench {
namespace {

int run(const Args& args) {
  const RealPair pair = load_real_pair();
  const std::string& c = args.config;
  WeightKind strategy = WeightKind::kObservations;
  bool reuse = true, scored = false;
  int threads = 0;
  std::string description;
  if (c == "lmalign_base") {
    strategy = WeightKind::kUniform;
    description = "lmalign base (nearest), exact neighbour reuse";
  } else if (c == "lmalign_base_plain") {
    strategy = WeightKind::kUniform;
    reuse = false;
    description = "lmalign base, no neighbour reuse (plain search every iteration)";
  } else if (c == "lmalign_weighted_k5") {
    description = "lmalign weighted k=5 (observations), exact neighbour reuse";
  } else if (c == "lmalign_weighted_k5_plain") {
    reuse = false;
    description = "lmalign weighted k=5, no neighbour reuse";
  } else if (c == "lmalign_weighted_k5_scored") {
    scored = true;
    description = "lmalign weighted k=5 with the score at every iteration (as the paper timed)";
  } else if (c == "lmalign_weighted_k5_1thread") {
    threads = 1;
    description = "lmalign weighted k=5, exact neighbour reuse, 1 thread";
  } else {
    std::fprintf(stderr, "bench_lmalign: unknown --config %s\n", c.c_str());
    return 2;
  }
  if (threads > 0) omp_set_num_threads(threads);
  const AlignRequest request = forced_paper_request(args.iterations, reuse, scored);
  const Preset preset = find_preset(paper_preset_name(strategy));
  const WeightKind weight = strategy;
  SourceView view;
  view.positions = &pair.source;

  auto once = [&]() {
    PreparedTarget target(pair.target);
    if (weight != WeightKind::kUniform) target.set_weights(weight, pair.target_weights);
    const RegistrationResult r = align(preset, view, target, request).registration;
    return RunResult{r.iterations, r.final_score_m2};
  };
  return measure(c, "lmalign", description, args.reps, once,
                 {{"threads", std::to_string(omp_get_max_threads())},
                  {"source_points", std::to_string(pair.source.size())},
                  {"target_points", std::to_string(pair.target.size())}});
}

}  // namespace
}  // namespace lmalign::bench

int main(int argc, char** argv) {
  return lmalign::bench::run_main("bench_lmalign", argc, argv, lmalign::bench::run);
}
