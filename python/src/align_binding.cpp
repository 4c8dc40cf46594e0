#include "align_binding.hpp"

#include <omp.h>

#include <chrono>

#include <limits>
#include "lmalign/core/error.hpp"

#include "lmalign/registration/robust.hpp"

namespace lmalign::python {

namespace {

/// Sets OpenMP's thread count of the calling thread for the lifetime of the object.
class ThreadCount {
 public:
  explicit ThreadCount(int threads) : previous_(omp_get_max_threads()), set_(threads > 0) {
    if (set_) omp_set_num_threads(threads);
  }
  ~ThreadCount() {
    if (set_) omp_set_num_threads(previous_);
  }
  ThreadCount(const ThreadCount&) = delete;
  ThreadCount& operator=(const ThreadCount&) = delete;

 private:
  int previous_;
  bool set_;
};

}  // namespace

AlignOutcome run_alignment(const Points3& source_points,
                           const std::vector<Mat3>& source_covariances_m2,
                           const PreparedTarget& target, const AlignRequest& request) {
  const PaperStrategy s = parse_paper_strategy(request.strategy);
  if (request.threads < 0) throw InvalidArgument("threads: must be >= 0 (0 = OpenMP's default)");
  const ThreadCount threads(request.threads);
  const auto now_s = [] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
  };
  AlignOutcome out;
  out.started_s = now_s();
  out.strategy = to_string(s);
  // As apps/lmalign/cmd_align.cpp, run_align(): the paper's strategies always get the budget
  // and distance (150 iterations and unlimited by default); lmalign's own only those given.
  StrategyRequest req;
  req.strategy = s;
  req.k = request.k;
  req.initial_guess = request.initial_guess;
  req.prior = request.prior;
  if (is_paper_strategy(s)) {
    req.max_iterations = request.max_iterations.value_or(150);
    req.max_distance_m = request.max_distance_m.value_or(std::numeric_limits<double>::infinity());
  } else {
    req.max_iterations = request.max_iterations;
    if (s != PaperStrategy::kAdaptive) req.max_distance_m = request.max_distance_m;
  }
  StrategySource src;
  src.positions = source_points;
  src.covariances_m2 = source_covariances_m2;
  src.up = request.source_up;
  out.outcome = run_strategy(src, target, req);
  out.finished_s = now_s();
  return out;
}

}  // namespace lmalign::python
