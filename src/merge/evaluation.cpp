// Ground-truth evaluation of a merge (include/lmalign/merge/evaluation.hpp).
#include "lmalign/merge/evaluation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <yaml-cpp/yaml.h>

#include <Eigen/SVD>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/pipeline.hpp"

namespace lmalign {

std::vector<Similarity3> read_ground_truth_similarities(const std::string& path,
                                                        const std::vector<std::string>& names) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw IoError("cannot read ground truth '" + path + "'");
  } catch (const YAML::ParserException& e) {
    throw ParseError(path, static_cast<std::size_t>(e.mark.line + 1), "YAML: " + e.msg);
  }
  const YAML::Node maps = root["maps"];
  if (!maps || !maps.IsMap()) {
    throw ParseError(path, 0, "expected 'maps: {name: [[4x4 rows of T_world_map]], ...}'");
  }
  std::vector<Similarity3> out;
  for (const std::string& name : names) {
    const YAML::Node m = maps[name];
    if (!m) throw ParseError(path, 0, "maps: no pose for map '" + name + "'");
    const std::size_t line = static_cast<std::size_t>(m.Mark().line + 1);
    const std::string expected = "maps." + name + ": expected 4 rows of 4 numbers (T_world_map)";
    if (!m.IsSequence() || m.size() != 4) throw ParseError(path, line, expected);
    Isometry3 T = Isometry3::Identity();
    for (int r = 0; r < 4; ++r) {
      if (!m[r].IsSequence() || m[r].size() != 4) throw ParseError(path, line, expected);
      for (int c = 0; c < 4; ++c) {
        try {
          T.matrix()(r, c) = m[r][c].as<double>();
        } catch (const YAML::Exception&) {
          throw ParseError(path, line, expected);
        }
      }
    }
    if (T.matrix().row(3) != Eigen::RowVector4d(0, 0, 0, 1)) {
      throw ParseError(path, line, "maps." + name + ": not a rigid transform");
    }
    if (is_rigid_transform(T)) {
      out.push_back(Similarity3{1.0, T});
      continue;
    }
    // A similarity [sR t; 0 1] (maps without metric scale).
    const double s = std::cbrt(T.linear().determinant());
    if (!std::isfinite(s) || !(s > 0.0)) {
      throw ParseError(path, line,
                       "maps." + name + ": scale (cube root of the 3x3 block's determinant) " +
                           message_number(s) + ", expected finite and > 0");
    }
    Isometry3 R = Isometry3::Identity();
    R.linear() = T.linear() / s;
    R.translation() = T.translation();
    if (!is_rigid_transform(R)) {
      throw ParseError(path, line, "maps." + name + ": not a rigid transform nor a similarity");
    }
    out.push_back(Similarity3{s, R});
  }
  return out;
}

std::vector<Isometry3> read_ground_truth(const std::string& path,
                                         const std::vector<std::string>& names) {
  const std::vector<Similarity3> S = read_ground_truth_similarities(path, names);
  std::vector<Isometry3> out;
  for (std::size_t i = 0; i < S.size(); ++i) {
    if (S[i].scale != 1.0) {
      throw ParseError(path, 0,
                       "maps." + names[i] + ": not a rigid transform (scale " +
                           message_number(S[i].scale) +
                           "; read_ground_truth_similarities reads similarities)");
    }
    out.push_back(S[i].rigid);
  }
  return out;
}

MergeEvaluation evaluate_merge(const MergeResult& result, const std::vector<Edge>& edges,
                               const std::vector<Isometry3>& truth,
                               const GroundTruthThresholds& thresholds) {
  std::vector<Similarity3> S;
  for (const Isometry3& T : truth) S.push_back(Similarity3{1.0, T});
  return evaluate_merge(result, edges, S, thresholds);
}

namespace {

// One evaluate_merge() against true similarities (merge/evaluation.hpp), part by part.
class MergeScoring {
 public:
  MergeScoring(const MergeResult& result, const std::vector<Edge>& edges,
               const std::vector<Similarity3>& truth, const GroundTruthThresholds& thresholds)
      : result_(result), edges_(edges), truth_(truth), t_(thresholds), n_(result.maps.size()) {}

  MergeEvaluation run() {
    if (truth_.size() != n_ || result_.edges.size() != edges_.size()) {
      throw InvalidArgument("evaluate_merge: " + std::to_string(truth_.size()) +
                            " true poses for " + std::to_string(n_) + " maps");
    }
    ev_.maps.resize(n_);
    // Estimated and true similarities S_world_map (scale 1 for rigid maps).
    est_.resize(n_);
    for (std::size_t i = 0; i < n_; ++i) est_[i] = result_.maps[i].similarity();
    group_parts();
    // The maps held by priors share one frame: one G for all of them.
    if (!prior_maps_.empty()) set_errors(robust_fit(prior_maps_), prior_maps_);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (std::size_t c = 0; c < parts_.size(); ++c) {
      const std::vector<std::size_t>& members = parts_[c];
      if (members.empty() || by_priors_[c]) continue;
      if (members.size() == 1) {  // alone without priors: its frame is its own, nothing to measure
        ev_.maps[members[0]].rotation_deg = nan;
        ev_.maps[members[0]].translation_m = nan;
        ev_.maps[members[0]].scale_error = nan;
        continue;
      }
      set_errors(robust_fit(members), members);
    }
    count_edge_parts();
    count_maps();
    count_pairs();
    count_edges();
    return std::move(ev_);
  }

