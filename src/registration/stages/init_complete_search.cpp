// Initialiser "complete_search" (the adaptive default's; stages/complete_search.hpp): without a
// prior, first the correspondence search's poses alone (search.first_pass; its descriptor radius
// at search.first_pass_neighbours), snapped and refined in the complete search's rounds without
// its vote; Pipeline::run asks for the deep pass when that answer is not trusted (or at once when
// the first pass finds no pose): the complete search over every pair of up-axis candidates,
// every yaw and every translation, with the correspondence poses in its pool, its candidates
// refined with the pipeline's own refinement in rounds. When the first pass's answer was trusted
// and the deeper pass only checks it for rivals (InitialiserContext::checking; with a prior, an
// answer the maps' own first pass confirmed and trusted without the prior's waiver of the alias
// test), search.check "correspondences" makes that pass a second correspondence search, at the
// finer search.descriptor_neighbours, its poses snapped and refined beside the answer without the
// vote (the vote runs when it finds none); "complete", the complete search. The distinct modes are
// the hypotheses, plus the initial guess if given. Each map's up-axis candidates are its frames'
// axis, its landmark plane's normal when that disagrees by more than init.second_up_min_angle_deg,
// and its dominant plane's normal (a floor, a desk, a road) when that disagrees with both by more
// than a degree. With a prior it is the "yaw_vote" initialiser (the vote bounded by the prior),
// and, with init.prior_check "rivals" or "strict", the complete search too: its modes join the
// prior's hypotheses, so that a pose the maps prefer outside the prior's window wins ("rivals") or
// is the trust judge's rival ("strict") (issue 41; docs/accuracy.md, "Priors are hints"); when none
// of the first pass's poses lies inside the prior's window, the prior's own search proposes beside
// them, and the complete search runs unless the maps put the answer outside the window
// (InitialiserReport::prior_unconfirmed). The vote cell, the search's coarse resolution, is
// init.vote_cell_factor x max(target spacing, 2 sin(step / 2) x source radius); the modes are
// refined from a third of it.
#include <algorithm>
#include <cmath>
#include <utility>

#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/stages/complete_search.hpp"
#include "lmalign/registration/stages/correspondence_search.hpp"
#include "lmalign/registration/stages/yaw_vote_search.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(init_complete_search)
LMALIGN_STAGE_FUNCTIONS(init_yaw_vote)

