// Initialiser "global_vote": global_align() (global_init.hpp): yaw hypotheses about a fixed up
// axis, the translation of each by a 3-D vote, each refined by the paper's ICP on a distance
// schedule, the one with the most inliers kept. The initial guess is ignored (fewer than 3
// landmarks a side: the guess).
#include "lmalign/registration/global_init.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(init_global_vote)

namespace lmalign::stages {

namespace {

class GlobalVote : public Initialiser {
 public:
  explicit GlobalVote(GlobalInitOptions o) : o_(std::move(o)) {}
  std::vector<Hypothesis> propose(const InitialiserContext& c,
                                  InitialiserReport* report) const override {
    report->initialisation = "global_vote";
    Hypothesis h;
    h.origin = "search";
    h.T_target_source = c.initial_guess.value_or(Isometry3::Identity());
    if (c.source.size() >= 3 && c.target->size() >= 3) {
      const GlobalInitResult r = global_align(*c.source.positions, *c.target, o_);
      h.T_target_source = r.T_target_source;
      h.search_score = r.inlier_fraction;
      report->best_search_score = r.inlier_fraction;
    }
    return {h};
  }

 private:
  GlobalInitOptions o_;
};

}  // namespace

std::vector<SettingRow> init_global_vote_settings() {
  const GlobalInitOptions d;
  SettingBound three;
  three.min_size = three.max_size = 3;
  SettingBound levels = SettingBound::above(0.0);
  levels.min_size = 1;
  return {
      reals_setting("init.up", "GlobalInitOptions::up", {d.up.x(), d.up.y(), d.up.z()}, three, "1",
                    "the up axis, the same in both maps"),
      real_setting("init.yaw_step_deg", "GlobalInitOptions::yaw_step_deg", d.yaw_step_deg,
                   SettingBound::open_closed(0.0, 90.0), "deg", "spacing of the yaw hypotheses"),
      real_setting("init.vote_cell_m", "GlobalInitOptions::vote_cell_m", d.vote_cell_m,
                   SettingBound::above(0.0), "m", "edge of a translation vote cell"),
      int_setting("init.max_vote_cells", "GlobalInitOptions::max_vote_cells",
                  static_cast<long long>(d.max_vote_cells), SettingBound::at_least(27), "count",
                  "a vote grid larger than this grows its cells until it fits"),
      int_setting("init.source_samples", "GlobalInitOptions::vote_source_samples",
                  static_cast<long long>(d.vote_source_samples), SettingBound::at_least(3), "count",
                  "source landmarks that vote (strided)"),
      int_setting("init.target_samples", "GlobalInitOptions::vote_target_samples",
                  static_cast<long long>(d.vote_target_samples), SettingBound::at_least(3), "count",
                  "target landmarks that vote (strided)"),
      int_setting("init.hypotheses", "GlobalInitOptions::hypotheses",
                  static_cast<long long>(d.hypotheses), SettingBound::at_least(1), "count",
                  "yaw hypotheses refined by ICP"),
      reals_setting("init.refine_levels_m", "GlobalInitOptions::refine_schedule_m",
                    d.refine_schedule_m, levels, "m", "maximum distances of the ICP stages"),
      int_setting("init.refine_iterations", "GlobalInitOptions::refine_iterations",
                  d.refine_iterations, SettingBound::closed(1, 2147483647), "count",
                  "iterations of each ICP stage"),
      real_setting("init.inlier_distance_m", "GlobalInitOptions::inlier_distance_m",
                   d.inlier_distance_m, SettingBound::above(0.0), "m",
                   "a source landmark this close to a target landmark is an inlier"),
  };
}

std::unique_ptr<Stage> make_init_global_vote(const Settings& s) {
  GlobalInitOptions o;
  const std::vector<double>& up = s.reals("init.up");
  o.up = Vec3(up[0], up[1], up[2]);
  o.yaw_step_deg = s.real("init.yaw_step_deg");
  o.vote_cell_m = s.real("init.vote_cell_m");
  o.max_vote_cells = static_cast<std::size_t>(s.integer("init.max_vote_cells"));
  o.vote_source_samples = static_cast<std::size_t>(s.integer("init.source_samples"));
  o.vote_target_samples = static_cast<std::size_t>(s.integer("init.target_samples"));
  o.hypotheses = static_cast<std::size_t>(s.integer("init.hypotheses"));
  o.refine_schedule_m = s.reals("init.refine_levels_m");
  o.refine_iterations = static_cast<int>(s.integer("init.refine_iterations"));
  o.inlier_distance_m = s.real("init.inlier_distance_m");
  std::string why;
  if (!o.is_valid(&why)) throw InvalidArgument("init: " + why);
  return std::make_unique<GlobalVote>(o);
}

}  // namespace lmalign::stages
