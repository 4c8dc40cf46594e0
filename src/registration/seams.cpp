// The definitions of the seams' header (include/lmalign/registration/seams.hpp): the seams'
// names, the source landmarks read off a map, and a matcher's default fitness score.
#include "lmalign/registration/seams.hpp"

#include "lmalign/core/enum_names.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/score.hpp"
#include "lmalign/registration/stages/data_scales.hpp"

namespace lmalign {

std::string to_string(Seam seam) {
  static constexpr EnumName<Seam> kNames[] = {
      {Seam::kInitialiser, "initialiser"}, {Seam::kMatcher, "matcher"},
      {Seam::kRejector, "rejectors"},      {Seam::kKernel, "kernel"},
      {Seam::kEstimator, "estimator"},     {Seam::kSchedule, "schedule"},
      {Seam::kScorer, "scorer"},           {Seam::kTrustJudge, "trust"}};
  return name_of(kNames, seam);
}

SourceLandmarks SourceLandmarks::from_map(const Map& map) {
  map.validate();
  SourceLandmarks s;
  s.positions = map.positions();
  s.covariances_m2 = map.covariances_m2();
  s.up = estimate_up_axis(map);
  s.view_directions = map.view_directions();
  return s;
}

SourceLandmarks SourceLandmarks::moved(const Isometry3& T) const {
  SourceLandmarks m;
  m.positions = transform_points(T, positions);
  m.covariances_m2 = transform_covariances(T, covariances_m2);
  if (up) m.up = T.linear() * *up;
  m.view_directions.reserve(view_directions.size());
  for (const Vec3& v : view_directions) m.view_directions.push_back(T.linear() * v);
  return m;
}

FitnessScore Matcher::fitness(const RefineContext& context, StageState* state, const Isometry3& T,
                              double max_range_m) const {
  (void)state;
  return fitness_score(*context.source.positions, context.target->tree(), T, max_range_m);
}

}  // namespace lmalign