namespace lmalign::stages {

namespace {

struct CompleteInitOptions {
  CompleteSearchOptions search;
  /// The correspondence search whose poses join the complete search's pool (issue 39);
  /// hypotheses = 0: none.
  CorrespondenceSearchOptions correspondences;
  /// The first pass: the correspondence search's poses alone, with the descriptor radius at
  /// first_pass_neighbours, snapped and refined without the vote (with a prior, beside the
  /// prior's own search when none lies inside its window); the complete search runs only when
  /// that answer is not trusted, or when it is trusted inside a prior's window that no first-pass
  /// pose confirmed, and not when the maps put it outside a prior's window (Pipeline::run).
  bool first_pass = true;
  std::size_t first_pass_neighbours = 48;
  /// The first pass's correspondence poses at most (the complete search's: search.
  /// correspondence_poses). More than the complete search's: the first pass has no vote beside
  /// them, and with a free scale it runs at a scale up to half a rung off (docs/scale.md).
  std::size_t first_pass_poses = 128;
  std::size_t hypotheses = 6;
  double vote_cell_factor = 1.5;
  double start_sigma_factor = 0.3;
  double second_up_min_angle_deg = 10.0;
  /// With a prior (issue 41: a prior is a hint, checked against the maps): "rivals", the global
  /// search runs too and its modes compete with the prior's hypotheses; "strict", they are the
  /// verdict's rivals but never the answer; "off", the prior's search alone.
  std::string prior_check = "rivals";
  /// With a prior checked by the global search: "rescue", the maps' own search runs first and
  /// its complete search whenever it can change the verdict (the first pass finds no pose, or
  /// its answer is not trusted and lies inside the window, or is trusted inside a window no
  /// first-pass pose confirmed); "check", the prior's own search first, then the maps' first
  /// pass (the correspondence poses: it checks a trusted answer and rescues an untrusted one
  /// that some landmarks support, a prior being a hint, never a wall), and their complete search
  /// only to check a trusted answer that no first-pass pose confirms, never to rescue an
  /// untrusted one (a fleet's prior edges, merge/candidates.hpp: most candidate pairs of a fleet
  /// do not overlap, and the complete search is the dear part).
  std::string prior_complete_search = "rescue";
  /// Without a prior: "rescue", the complete search runs whenever the first pass does not settle
  /// the answer (it finds no pose, or its answer is not trusted); "check", only to check a
  /// trusted first-pass answer that needs every rival, never to rescue one: a first pass that
  /// finds no correspondence pose gives no answer (not trusted, "no correspondence pose"), an
  /// untrusted one stays the answer. For a fleet's candidate pairs, most of which do not
  /// overlap (a merge of more than 12 maps, merge/candidates.hpp): on four simulated fleets of
  /// 50-200 maps the complete search took 77-93% of the edges' time and made 0-3 edges trusted
  /// and right (and up to 5 trusted and wrong) of the 32-654 pairs it ran on.
  std::string complete_search = "rescue";
  /// The deeper pass that checks a trusted first-pass answer for rivals
  /// (InitialiserContext::checking: with a prior, only an answer the maps' own poses confirmed,
  /// trusted without the prior's waiver of the alias test): "correspondences", a second
  /// correspondence search at the finer descriptor radius (correspondences.neighbours) whose poses
  /// are snapped and refined beside the answer, without the vote (the vote runs when it finds no
  /// pose); "complete", the complete search. Measured (docs/accuracy.md, "The check by
  /// correspondences"): the same answers and no verdict lost on the streets, roads, the accuracy
  /// benchmark, the prior sweep and the merges, at a third to a quarter of the check's time. An
  /// answer trusted on a prior's waiver is always checked completely: on real desk windows that
  /// share no frame, the correspondence search kept a first-pass answer 6.8 deg off that the vote
  /// improves to 3.6.
  std::string check = "correspondences";
  /// The gate the search's votes are scored with: the matcher's (match.*).
  MahalanobisGateOptions gate;
};

class CompleteSearchInit : public Initialiser {
 public:
  CompleteSearchInit(CompleteInitOptions o, std::unique_ptr<Stage> bounded)
      : o_(o), bounded_(static_cast<Initialiser*>(bounded.release())) {}
  bool needs_scales() const override { return true; }
  bool uses_prior() const override { return true; }

