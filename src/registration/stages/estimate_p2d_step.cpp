// Estimator "p2d_step": one Gauss-Newton step of the point-to-distribution cost on the gated
// pairs per iteration, about the source centre's image (stages/p2d_step.hpp; 6 DoF, 4 about the
// target's up axis, or 7 with the scale when the loop frees it). Its covariance: the last step's
// normal equations (p2d_covariance), for 6 and 7 DoF the cluster-robust sandwich over spatial
// blocks (p2d_cluster_covariance); resampled_covariance raises it to the half-sample covariance
// (balanced repeated replication over spatial halves of the overlap, each re-aligned alone, its
// scale free when the run's is; docs/accuracy.md, "Uncertainty of the adaptive default"), which
// the pipeline asks for only where it matters (PipelineRun::resample_covariance).
#include <optional>

#include <Eigen/Eigenvalues>

#include "lmalign/core/first_exception.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/stages/mahalanobis_gate.hpp"
#include "lmalign/registration/stages/p2d_step.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(estimate_p2d_step)

namespace lmalign::stages {

namespace {

struct P2DStepOptions {
  bool four_dof = false;  ///< estimate.dof 4: x, y, z and the yaw about the target's up axis
  double block_factor = 0.5;
  int half_sample_planes = 8;
  std::size_t half_sample_min_landmarks = 12;
};

class P2DStepEstimator : public Estimator {
 public:
  explicit P2DStepEstimator(P2DStepOptions o) : o_(o) {}
  bool needs_scales() const override { return true; }
  Pairs::Kind needs() const override { return Pairs::Kind::kDistributions; }
  std::size_t min_pairs() const override { return o_.four_dof ? 2 : 3; }
  int degrees_of_freedom() const override { return o_.four_dof ? 4 : 6; }
  bool estimates_scale() const override { return !o_.four_dof; }
  bool distribution_step(const LoopState&) const override { return true; }

  Step solve(const RefineContext& c, const LoopState& loop, const Pairs& pairs, const Pose& current,
             const Isometry3&) const override {
    const Vec3& pivot = loop.sigma.pivot_m;
    std::vector<Mat3> rotated;
    const P2DBasis basis = this->basis(c, loop, pairs, current.T_target_source, &rotated);
    std::vector<double> buffer;
    const P2DStep s = solve_p2d_step(pairs.gated, c.target->points(), pivot,
                                     weights(c, loop, pairs, &buffer), basis);
    Step step;
    step.ok = s.ok;
    step.has_xi = true;
    step.xi = s.xi;
    step.pivot_m = pivot;
    step.hessian = s.hessian;
    step.dof = s.dof;
    step.chi2 = s.chi2;
    step.estimate = current;
    if (s.ok) {
      step.estimate.T_target_source =
          apply_step(current.T_target_source, s.xi, pivot, &step.estimate.scale);
      step.increment = step.estimate.T_target_source * current.T_target_source.inverse();
    }
    return step;
  }

  PoseCovariance covariance(const RefineContext& c, const Pipeline&, const LoopState& loop,
                            const Pairs& pairs, const Pose& estimate,
                            const Step* last_step) const override {
    if (last_step == nullptr) return {};
    // The normal equations of the last step (or, with the scale free, those of a 7-DoF step on
    // the same pairs: the step may have been a rigid one); validity, and with it the trust
    // verdict, as they say.
    P2DStep s;
    s.ok = last_step->ok;
    s.xi = last_step->xi;
    s.hessian = last_step->hessian;
    s.dof = last_step->dof;
    s.chi2 = last_step->chi2;
    std::vector<Mat3> rotated;
    const P2DBasis basis = this->basis(c, loop, pairs, estimate.T_target_source, &rotated);
    std::vector<double> buffer;
    const std::vector<double>& w = weights(c, loop, pairs, &buffer);
    if (basis.kind == P2DBasis::Kind::k7 && s.dof != 7) {
      s = solve_p2d_step(pairs.gated, c.target->points(), last_step->pivot_m, w, basis);
    }
    PoseCovariance cov = p2d_covariance(s, pairs.size(), last_step->pivot_m);
    if (!cov.valid || o_.four_dof) return cov;
    const PoseCovariance robust =
        p2d_cluster_covariance(pairs.gated, c.target->points(), last_step->pivot_m, w,
                               o_.block_factor * c.scales->source.radius_m, basis);
    if (robust.valid) cov = robust;
    return cov;
  }