 private:
  struct Error7 {
    TransformError pose;
    double scale = 0.0;
  };
  static Error7 error_of(const Similarity3& S_est, const Similarity3& S_true) {
    return Error7{transform_error(S_est.rigid, S_true.rigid),
                  std::abs(S_est.scale / S_true.scale - 1.0)};
  }
  bool within_thresholds(const Error7& err) const {
    return err.pose.rotation_deg <= t_.rotation_deg && err.pose.translation_m <= t_.translation_m &&
           err.scale <= t_.scale;
  }

  // G fitted to the members: chordal rotation mean of R_true R_est^T, then mean translation.
  Similarity3 fit(const std::vector<std::size_t>& members) const {
    Mat3 M = Mat3::Zero();
    double log_g = 0.0;
    for (const std::size_t i : members) {
      M += truth_[i].rigid.linear() * est_[i].rigid.linear().transpose();
      log_g += std::log(truth_[i].scale / est_[i].scale);
    }
    const double g = std::exp(log_g / static_cast<double>(members.size()));
    Eigen::JacobiSVD<Mat3> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Mat3 D = Mat3::Identity();
    D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
    Similarity3 G{g, Isometry3::Identity()};
    G.rigid.linear() = svd.matrixU() * D * svd.matrixV().transpose();
    Vec3 t = Vec3::Zero();
    for (const std::size_t i : members) {
      t += truth_[i].rigid.translation() - g * (G.rigid.linear() * est_[i].rigid.translation());
    }
    G.rigid.translation() = t / static_cast<double>(members.size());
    return G;
  }

  std::vector<std::size_t> agreeing(const Similarity3& G,
                                    const std::vector<std::size_t>& members) const {
    std::vector<std::size_t> in;
    for (const std::size_t i : members) {
      if (within_thresholds(error_of(G * est_[i], truth_[i]))) in.push_back(i);
    }
    return in;
  }

  // G fitted to the maps of a group that agree with the truth (docs/merge.md, "Ground truth"):
  // each map's own G_k = T_true_k T_est_k^-1 is a candidate; the one that puts the most maps
  // within the thresholds wins (ties: the lowest map), then G is refitted to those maps when that
  // keeps as many.
  Similarity3 robust_fit(const std::vector<std::size_t>& members) const {
    Similarity3 G = fit(members);
    std::vector<std::size_t> best = agreeing(G, members);
    for (const std::size_t k : members) {
      const Similarity3 G_k = truth_[k] * est_[k].inverse();
      std::vector<std::size_t> in = agreeing(G_k, members);
      if (in.size() > best.size()) {
        best = std::move(in);
        G = G_k;
      }
    }
    if (!best.empty()) {
      const Similarity3 G_fit = fit(best);
      if (agreeing(G_fit, members).size() >= best.size()) G = G_fit;
    }
    return G;
  }

  void set_errors(const Similarity3& G, const std::vector<std::size_t>& members) {
    for (const std::size_t i : members) {
      const Error7 err = error_of(G * est_[i], truth_[i]);
      ev_.maps[i].rotation_deg = err.pose.rotation_deg;
      ev_.maps[i].translation_m = err.pose.translation_m;
      ev_.maps[i].scale_error = err.scale;
      ev_.maps[i].within = within_thresholds(err);  // cleared below unless placed
    }
  }

  // The parts, which are held by priors (no gauge map: their frame is the priors'), and the
  // reference frame: the priors' when any part has them, else the largest part's.
  void group_parts() {
    ev_.num_parts = result_.num_components;
    parts_.resize(result_.num_components);
    for (std::size_t i = 0; i < n_; ++i) {
      if (result_.maps[i].component >= parts_.size()) parts_.resize(result_.maps[i].component + 1);
      parts_[result_.maps[i].component].push_back(i);
    }
    by_priors_.assign(parts_.size(), false);
    for (std::size_t c = 0; c < parts_.size(); ++c) {
      by_priors_[c] = !parts_[c].empty() &&
                      std::none_of(parts_[c].begin(), parts_[c].end(),
                                   [&](std::size_t i) { return result_.maps[i].is_gauge; });
      if (by_priors_[c]) prior_maps_.insert(prior_maps_.end(), parts_[c].begin(), parts_[c].end());
    }
    for (std::size_t c = 0; c < parts_.size(); ++c) {
      ev_.largest_part = std::max(ev_.largest_part, parts_[c].size());
      if (parts_[c].size() > parts_[largest_].size()) largest_ = c;
    }
  }