  std::vector<Hypothesis> propose(const InitialiserContext& c,
                                  InitialiserReport* report) const override {
    if (c.pipeline == nullptr || c.refine_context == nullptr) return bounded_->propose(c, report);
    const bool check_by_correspondences =
        c.checking && o_.check == "correspondences" && !c.free_scale;
    if (!c.prior_sigma_deg_m.has_value()) {
      const bool rescue = o_.complete_search == "rescue";
      std::vector<Hypothesis> out = global(c, report, rescue, check_by_correspondences);
      if (out.empty()) {
        report->declined =
            "no correspondence pose: the first pass found no consistent set of matches, and "
            "search.complete_search = check does not search further";
      }
      report->deeper_if_untrusted = rescue;
      return out;
    }
    if (o_.prior_check == "off") return bounded_->propose(c, report);
    // "check": the prior's own search first; the maps' first pass runs next (to check a trusted
    // answer, or to rescue an untrusted one that some landmarks support: the prior's window may
    // hold the truth that its own search missed); their complete search only to check a trusted
    // answer.
    const bool rescue = o_.prior_complete_search == "rescue";
    if (!rescue && c.pass == 0) {
      std::vector<Hypothesis> out = bounded_->propose(c, report);
      report->notes.emplace_back("prior hypotheses", static_cast<double>(out.size()));
      report->deeper_pass = true;
      report->prior_unconfirmed = true;
      report->deeper_if_untrusted = true;
      report->deeper_needs_evidence = true;
      return out;
    }
    // The global search first (as without a prior); its modes are the hypotheses, and the trust
    // judge's rival test sees what the maps prefer outside the prior's window. When one of them
    // lies inside the window, it is the prior's hypothesis: the prior's own search would find
    // that basin again, and is skipped (a prior then costs what no prior costs). Otherwise the
    // prior's search proposes its hypotheses first. With "strict" the modes outside the window
    // are only the verdict's rivals, never the answer. The report keeps the initialisation
    // "prior", with the coarser of the searches' resolutions (it measures which poses are
    // distinct).
    InitialiserContext open = c;
    open.prior_sigma_deg_m.reset();
    open.initial_guess.reset();
    const PoseWindow window =
        PoseWindow::of_prior(c.initial_guess.value_or(Isometry3::Identity()),
                             c.prior_sigma_deg_m->first, c.prior_sigma_deg_m->second);
    const Vec3 centre = c.scales != nullptr ? c.scales->source.centre_m : Vec3::Zero();
    // (With "check" the maps' first pass is pass 1, their complete search pass 2.)
    open.pass = rescue ? c.pass : c.pass - 1;
    InitialiserReport global_report;
    std::vector<Hypothesis> modes = global(open, &global_report, rescue, check_by_correspondences);
    std::vector<Hypothesis> inside, outside;
    auto split = [&] {
      inside.clear();
      outside.clear();
      for (Hypothesis& h : modes) {
        if (h.origin != "search") continue;
        if (window
                .check(h.T_target_source, centre, global_report.resolution_m,
                       global_report.resolution_rad)
                .inside()) {
          h.origin = "global, inside the prior's window";
          inside.push_back(h);
        } else {
          h.origin = "global check";
          h.rival_only = o_.prior_check == "strict";
          outside.push_back(h);
        }
      }
    };
    split();
    // A first pass none of whose poses lies inside the prior's window: the prior's own search
    // proposes, the first pass's modes are the rivals, and Pipeline::run runs the complete search
    // unless the maps put the answer outside the window (InitialiserReport::prior_unconfirmed).
    const bool unconfirmed = global_report.deeper_pass && inside.empty();
    std::vector<Hypothesis> out;
    if (inside.empty()) {
      out = bounded_->propose(c, report);
      report->notes.emplace_back("prior search resolution (m)", report->resolution_m);
      report->notes.emplace_back("prior hypotheses", static_cast<double>(out.size()));
    } else {
      *report = global_report;
      report->initialisation = "prior";
      out = inside;
      report->notes.emplace_back("global modes inside the prior's window",
                                 static_cast<double>(inside.size()));
    }
    out.insert(out.end(), outside.begin(), outside.end());
    report->notes.emplace_back("global check modes", static_cast<double>(outside.size()));
    report->resolution_m = std::max(report->resolution_m, global_report.resolution_m);
    report->resolution_rad = std::max(report->resolution_rad, global_report.resolution_rad);
    report->prior_checked = true;
    report->deeper_pass = global_report.deeper_pass;
    report->prior_unconfirmed = unconfirmed;
    report->deeper_if_untrusted = rescue;
    return out;
  }

  std::optional<ScaleMeasurement> measure_scale(const InitialiserContext& c, int steps,
                                                double ratio, double margin) const override {
    // The correspondence search on a ladder of scales (correspondence_search.hpp, step 5): the
    // scale of its largest clique (the first of the largest: deterministic), if decisive.
    if (steps <= 0 || o_.correspondences.hypotheses == 0 || c.scales == nullptr) {
      return std::nullopt;
    }
    const Scales& sc = *c.scales;
    const CorrespondenceSearchInput ci{
        search_maps(c, up_candidates(sc.up_source, *c.source.positions, sc.source.spacing_m),
                    up_candidates(sc.up_target, c.target->points(), sc.target.spacing_m))};
    CorrespondenceSearchOptions co = o_.correspondences;
    co.scale_steps = steps;
    co.scale_ratio = ratio;
    co.seeds = std::min<std::size_t>(co.seeds, 16);  // only the largest clique counts here
    // The margin below was measured on 16 poses: more admit more cliques at other scales (the
    // real desk's Sim(3) split was no longer decisive with 64).
    co.hypotheses = std::min<std::size_t>(co.hypotheses, 16);
    const CorrespondenceSearchResult cr = correspondence_search(ci, co);
    const CorrespondenceHypothesis* best = nullptr;
    for (const CorrespondenceHypothesis& h : cr.hypotheses) {
      if (best == nullptr || h.inliers > best->inliers) best = &h;
    }
    if (best == nullptr) return std::nullopt;
    ScaleMeasurement m;
    m.factor = best->scale;
    for (const CorrespondenceHypothesis& h : cr.hypotheses)
      m.cliques.emplace_back(h.scale, h.inliers);
    // Decisive only: at least `margin` times the matches of the largest clique at a scale more
    // than a rung away (on a street's repeated structure the largest cliques are often at
    // wrong scales and poses, and nearly as large as each other).
    std::size_t other = 0;
    for (const CorrespondenceHypothesis& h : cr.hypotheses) {
      if (std::abs(std::log(h.scale / best->scale)) > std::log(ratio)) {
        other = std::max(other, h.inliers);
      }
    }
    if (static_cast<double>(best->inliers) < margin * static_cast<double>(other)) {
      m.decisive = false;
      return m;
    }
    // The poses at the measured scale (within half a rung of it), best first: the first pass's
    // at that scale.
    m.poses.push_back(best->T_target_source);
    for (const CorrespondenceHypothesis& h : cr.hypotheses) {
      if (&h != best && std::abs(std::log(h.scale / best->scale)) <= 0.5 * std::log(ratio)) {
        m.poses.push_back(h.T_target_source);
      }
    }
    return m;
  }

