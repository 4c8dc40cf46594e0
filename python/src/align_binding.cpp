#include "align_binding.hpp"

#include <omp.h>

#include <chrono>

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
  // As apps/lmalign/cmd_align.cpp, run_align().
  if (is_paper_strategy(s)) {
    RegistrationOptions o = RegistrationOptions::paper(s, request.k);
    o.max_correspondence_distance_m =
        request.max_distance_m.value_or(std::numeric_limits<double>::infinity());
    o.convergence.max_iterations = request.max_iterations.value_or(150);
    out.result = align(source_points, target, o, request.T_target_source_init);
  } else {
    RobustRegistrationOptions ro = robust_strategy_options(s, request.k);
    if (request.max_iterations || request.max_distance_m) {
      ro = with_limits(ro, request.max_iterations.value_or(ro.max_iterations),
                       request.max_distance_m.value_or(std::numeric_limits<double>::infinity()));
    }
    out.result = align_robust(source_points, target, ro, request.T_target_source_init,
                              source_covariances_m2.empty() ? nullptr : &source_covariances_m2);
  }
  out.trust = judge_alignment(source_points, target.tree(), out.result.T_target_source, {},
                              &out.inlier_covariance);
  out.finished_s = now_s();
  return out;
}

}  // namespace lmalign::python