  bool placed_part(std::size_t c) const {
    return prior_maps_.empty() ? c == largest_ && parts_[c].size() >= 2 : bool(by_priors_[c]);
  }

  // The kept edges' own components (union-find), and who has a kept edge.
  void count_edge_parts() {
    std::vector<std::size_t> root(n_);
    for (std::size_t i = 0; i < n_; ++i) root[i] = i;
    auto find = [&](std::size_t i) {
      while (root[i] != i) i = root[i] = root[root[i]];
      return i;
    };
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      if (!result_.edges[e].used || result_.edges[e].rejected) continue;
      ev_.maps[edges_[e].source].connected = ev_.maps[edges_[e].target].connected = true;
      root[find(edges_[e].source)] = find(edges_[e].target);
    }
    for (std::size_t i = 0; i < n_; ++i) ev_.num_edge_parts += find(i) == i ? 1 : 0;
  }

  void count_maps() {
    std::size_t within = 0;
    for (std::size_t i = 0; i < n_; ++i) {
      MapError& e = ev_.maps[i];
      e.placed = placed_part(result_.maps[i].component);
      e.within = e.within && e.placed;
      ev_.placed += e.placed ? 1 : 0;
      within += e.within ? 1 : 0;
      if (!std::isnan(e.rotation_deg)) {
        ev_.max_rotation_deg = std::max(ev_.max_rotation_deg, e.rotation_deg);
        ev_.max_translation_m = std::max(ev_.max_translation_m, e.translation_m);
        ev_.max_scale_error = std::max(ev_.max_scale_error, e.scale_error);
      }
    }
    ev_.fraction_within = n_ ? static_cast<double>(within) / static_cast<double>(n_) : 1.0;
  }

  // Pairs: relative poses need no gauge; two maps share a frame in one part, or both by priors.
  void count_pairs() {
    if (n_ > 2000) {
      ev_.pair_fraction_within = std::numeric_limits<double>::quiet_NaN();
      return;
    }
    std::size_t pairs = 0;
    for (std::size_t i = 0; i < n_; ++i) {
      for (std::size_t j = i + 1; j < n_; ++j) {
        ++pairs;
        const std::size_t ci = result_.maps[i].component, cj = result_.maps[j].component;
        if (ci != cj && !(by_priors_[ci] && by_priors_[cj])) continue;
        const Error7 err = error_of(est_[i].inverse() * est_[j], truth_[i].inverse() * truth_[j]);
        ev_.pairs_within += within_thresholds(err) ? 1 : 0;
        ev_.max_pair_scale_error = std::max(ev_.max_pair_scale_error, err.scale);
      }
    }
    ev_.pair_fraction_within =
        pairs ? static_cast<double>(ev_.pairs_within) / static_cast<double>(pairs) : 1.0;
  }

  // Each edge against the truth; the kept ones' precision and recall.
  void count_edges() {
    std::size_t kept_true = 0, all_true = 0;
    ev_.edge_true.resize(edges_.size());
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      const Edge& ed = edges_[e];
      const Similarity3 S_true = truth_[ed.target].inverse() * truth_[ed.source];
      const bool ok =
          within_thresholds(error_of(Similarity3{ed.scale, ed.T_target_source}, S_true));
      ev_.edge_true[e] = ok;
      all_true += ok ? 1 : 0;
      const bool kept = result_.edges[e].used && !result_.edges[e].rejected;
      if (kept) {
        ++ev_.kept_edges;
        kept_true += ok ? 1 : 0;
        ev_.false_kept_edges += ok ? 0 : 1;
      }
    }
    ev_.edge_precision =
        ev_.kept_edges ? static_cast<double>(kept_true) / static_cast<double>(ev_.kept_edges) : 1.0;
    ev_.edge_recall =
        all_true ? static_cast<double>(kept_true) / static_cast<double>(all_true) : 1.0;
  }

  const MergeResult& result_;
  const std::vector<Edge>& edges_;
  const std::vector<Similarity3>& truth_;
  const GroundTruthThresholds& t_;
  const std::size_t n_;
  MergeEvaluation ev_;
  std::vector<Similarity3> est_;
  std::vector<std::vector<std::size_t>> parts_;
  std::vector<bool> by_priors_;
  std::vector<std::size_t> prior_maps_;
  std::size_t largest_ = 0;
};

}  // namespace

MergeEvaluation evaluate_merge(const MergeResult& result, const std::vector<Edge>& edges,
                               const std::vector<Similarity3>& truth,
                               const GroundTruthThresholds& thresholds) {
  return MergeScoring(result, edges, truth, thresholds).run();
}

}  // namespace lmalign