 private:
  // The searches' maps: the context's, these up axes, the scales' floor.
  static SearchMaps search_maps(const InitialiserContext& c, std::vector<Vec3> ups_source,
                                std::vector<Vec3> ups_target) {
    SearchMaps m;
    m.source.points = c.source.positions;
    m.source.covariances_m2 = c.source.covariances_m2;
    m.source.view_directions = c.source.view_directions;
    m.target = c.target;
    m.ups_source = std::move(ups_source);
    m.ups_target = std::move(ups_target);
    m.floor_m = c.scales->floor_m;
    return m;
  }

  // A map's up-axis candidates: its frames' axis, its landmark plane's normal when that
  // disagrees by more than init.second_up_min_angle_deg, its dominant plane's normal when that
  // disagrees with both by more than a degree.
  std::vector<Vec3> up_candidates(const Vec3& up, const Points3& points, double spacing_m) const {
    const double min_cos = std::cos(o_.second_up_min_angle_deg * kPi / 180.0);
    std::vector<Vec3> ups{up};
    const std::optional<Vec3> plane = landmark_plane_normal(points, up);
    if (plane && plane->dot(up) < min_cos) ups.push_back(*plane);
    const std::optional<Vec3> floor = dominant_plane_normal(points, up, spacing_m);
    if (floor) {
      bool fresh = true;
      for (const Vec3& u : ups) fresh = fresh && floor->dot(u) < std::cos(kPi / 180.0);
      if (fresh) ups.push_back(*floor);
    }
    return ups;
  }