  // Raised to the half-sample covariance (see half_sample_deviations) when enough halves count.
  PoseCovariance resampled_covariance(const RefineContext& c, const Pipeline& pipeline,
                                      const Pose& estimate, const PoseCovariance& estimator_cov,
                                      std::size_t* num_resamples) const override {
    PoseCovariance cov = estimator_cov;
    if (!cov.valid || o_.four_dof || o_.half_sample_planes <= 0) return cov;
    const std::vector<Vec7> deviations = half_sample_deviations(c, pipeline, estimate);
    const std::size_t halves = 2 * static_cast<std::size_t>(o_.half_sample_planes + 1);
    if (2 * deviations.size() < halves) return cov;
    Mat7 B = Mat7::Zero();
    for (const Vec7& d : deviations) B.noalias() += d * d.transpose();
    B /= static_cast<double>(deviations.size());
    if (cov.has_scale) {
      cov.covariance_7x7 = covariance_max(cov.covariance_7x7, B);
      cov.covariance = cov.covariance_7x7.topLeftCorner<6, 6>();
    } else {
      cov.covariance = covariance_max(cov.covariance, Mat6(B.topLeftCorner<6, 6>()));
    }
    if (num_resamples != nullptr) *num_resamples = deviations.size();
    return cov;
  }

 private:
  // The overlap landmarks (those that pass the gate widened by one resolution of pose
  // uncertainty at the estimate) are cut by half_sample_planes vertical planes through their
  // centroid (at k x 180 deg / n about the source's up axis from their widest horizontal
  // direction) and one horizontal plane; each side of each plane is refined again from the
  // estimate (the gate at its floor, its scale free when the run's is), and its deviation is
  // pose_error_twist (similarity_error_twist) against the
  // estimate. Halves with fewer than half_sample_min_landmarks landmarks, and refinements that
  // do not end settled or at their budget, are left out. One slot per half: deterministic.
  // The pairs' weights in the step: the kernel's, except with the scale free. Then the step
  // minimises what the gated score measures (gated_inlier_score: the sum over the gated pairs
  // of 1 - d^2 / chi2 times each pair's evidence weight, pair_evidence), so that a similarity
  // never scores below the rigid answer it refines from; with the kernel's weights its scale
  // settled up to 1% away from the score's best on real pairs (docs/scale.md). *buffer holds
  // the evidence weights (empty: every pair alike).
  const std::vector<double>& weights(const RefineContext& c, const LoopState& loop,
                                     const Pairs& pairs, std::vector<double>* buffer) const {
    if (!loop.free_scale) return pairs.weights;
    buffer->clear();
    if (c.scales == nullptr || !c.scales->evidence().on()) return *buffer;
    buffer->reserve(pairs.gated.size());
    for (const GatedPair& g : pairs.gated) buffer->push_back(evidence_weight(g));
    return *buffer;
  }

  // The basis of a step at T: 4 DoF, 7 with the loop's free scale (each pair's source covariance
  // rotated into the target frame, in *rotated), else 6.
  P2DBasis basis(const RefineContext& c, const LoopState& loop, const Pairs& pairs,
                 const Isometry3& T, std::vector<Mat3>* rotated) const {
    P2DBasis b;
    if (o_.four_dof) {
      b.kind = P2DBasis::Kind::k4;
      b.up = c.scales->up_target;
    } else if (loop.free_scale) {
      b.kind = P2DBasis::Kind::k7;
      if (c.source.has_covariances()) {
        const Mat3& R = T.linear();
        rotated->reserve(pairs.gated.size());
        for (const GatedPair& g : pairs.gated) {
          rotated->push_back(R * (*c.source.covariances_m2)[g.source_index] * R.transpose());
        }
        b.source_covariances_m2 = rotated;
      }
    }
    return b;
  }

