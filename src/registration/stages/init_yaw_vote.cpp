// Initialiser "yaw_vote" (the adaptive default's; stages/yaw_vote_search.hpp): without a prior,
// every yaw on a grid about the target's up axis after turning the source's up axis onto it,
// each with its translation by a vote over horizontal cells; the local maxima over yaw are the
// hypotheses, plus the initial guess if given. Each map's landmark-plane normal joins its up-axis
// candidates when it disagrees with its frames' axis, and the search votes for every pair. With a
// prior: the same search within 3 sigma of the guess (and of the guess tilted to agree with the
// maps' up axes), or the guess alone when the prior is finer than the search. The vote cell, the
// search's resolution, is init.vote_cell_factor x max(target spacing, 2 sin(step / 2) x source
// radius).
#include <algorithm>
#include <cmath>

#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/stages/yaw_vote_search.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(init_yaw_vote)

namespace lmalign::stages {

namespace {

struct YawVoteInitOptions {
  YawVoteOptions search;
  double vote_cell_factor = 1.5;
  double start_sigma_factor = 0.3;
  double second_up_min_angle_deg = 10.0;
};

class YawVote : public Initialiser {
 public:
  explicit YawVote(YawVoteInitOptions o) : o_(o) {}
  bool needs_scales() const override { return true; }
  bool uses_prior() const override { return true; }

  std::vector<Hypothesis> propose(const InitialiserContext& c,
                                  InitialiserReport* report) const override {
    const Scales& sc = *c.scales;
    const Points3& source = *c.source.positions;
    const Points3& target = c.target->points();
    const Isometry3 guess = c.initial_guess.value_or(Isometry3::Identity());
    const bool has_prior = c.prior_sigma_deg_m.has_value();
    const double step_rad = o_.search.yaw_step_deg * kPi / 180.0;
    const double cell =
        o_.vote_cell_factor *
        std::max(sc.target.spacing_m, 2.0 * std::sin(0.5 * step_rad) * sc.source.radius_m);
    report->initialisation = has_prior ? "prior" : "global";
    report->resolution_m = cell;
    report->resolution_rad = step_rad;

    PoseWindow window;
    if (has_prior) {
      window = PoseWindow::of_prior(guess, c.prior_sigma_deg_m->first, c.prior_sigma_deg_m->second);
    }
    const double centre_sd_m = has_prior ? window.point_sd_m(sc.source.centre_m) : 0.0;
    const bool search_needed =
        !has_prior || window.rotation_sd_rad > 0.5 * step_rad || centre_sd_m > cell;
    std::vector<Hypothesis> out;
    Hypothesis searched;
    searched.start_sigma_m = o_.start_sigma_factor * 2.0 * cell;
    searched.start_sigma_rad = o_.start_sigma_factor * step_rad;
    searched.origin = "search";
    if (search_needed) {
      // Up-axis candidates of each map: its frames' (or the default), and its landmark plane's
      // normal when that disagrees by more than second_up_min_angle_deg. Without a prior the
      // search votes once per pair of candidates and keeps the best hypotheses of all of them.
      // With a prior the guess's rotation is the base (and, below, the guess tilted to agree
      // with the frames' up axes); the landmark-plane candidates do not enter.
      const double min_cos = std::cos(o_.second_up_min_angle_deg * kPi / 180.0);
      auto candidates = [&](const Vec3& up, const Points3& points) {
        std::vector<Vec3> ups{up};
        if (!has_prior) {
          const std::optional<Vec3> plane = landmark_plane_normal(points, up);
          if (plane && plane->dot(up) < min_cos) ups.push_back(*plane);
        }
        return ups;
      };
      report->ups_source = candidates(sc.up_source, source);
      report->ups_target = candidates(sc.up_target, target);
      std::vector<YawHypothesis> yh;
      for (const Vec3& us : report->ups_source) {
        for (const Vec3& ut : report->ups_target) {
          const std::vector<YawHypothesis> part = yaw_vote_hypotheses(
              source, target, us, ut, cell, o_.search, has_prior ? &window : nullptr);
          yh.insert(yh.end(), part.begin(), part.end());
        }
      }
      if (has_prior) {
        // A second base with a prior: the guess tilted (about the target origin, as the prior's
        // perturbation) so that the maps' up axes agree, when that takes more than half a yaw
        // step and stays within 3 sigma of the prior's rotation. The up axes measure the tilt
        // that a yaw search cannot correct.
        const Mat3 R_guess = guess.linear();
        const Mat3 tilt = rotation_between(R_guess * sc.up_source, sc.up_target);
        const double angle = Eigen::AngleAxisd(tilt).angle();
        if (angle > 0.5 * step_rad && angle <= 3.0 * window.rotation_sd_rad) {
          PoseWindow tilted = window;
          tilted.T_target_source_guess = Isometry3(tilt) * guess;  // about the target origin
          const std::vector<YawHypothesis> part = yaw_vote_hypotheses(
              source, target, sc.up_source, sc.up_target, cell, o_.search, &tilted);
          yh.insert(yh.end(), part.begin(), part.end());
        }
      }
      // Best first over all pairs of up axes (stable: ties keep the frames' axes first).
      std::stable_sort(yh.begin(), yh.end(), [](const YawHypothesis& a, const YawHypothesis& b) {
        return a.votes > b.votes;
      });
      if (yh.size() > o_.search.hypotheses) yh.resize(o_.search.hypotheses);
      for (const YawHypothesis& h : yh) {
        Hypothesis a = searched;
        a.T_target_source = h.T_target_source;
        a.search_score = static_cast<double>(h.votes);
        out.push_back(a);
      }
      if (!yh.empty()) report->best_search_score = static_cast<double>(yh[0].votes);
      if (yh.size() > 1) report->second_search_score = static_cast<double>(yh[1].votes);
    } else {
      report->initialisation = "given";
    }
    if (c.initial_guess.has_value() || !search_needed || out.empty()) {
      Hypothesis g = searched;
      g.T_target_source = guess;
      g.origin = "guess";
      if (has_prior) {
        // The gate's pose sigma is about the source centre's image (its pivot).
        g.start_sigma_m = o_.start_sigma_factor * centre_sd_m;
        g.start_sigma_rad = o_.start_sigma_factor * window.rotation_sd_rad;
      }
      out.push_back(g);
    }
    return out;
  }