  // The global search. A first pass that finds no pose runs the complete search at once, unless
  // !vote_at_once: then no mode, and the complete search stays the deeper pass. A later pass
  // with `check_by_correspondences` is the correspondence search alone (search.check), unless it
  // finds no pose.
  std::vector<Hypothesis> global(const InitialiserContext& c, InitialiserReport* report,
                                 bool vote_at_once = true,
                                 bool check_by_correspondences = false) const {
    const Scales& sc = *c.scales;
    const Points3& source = *c.source.positions;
    const Points3& target = c.target->points();
    const double step_rad = o_.search.yaw_step_deg * kPi / 180.0;
    const double cell =
        o_.vote_cell_factor *
        std::max(sc.target.spacing_m, 2.0 * std::sin(0.5 * step_rad) * sc.source.radius_m);
    report->initialisation = "global";
    report->resolution_m = cell;
    report->resolution_rad = step_rad;

    report->ups_source = up_candidates(sc.up_source, source, sc.source.spacing_m);
    report->ups_target = up_candidates(sc.up_target, target, sc.target.spacing_m);

    CompleteSearchInput in;
    static_cast<SearchMaps&>(in) = search_maps(c, report->ups_source, report->ups_target);
    in.source_centre_m = sc.source.centre_m;
    in.source_radius_m = sc.source.radius_m;
    in.cell_m = cell;
    in.gate = o_.gate;
    in.evidence = sc.evidence();
    in.coarse_sigma.translation_m = o_.start_sigma_factor * 2.0 * cell;
    in.coarse_sigma.rotation_rad = o_.start_sigma_factor * step_rad;
    CompleteSearchOptions so = o_.search;
    so.modes = o_.hypotheses;
    if (o_.correspondences.hypotheses > 0 && o_.first_pass && c.pass == 0 &&
        !c.measured_poses.empty()) {
      // The first pass of a free scale: the poses the scale's measurement found at the measured
      // scale, without searching again.
      in.extra_candidates = c.measured_poses;
      report->notes.emplace_back("first pass poses from the scale's measurement",
                                 static_cast<double>(in.extra_candidates.size()));
      so.vote = false;
      report->deeper_pass = true;
    } else if (o_.correspondences.hypotheses > 0 && o_.first_pass && c.pass == 0) {
      // The first pass: the correspondence poses alone, at the first pass's descriptor radius.
      // None found: the complete search at once.
      CorrespondenceSearchOptions first = o_.correspondences;
      first.neighbours = o_.first_pass_neighbours;
      first.hypotheses = o_.first_pass_poses;
      const CorrespondenceSearchResult cr =
          correspondence_search(CorrespondenceSearchInput{SearchMaps(in)}, first);
      for (const CorrespondenceHypothesis& h : cr.hypotheses) {
        in.extra_candidates.push_back(h.T_target_source);
      }
      report->notes.emplace_back("first pass correspondence matches",
                                 static_cast<double>(cr.matches));
      report->notes.emplace_back("first pass correspondence poses",
                                 static_cast<double>(cr.hypotheses.size()));
      so.vote = in.extra_candidates.empty();
      report->deeper_pass = !so.vote;
      if (so.vote && !vote_at_once) {
        report->deeper_pass = true;
        return {};
      }
      if (so.vote) in.extra_candidates.clear();
    }
    if (o_.correspondences.hypotheses > 0 && so.vote) {
      const CorrespondenceSearchResult cr =
          correspondence_search(CorrespondenceSearchInput{SearchMaps(in)}, o_.correspondences);
      // (Rigid here: with a free scale the pipeline measured the scale before this search.)
      for (const CorrespondenceHypothesis& h : cr.hypotheses) {
        in.extra_candidates.push_back(h.T_target_source);
      }
      report->notes.emplace_back("correspondence matches", static_cast<double>(cr.matches));
      report->notes.emplace_back("correspondence poses", static_cast<double>(cr.hypotheses.size()));
      // A check by correspondences: their poses alone, when there are any (search.check).
      if (check_by_correspondences && c.pass > 0 && !in.extra_candidates.empty()) {
        so.vote = false;
        report->notes.emplace_back("check by correspondences", 1.0);
      }
    }
    const Pipeline& pipeline = *c.pipeline;
    const RefineContext& all = *c.refine_context;
    const SearchRefineFn refine = [&](const Isometry3& start, const PoseSigma& sigma,
                                      const std::vector<std::uint32_t>& subset,
                                      int max_iterations) {
      Hypothesis h;
      h.T_target_source = start;
      h.start_sigma_m = sigma.translation_m;
      h.start_sigma_rad = sigma.rotation_rad;
      h.max_iterations = max_iterations;
      h.max_iterations_per_level = 5;
      return pipeline.refine_part(all, subset, h, Phase::kHypothesis).T;
    };
    const CompleteSearchResult found = complete_search(in, so, refine);

    std::vector<Hypothesis> out;
    for (const SearchMode& m : found.modes) {
      Hypothesis h;
      h.T_target_source = m.T_target_source;
      h.start_sigma_m = found.fine_sigma.translation_m;
      h.start_sigma_rad = found.fine_sigma.rotation_rad;
      h.search_score = m.score;
      h.origin = "search";
      out.push_back(h);
    }
    if (!found.modes.empty()) report->best_search_score = found.modes[0].score;
    if (found.modes.size() > 1) report->second_search_score = found.modes[1].score;
    report->notes.emplace_back("search candidates", static_cast<double>(found.candidates));
    report->notes.emplace_back("search pool", static_cast<double>(found.pooled));
    report->notes.emplace_back("search fine cell (m)", found.fine_cell_m);
    if (c.initial_guess.has_value() || out.empty()) {
      Hypothesis g;
      g.T_target_source = c.initial_guess.value_or(Isometry3::Identity());
      g.start_sigma_m = in.coarse_sigma.translation_m;
      g.start_sigma_rad = in.coarse_sigma.rotation_rad;
      g.origin = "guess";
      out.push_back(g);
    }
    return out;
  }

