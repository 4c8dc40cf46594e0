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

MergeEvaluation evaluate_merge(const MergeResult& result, const std::vector<Edge>& edges,
                               const std::vector<Similarity3>& truth,
                               const GroundTruthThresholds& thresholds) {
  const std::size_t n = result.maps.size();
  if (truth.size() != n || result.edges.size() != edges.size()) {
    throw InvalidArgument("evaluate_merge: " + std::to_string(truth.size()) + " true poses for " +
                          std::to_string(n) + " maps");
  }
  MergeEvaluation ev;
  ev.maps.resize(n);
  // Per group (the maps held by priors, or a part without priors): G fitted to the maps that agree
  // with the truth: each map's own G_k = T_true_k T_est_k^-1 is a candidate; the one that puts the
  // most maps within the thresholds wins (ties: the lowest map), then G is refitted to those maps
  // (chordal rotation mean of R_true R_est^T, then mean translation) when that keeps as many.
  // Estimated and true similarities S_world_map (scale 1 for rigid maps).
  std::vector<Similarity3> est(n);
  for (std::size_t i = 0; i < n; ++i) est[i] = result.maps[i].similarity();
  struct Error7 {
    TransformError pose;
    double scale = 0.0;
  };
  auto error_of = [&](const Similarity3& S_est, const Similarity3& S_true) {
    return Error7{transform_error(S_est.rigid, S_true.rigid),
                  std::abs(S_est.scale / S_true.scale - 1.0)};
  };
  auto within_thresholds = [&](const Error7& err) {
    return err.pose.rotation_deg <= thresholds.rotation_deg &&
           err.pose.translation_m <= thresholds.translation_m && err.scale <= thresholds.scale;
  };
  auto fit = [&](const std::vector<std::size_t>& members) {
    Mat3 M = Mat3::Zero();
    double log_g = 0.0;
    for (const std::size_t i : members) {
      M += truth[i].rigid.linear() * est[i].rigid.linear().transpose();
      log_g += std::log(truth[i].scale / est[i].scale);
    }
    const double g = std::exp(log_g / static_cast<double>(members.size()));
    Eigen::JacobiSVD<Mat3> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Mat3 D = Mat3::Identity();
    D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
    Similarity3 G{g, Isometry3::Identity()};
    G.rigid.linear() = svd.matrixU() * D * svd.matrixV().transpose();
    Vec3 t = Vec3::Zero();
    for (const std::size_t i : members) {
      t += truth[i].rigid.translation() - g * (G.rigid.linear() * est[i].rigid.translation());
    }
    G.rigid.translation() = t / static_cast<double>(members.size());
    return G;
  };
  auto agreeing = [&](const Similarity3& G, const std::vector<std::size_t>& members) {
    std::vector<std::size_t> in;
    for (const std::size_t i : members) {
      if (within_thresholds(error_of(G * est[i], truth[i]))) in.push_back(i);
    }
    return in;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // The parts, and which are held by priors (no gauge map: their frame is the priors').
  ev.num_parts = result.num_components;
  std::vector<std::vector<std::size_t>> parts(result.num_components);
  for (std::size_t i = 0; i < n; ++i) {
    if (result.maps[i].component >= parts.size()) parts.resize(result.maps[i].component + 1);
    parts[result.maps[i].component].push_back(i);
  }
  std::vector<bool> by_priors(parts.size(), false);
  std::vector<std::size_t> prior_maps;
  for (std::size_t c = 0; c < parts.size(); ++c) {
    by_priors[c] =
        !parts[c].empty() && std::none_of(parts[c].begin(), parts[c].end(),
                                          [&](std::size_t i) { return result.maps[i].is_gauge; });
    if (by_priors[c]) prior_maps.insert(prior_maps.end(), parts[c].begin(), parts[c].end());
  }
  // The reference frame: the priors' when any part has them, else the largest part's.
  std::size_t largest = 0;
  for (std::size_t c = 0; c < parts.size(); ++c) {
    ev.largest_part = std::max(ev.largest_part, parts[c].size());
    if (parts[c].size() > parts[largest].size()) largest = c;
  }
  auto placed_part = [&](std::size_t c) {
    return prior_maps.empty() ? c == largest && parts[c].size() >= 2 : bool(by_priors[c]);
  };
  auto set_errors = [&](const Similarity3& G, const std::vector<std::size_t>& members) {
    for (const std::size_t i : members) {
      const Error7 err = error_of(G * est[i], truth[i]);
      ev.maps[i].rotation_deg = err.pose.rotation_deg;
      ev.maps[i].translation_m = err.pose.translation_m;
      ev.maps[i].scale_error = err.scale;
      ev.maps[i].within = within_thresholds(err);  // cleared below unless placed
    }
  };
  // G fitted to the maps of a group that agree with the truth (docs/merge.md, "Ground truth").
  auto robust_fit = [&](const std::vector<std::size_t>& members) {
    Similarity3 G = fit(members);
    std::vector<std::size_t> best = agreeing(G, members);
    for (const std::size_t k : members) {
      const Similarity3 G_k = truth[k] * est[k].inverse();
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
  };
  // The maps held by priors share one frame: one G for all of them.
  if (!prior_maps.empty()) set_errors(robust_fit(prior_maps), prior_maps);
  for (std::size_t c = 0; c < parts.size(); ++c) {
    const std::vector<std::size_t>& members = parts[c];
    if (members.empty() || by_priors[c]) continue;
    if (members.size() == 1) {  // alone without priors: its frame is its own, nothing to measure
      ev.maps[members[0]].rotation_deg = nan;
      ev.maps[members[0]].translation_m = nan;
      ev.maps[members[0]].scale_error = nan;
      continue;
    }
    set_errors(robust_fit(members), members);
  }
  // The kept edges' own components (union-find), and who has a kept edge.
  std::vector<std::size_t> root(n);
  for (std::size_t i = 0; i < n; ++i) root[i] = i;
  auto find = [&](std::size_t i) {
    while (root[i] != i) i = root[i] = root[root[i]];
    return i;
  };
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (!result.edges[e].used || result.edges[e].rejected) continue;
    ev.maps[edges[e].source].connected = ev.maps[edges[e].target].connected = true;
    root[find(edges[e].source)] = find(edges[e].target);
  }
  for (std::size_t i = 0; i < n; ++i) ev.num_edge_parts += find(i) == i ? 1 : 0;
  std::size_t within = 0;
  for (std::size_t i = 0; i < n; ++i) {
    MapError& e = ev.maps[i];
    const std::size_t c = result.maps[i].component;
    e.placed = placed_part(c);
    e.within = e.within && e.placed;
    ev.placed += e.placed ? 1 : 0;
    within += e.within ? 1 : 0;
    if (!std::isnan(e.rotation_deg)) {
      ev.max_rotation_deg = std::max(ev.max_rotation_deg, e.rotation_deg);
      ev.max_translation_m = std::max(ev.max_translation_m, e.translation_m);
      ev.max_scale_error = std::max(ev.max_scale_error, e.scale_error);
    }
  }
  ev.fraction_within = n ? static_cast<double>(within) / static_cast<double>(n) : 1.0;
  // Pairs: relative poses need no gauge; two maps share a frame in one part, or both by priors.
  if (n > 2000) {
    ev.pair_fraction_within = nan;
  } else {
    std::size_t pairs = 0;
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t j = i + 1; j < n; ++j) {
        ++pairs;
        const std::size_t ci = result.maps[i].component, cj = result.maps[j].component;
        if (ci != cj && !(by_priors[ci] && by_priors[cj])) continue;
        const Error7 err = error_of(est[i].inverse() * est[j], truth[i].inverse() * truth[j]);
        ev.pairs_within += within_thresholds(err) ? 1 : 0;
        ev.max_pair_scale_error = std::max(ev.max_pair_scale_error, err.scale);
      }
    }
    ev.pair_fraction_within =
        pairs ? static_cast<double>(ev.pairs_within) / static_cast<double>(pairs) : 1.0;
  }
  std::size_t kept_true = 0, all_true = 0;
  ev.edge_true.resize(edges.size());
  for (std::size_t e = 0; e < edges.size(); ++e) {
    const Edge& ed = edges[e];
    const Similarity3 S_true = truth[ed.target].inverse() * truth[ed.source];
    const bool ok = within_thresholds(error_of(Similarity3{ed.scale, ed.T_target_source}, S_true));
    ev.edge_true[e] = ok;
    all_true += ok ? 1 : 0;
    const bool kept = result.edges[e].used && !result.edges[e].rejected;
    if (kept) {
      ++ev.kept_edges;
      kept_true += ok ? 1 : 0;
      ev.false_kept_edges += ok ? 0 : 1;
    }
  }
  ev.edge_precision =
      ev.kept_edges ? static_cast<double>(kept_true) / static_cast<double>(ev.kept_edges) : 1.0;
  ev.edge_recall = all_true ? static_cast<double>(kept_true) / static_cast<double>(all_true) : 1.0;
  return ev;
}

}  // namespace lmalign
