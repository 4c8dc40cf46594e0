#include "align_binding.hpp"

#include <omp.h>

#include <chrono>

#include "lmalign/core/error.hpp"

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
                           const std::vector<Vec3>& source_view_directions,
                           const PreparedTarget& target, const AlignRequest& request) {
  const Preset preset =
      request.strategy.empty() ? recommended_preset() : find_preset(request.strategy);
  if (request.threads < 0) throw InvalidArgument("threads: must be >= 0 (0 = OpenMP's default)");
  lmalign::AlignRequest r = request;
  r.describe_maps(request.source_header, request.target_header);
  r.resolve(preset);  // text values read by their rows; every check before the alignment
  const ThreadCount threads(request.threads);
  const auto now_s = [] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
  };
  AlignOutcome out;
  out.started_s = now_s();
  out.strategy = preset.name;
  SourceView view;
  view.positions = &source_points;
  view.covariances_m2 = &source_covariances_m2;
  view.up = request.source_up;
  view.view_directions = &source_view_directions;
  out.summary = align(preset, view, target, r);
  out.finished_s = now_s();
  return out;
}

}  // namespace lmalign::python