  CompleteInitOptions o_;
  std::unique_ptr<Initialiser> bounded_;
};

const SettingsBinding<CompleteInitOptions>& binding() {
  static const SettingsBinding<CompleteInitOptions> b =
      SettingsBinding<CompleteInitOptions>("CompleteInitOptions")
          .choice("init.prior_check", LMALIGN_FIELD(prior_check), {"rivals", "strict", "off"},
                  "with a prior: rivals = the global search runs too and its modes compete with "
                  "the prior's hypotheses; strict = they are the verdict's rivals, never the "
                  "answer; off = the prior's search alone (an answer outside the prior's window is "
                  "not trusted either way)")
          .choice("init.prior_complete_search", LMALIGN_FIELD(prior_complete_search),
                  {"rescue", "check"},
                  "with a prior checked by the global search: rescue = the maps' own search runs "
                  "first, its complete search whenever it can change the verdict (the first pass "
                  "finds no pose, or its answer is not trusted, or is trusted inside the prior's "
                  "window that no first-pass pose confirmed); check = the prior's own search "
                  "first, then the maps' first pass (it checks a trusted answer and rescues an "
                  "untrusted one that at least trust.min_inliers landmarks support), their "
                  "complete search only to check a trusted answer that no first-pass pose "
                  "confirms (the prior edges of a merge of more than 12 maps)")
          .choice("search.check", LMALIGN_FIELD(check), {"correspondences", "complete"},
                  "the deeper pass that checks a trusted first-pass answer for rivals (its "
                  "residuals exceed their covariances, or a rival is within "
                  "trust.alias_ambiguity): correspondences = a second correspondence search at "
                  "search.descriptor_neighbours, its poses snapped and refined beside the answer, "
                  "without the vote (the vote runs when it finds no pose); complete = the complete "
                  "search (the vote over every yaw and pair of up axes, and its pool). With a "
                  "prior, an answer no first-pass pose confirmed, or trusted only because the "
                  "prior told an alias apart, is always checked completely; so is any answer "
                  "with a free scale")
          .choice("search.complete_search", LMALIGN_FIELD(complete_search), {"rescue", "check"},
                  "without a prior: rescue = the complete search runs whenever the first pass "
                  "does not settle the answer (no pose, or an answer not trusted); check = only "
                  "to check a trusted first-pass answer, never to rescue one (no pose: no answer, "
                  "not trusted; the pairs without priors of a merge of more than 12 maps)")
          .add("search.vote_source_samples", LMALIGN_FIELD(search.vote_source_samples),
               SettingBound::closed(3, 1000000), "count",
               "source landmarks that cast the coarse 3-D vote (evenly strided)")
          .add("search.vote_target_samples", LMALIGN_FIELD(search.vote_target_samples),
               SettingBound::closed(3, 1000000), "count",
               "target landmarks the coarse vote is cast towards (evenly strided)")
          .add("search.peaks_per_yaw", LMALIGN_FIELD(search.peaks_per_yaw),
               SettingBound::closed(1, 64), "count",
               "translation peaks kept per yaw and pair of up axes (3 cells apart)")
          .add("search.pool", LMALIGN_FIELD(search.pool), SettingBound::closed(1, 1000000), "count",
               "candidates snapped to a finer vote (from the rankings by votes and by the coarse "
               "score, in turn)")
          .add("search.screen_samples", LMALIGN_FIELD(search.screen_samples),
               SettingBound::closed(16, 1000000), "count",
               "source landmarks of the coarse score that ranks the candidates")
          .add("search.snap_samples", LMALIGN_FIELD(search.snap_samples),
               SettingBound::closed(16, 1000000), "count",
               "source landmarks of the finer vote about each pooled candidate")
          .add("search.snap_neighbours", LMALIGN_FIELD(search.snap_neighbours),
               SettingBound::closed(1, 256), "count",
               "nearest target landmarks each of them votes towards")
          .add("search.rank_samples", LMALIGN_FIELD(search.rank_samples),
               SettingBound::closed(16, 1000000), "count",
               "source landmarks of the fine score that ranks the snapped candidates")
          .add("search.rank_keep", LMALIGN_FIELD(search.rank_keep),
               SettingBound::closed(1, 1000000), "count",
               "snapped candidates refined in the first round")
          .add("search.round1_iterations", LMALIGN_FIELD(search.round1_iterations),
               SettingBound::closed(1, 100000), "count",
               "iterations of the first round's refinements")
          .add("search.round1_samples", LMALIGN_FIELD(search.round1_samples),
               SettingBound::closed(16, 1000000), "count", "source landmarks of the first round")
          .add("search.round1_keep", LMALIGN_FIELD(search.round1_keep),
               SettingBound::closed(1, 1000000), "count", "candidates refined in the second round")
          .add("search.round2_iterations", LMALIGN_FIELD(search.round2_iterations),
               SettingBound::closed(1, 100000), "count",
               "iterations of the second round's refinements")
          .add("search.round2_samples", LMALIGN_FIELD(search.round2_samples),
               SettingBound::closed(16, 1000000), "count", "source landmarks of the second round")
          .add("search.correspondence_poses", LMALIGN_FIELD(correspondences.hypotheses),
               SettingBound::closed(0, 4096), "count",
               "poses of the correspondence search (descriptors, a consistency graph, cliques); "
               "0 = none; it grows 4 cliques per pose")
          .add("search.correspondence_keep", LMALIGN_FIELD(search.extra_keep),
               SettingBound::closed(1, 4096), "count",
               "correspondence poses refined: when there are more, that many from their order by "
               "clique size and by the sharp gated score on search.rank_samples landmarks, in "
               "turn")
          .add("search.correspondence_refits", LMALIGN_FIELD(correspondences.refits),
               SettingBound::closed(0, 16), "count",
               "each rigid clique's pose re-estimated from every match it carries within "
               "search.consistency_sigmas standard deviations, until those matches repeat, at most "
               "this many times (LO-RANSAC's local optimisation); 0 = the clique's own pose")
          .flag("search.first_pass", LMALIGN_FIELD(first_pass),
                "the correspondence poses alone are refined and judged first (with a prior, beside "
                "the prior's own search when none lies inside its window); the complete search "
                "(the vote and its pool, with the correspondence poses) runs when that answer is "
                "not trusted, or is trusted inside a prior's window no correspondence pose "
                "confirmed; not when the maps put it outside a prior's window")
          .add("search.first_pass_neighbours", LMALIGN_FIELD(first_pass_neighbours),
               SettingBound::closed(4, 256), "count",
               "the first pass's descriptor radius is the target's median distance to this "
               "neighbour")
          .add("search.first_pass_poses", LMALIGN_FIELD(first_pass_poses),
               SettingBound::closed(1, 4096), "count",
               "the first pass's correspondence poses at most (it grows 4 cliques per pose); "
               "search.correspondence_poses = 0 turns the correspondence search off in both "
               "passes")
          .add("search.correspondence_keypoints", LMALIGN_FIELD(correspondences.keypoints),
               SettingBound::closed(3, 1000000), "count",
               "source landmarks the correspondence search describes and matches")
          .add("search.descriptor_neighbours", LMALIGN_FIELD(correspondences.neighbours),
               SettingBound::closed(4, 256), "count",
               "the descriptor radius is the target's median distance to this neighbour")
          .flag("search.oriented_descriptors", LMALIGN_FIELD(correspondences.oriented),
                "where both maps know their landmarks' viewing directions, describe each "
                "landmark's neighbourhood about the up axis and its horizontal viewing direction "
                "(else, or false: about the up axis alone)")
          .add("search.consistency_sigmas", LMALIGN_FIELD(correspondences.consistency_sigmas),
               SettingBound::open_closed(0.0, 100.0), "1",
               "two matches agree when their distances agree within this many standard deviations "
               "of the four landmarks");
  return b;
}

}  // namespace

std::vector<SettingRow> init_complete_search_settings() {
  // The prior-bounded vote's settings (init.*), then the complete search's own (search.*).
  std::vector<SettingRow> rows = init_yaw_vote_settings();
  rows.insert(rows.end(), binding().rows().begin(), binding().rows().end());
  return rows;
}

std::unique_ptr<Stage> make_init_complete_search(const Settings& s) {
  CompleteInitOptions o = binding().read(s);
  // The prior-bounded vote's settings and the gate's, whose rows are their own stages'.
  o.search.yaw_step_deg = s.real("init.yaw_step_deg");
  o.hypotheses = static_cast<std::size_t>(s.integer("init.hypotheses"));
  o.vote_cell_factor = s.real("init.vote_cell_factor");
  o.start_sigma_factor = s.real("init.start_sigma_factor");
  o.second_up_min_angle_deg = s.real("init.second_up_min_angle_deg");
  o.gate.k = static_cast<int>(s.integer("match.k"));
  o.gate.chi2_threshold = s.real("match.chi2_threshold");
  o.gate.max_view_angle_deg = s.real("match.max_view_angle_deg");
  o.correspondences.seeds = std::max<std::size_t>(1, 4 * o.correspondences.hypotheses);
  return std::make_unique<CompleteSearchInit>(o, make_init_yaw_vote(s));
}

}  // namespace lmalign::stages