  std::vector<Vec7> half_sample_deviations(const RefineContext& c, const Pipeline& pipeline,
                                           const Pose& estimate) const {
    const Isometry3& T = estimate.T_target_source;
    const Vec3& up = c.scales->up_source;
    LoopState wide;
    wide.sigma.translation_m = c.init->resolution_m;
    wide.sigma.pivot_m = T * c.scales->source.centre_m;
    Pairs near;
    // The match at the estimate warms a state of the whole source: each half's first iteration,
    // also at the estimate, then starts from its landmarks' neighbours (the same pairs, faster).
    const std::unique_ptr<StageState> at_estimate = pipeline.matcher().begin(c);
    pipeline.matcher().match(c, at_estimate.get(), T, wide, &near);
    std::vector<std::uint32_t> overlap;
    overlap.reserve(near.gated.size());
    for (const GatedPair& g : near.gated) overlap.push_back(g.source_index);

    const Points3& p = *c.source.positions;
    std::vector<Vec7> out;
    if (overlap.size() < 2 * o_.half_sample_min_landmarks) return out;
    Vec3 centre = Vec3::Zero();
    for (std::uint32_t i : overlap) centre += p[i];
    centre /= static_cast<double>(overlap.size());
    Mat3 scatter = Mat3::Zero();
    for (std::uint32_t i : overlap) {
      Vec3 q = p[i] - centre;
      q -= up * up.dot(q);
      scatter.noalias() += q * q.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Mat3> eig(scatter);
    Vec3 widest = eig.eigenvectors().col(2);
    widest -= up * up.dot(widest);
    if (!(widest.norm() > 0.0)) widest = up.unitOrthogonal();
    widest.normalize();
    const int n = o_.half_sample_planes;
    std::vector<Vec3> normals;
    for (int k = 0; k < n; ++k) normals.push_back(Eigen::AngleAxisd(kPi * k / n, up) * widest);
    normals.push_back(up);
    const std::size_t slots = 2 * normals.size();
    std::vector<std::optional<Vec7>> dev(slots);
    Hypothesis from;
    from.T_target_source = T;
    FirstException error;  // an exception may not leave the parallel loop
#pragma omp parallel for schedule(dynamic, 1)
    for (std::ptrdiff_t s = 0; s < static_cast<std::ptrdiff_t>(slots); ++s) {
      error.capture([&] {
        const Vec3& normal = normals[static_cast<std::size_t>(s) / 2];
        const bool below = s % 2 == 0;
        std::vector<std::uint32_t> half;
        for (std::uint32_t i : overlap) {
          if ((normal.dot(p[i] - centre) < 0.0) == below) half.push_back(i);
        }
        if (half.size() < o_.half_sample_min_landmarks) return;
        const Refinement r =
            pipeline.refine_part(c, half, from, Phase::kResample, at_estimate.get());
        if (r.termination != TerminationReason::kTransform &&
            r.termination != TerminationReason::kMaxIterations) {
          return;
        }
        if (c.free_scale) {
          dev[static_cast<std::size_t>(s)] = similarity_error_twist(r.T, r.scale, T);
        } else {
          Vec7 d = Vec7::Zero();
          d.head<6>() = pose_error_twist(r.T, T);
          dev[static_cast<std::size_t>(s)] = d;
        }
      });
    }
    error.rethrow();
    for (const auto& d : dev) {
      if (d && d->allFinite()) out.push_back(*d);
    }
    return out;
  }

  P2DStepOptions o_;
};

const SettingsBinding<P2DStepOptions>& binding() {
  static const SettingsBinding<P2DStepOptions> b =
      SettingsBinding<P2DStepOptions>("P2DStepOptions")
          .add("estimate.covariance_block_factor", LMALIGN_FIELD(block_factor),
               SettingBound::above(0.0), "1",
               "edge of the spatial blocks of the cluster-robust covariance, as a fraction of the "
               "source's radius")
          .add("estimate.half_sample_planes", LMALIGN_FIELD(half_sample_planes),
               SettingBound::closed(0, 1000), "count",
               "vertical planes cutting the overlap in halves for the half-sample covariance (0: "
               "off); costs 2 (n + 1) refinements of half the overlap, run for a trusted answer "
               "and where the verdict weighs the standard deviations (an untrusted answer "
               "reports the estimator's covariance alone)")
          .add("estimate.half_sample_min_landmarks", LMALIGN_FIELD(half_sample_min_landmarks),
               SettingBound::at_least(3), "count",
               "a half with fewer landmarks is left out of the half-sample covariance");
  return b;
}

}  // namespace

std::vector<SettingRow> estimate_p2d_step_settings() {
  // The degrees of freedom are a choice of names ("6", "4") over a flag; the rest are bound.
  std::vector<SettingRow> rows = {choice_setting(
      "estimate.dof", "P2DStepOptions::four_dof", P2DStepOptions{}.four_dof ? "4" : "6", {"6", "4"},
      "degrees of freedom: 6, or 4 (x, y, z and the yaw about the target's up axis, "
      "scales.up_target; roll and pitch kept)")};
  rows.insert(rows.end(), binding().rows().begin(), binding().rows().end());
  return rows;
}

std::unique_ptr<Stage> make_estimate_p2d_step(const Settings& s) {
  P2DStepOptions o = binding().read(s);
  o.four_dof = s.choice("estimate.dof") == "4";
  return std::make_unique<P2DStepEstimator>(o);
}

}  // namespace lmalign::stages