 private:
  YawVoteInitOptions o_;
};

const SettingsBinding<YawVoteInitOptions>& binding() {
  static const SettingsBinding<YawVoteInitOptions> b =
      SettingsBinding<YawVoteInitOptions>("YawVoteInitOptions")
          .add("init.yaw_step_deg", LMALIGN_FIELD(search.yaw_step_deg),
               SettingBound::open_closed(0.0, 90.0), "deg", "spacing of the yaw grid")
          .add("init.source_samples", LMALIGN_FIELD(search.source_samples),
               SettingBound::closed(3, 1000000), "count",
               "source landmarks that vote (evenly strided)")
          .add("init.target_samples", LMALIGN_FIELD(search.target_samples),
               SettingBound::closed(3, 1000000), "count",
               "target landmarks that vote (evenly strided)")
          .add("init.hypotheses", LMALIGN_FIELD(search.hypotheses), SettingBound::closed(1, 100000),
               "count", "hypotheses kept at most (local maxima of the votes over yaw)")
          .add("init.vote_cell_factor", LMALIGN_FIELD(vote_cell_factor), SettingBound::above(0.0),
               "1",
               "the vote cell is this times max(target spacing, 2 sin(step / 2) x source radius)")
          .add("init.start_sigma_factor", LMALIGN_FIELD(start_sigma_factor),
               SettingBound::open_closed(0.0, 10.0), "1",
               "a hypothesis' gate starts at this fraction of the search's resolution (two cells, "
               "one yaw step) or of the prior's sigmas")
          .add("init.second_up_min_angle_deg", LMALIGN_FIELD(second_up_min_angle_deg),
               SettingBound::closed(0.0, 180.0), "deg",
               "a map's landmark-plane normal becomes a second up-axis candidate when this far "
               "from its frames' up axis (180: never)");
  return b;
}

}  // namespace
}  // namespace lmalign::stages

LMALIGN_BOUND_STAGE(init_yaw_vote, YawVote)
