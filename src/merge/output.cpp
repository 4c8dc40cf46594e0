// Outputs of a merge (include/lmalign/merge/output.hpp).
#include "lmalign/merge/output.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include <Eigen/Eigenvalues>

#include "lmalign/core/error.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/io/output_file.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/map/transform.hpp"
#include "lmalign/merge/folds.hpp"

namespace lmalign {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

json matrix_json(const Eigen::MatrixXd& m) {
  json rows = json::array();
  for (int r = 0; r < m.rows(); ++r) {
    json row = json::array();
    for (int c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
    rows.push_back(row);
  }
  return rows;
}

Eigen::MatrixXd json_matrix(const json& j, int rows, int cols, const std::string& field) {
  if (!j.is_array() || static_cast<int>(j.size()) != rows) {
    throw InvalidArgument(field + ": expected " + std::to_string(rows) + " rows");
  }
  Eigen::MatrixXd m(rows, cols);
  for (int r = 0; r < rows; ++r) {
    if (!j[r].is_array() || static_cast<int>(j[r].size()) != cols) {
      throw InvalidArgument(field + ": expected " + std::to_string(cols) + " columns");
    }
    for (int c = 0; c < cols; ++c) m(r, c) = j[r][c].get<double>();
  }
  return m;
}

std::string yaml_row(const Eigen::MatrixXd& m, int r) {
  std::ostringstream os;
  os << std::setprecision(17) << "[";
  for (int c = 0; c < m.cols(); ++c) os << (c ? ", " : "") << m(r, c);
  os << "]";
  return os.str();
}

// The coordinate-wise median of a map's landmarks moved by T (m): a centre that far landmarks
// do not drag; null without landmarks.
json landmark_centre(const Map& map, const Similarity3& T) {
  if (map.landmarks.empty()) return json();
  std::vector<double> axis[3];
  for (const Landmark& l : map.landmarks) {
    const Vec3 p = T * l.p_world;
    for (int k = 0; k < 3; ++k) axis[k].push_back(p[k]);
  }
  json out = json::array();
  for (std::vector<double>& v : axis) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    out.push_back(v[v.size() / 2]);
  }
  return out;
}

}  // namespace

Map merge_maps(const std::vector<Map>& maps, const std::vector<std::string>& sessions,
               const MergeResult& result, std::size_t component, const MergeOutputOptions& options,
               std::vector<std::pair<std::size_t, std::size_t>>* landmark_ranges,
               std::size_t* left_out) {
  if (sessions.size() != maps.size() || result.maps.size() != maps.size()) {
    throw InvalidArgument("merge_maps: maps, sessions and poses differ in number");
  }
  if (landmark_ranges != nullptr) landmark_ranges->assign(maps.size(), {0, 0});
  if (left_out != nullptr) *left_out = 0;
  Map out;
  bool any_metric = false, held_by_gauge = false;
  Id next_frame = 0;
  // (session, landmark id) -> index in out.landmarks, and the fused information sums.
  std::map<std::pair<std::string, Id>, std::size_t> fused;
  std::vector<Mat3> info_sum;
  std::vector<Vec3> info_mean_sum;
  for (std::size_t m = 0; m < maps.size(); ++m) {
    if (result.maps[m].component != component) continue;
    // Maps without metric scale by their similarity (covariances times s^2).
    const MapPose& pose = result.maps[m];
    const Map moved = pose.scale == 1.0 ? transform_map(maps[m], pose.T_world_map)
                                        : transform_map(maps[m], pose.similarity());
    const std::size_t first_landmark = out.landmarks.size();
    std::map<Id, Id> frame_id;
    for (const Frame& f : moved.frames) {
      Frame g = f;
      g.id = next_frame++;
      frame_id[f.id] = g.id;
      out.frames.push_back(g);
    }
    for (std::size_t li = 0; li < moved.landmarks.size(); ++li) {
      const Landmark& l = moved.landmarks[li];
      if (!within_supported_range(maps[m].landmarks[li].p_world)) {
        if (left_out != nullptr) ++*left_out;
        continue;
      }
      Landmark k = l;
      for (Observation& o : k.observations) o.frame_id = frame_id.at(o.frame_id);
      const bool fusable = options.fuse_landmarks && !sessions[m].empty();
      const auto key = std::make_pair(sessions[m], l.id);
      auto it = fusable ? fused.find(key) : fused.end();
      Eigen::LDLT<Mat3> ldlt(k.cov_world_m2);
      const bool invertible = ldlt.info() == Eigen::Success && k.cov_world_m2.determinant() > 0.0;
      if (it != fused.end() && invertible) {
        const std::size_t idx = it->second;
        const Mat3 info = k.cov_world_m2.inverse();
        info_sum[idx] += info;
        info_mean_sum[idx] += info * k.p_world;
        Landmark& f = out.landmarks[idx];
        f.cov_world_m2 = info_sum[idx].inverse();
        f.cov_world_m2 = 0.5 * (f.cov_world_m2 + f.cov_world_m2.transpose()).eval();
        f.p_world = f.cov_world_m2 * info_mean_sum[idx];
        f.observations.insert(f.observations.end(), k.observations.begin(), k.observations.end());
        continue;
      }
      k.id = static_cast<Id>(out.landmarks.size());
      if (fusable && invertible && it == fused.end()) fused[key] = out.landmarks.size();
      info_sum.push_back(invertible ? Mat3(k.cov_world_m2.inverse()) : Mat3::Zero());
      info_mean_sum.push_back(invertible ? Vec3(k.cov_world_m2.inverse() * k.p_world)
                                         : Vec3::Zero());
      out.landmarks.push_back(std::move(k));
    }
    if (landmark_ranges != nullptr) (*landmark_ranges)[m] = {first_landmark, out.landmarks.size()};
    any_metric = any_metric || maps[m].header.scale == MapScale::kMetric;
    held_by_gauge = held_by_gauge || result.maps[m].is_gauge;
    out.header.covariance_assumed =
        out.header.covariance_assumed || maps[m].header.covariance_assumed;
  }
  // Metres when a map of the component has them or priors hold it; else the gauge map's units.
  out.header.scale = any_metric || !held_by_gauge ? MapScale::kMetric : MapScale::kArbitrary;
  return out;
}

std::vector<MapNote> map_notes(const std::vector<Map>& maps, const std::vector<Edge>& edges,
                               const MergeResult& result) {
  if (result.maps.size() != maps.size() || result.edges.size() != edges.size()) {
    throw InvalidArgument("map_notes: maps, poses and edges differ in number");
  }
  std::vector<MapNote> notes(maps.size());
  std::vector<std::size_t> part_size(result.num_components, 0);
  for (const MapPose& p : result.maps) {
    if (p.component < part_size.size()) ++part_size[p.component];
  }
  std::map<std::string, std::size_t> first_with;  // fingerprint -> first map
  for (std::size_t i = 0; i < maps.size(); ++i) {
    const auto [it, fresh] = first_with.emplace(map_fingerprint(maps[i]), i);
    if (!fresh) notes[i].same_landmarks_as = it->second;
    const std::size_t c = result.maps[i].component;
    if (c < part_size.size() && part_size[c] > 1) continue;
    std::size_t pairs = 0, trusted = 0;
    std::map<std::string, std::size_t> reasons;  // untrusted edges' reasons, counted
    std::string graph_reason;
    for (std::size_t e = 0; e < edges.size(); ++e) {
      if (edges[e].source != i && edges[e].target != i) continue;
      ++pairs;
      const EdgeReport& r = result.edges[e];
      if (!edges[e].trusted) {
        ++reasons[edges[e].trust_reason.empty() ? "no reason given" : edges[e].trust_reason];
        continue;
      }
      ++trusted;
      if (graph_reason.empty()) {
        graph_reason = !r.skip_reason.empty()     ? r.skip_reason
                       : !r.reject_reason.empty() ? r.reject_reason
                       : r.rejected               ? "rejected by the graph after optimisation"
                                                  : "";
      }
    }
    if (pairs == 0) {
      notes[i].alone = "no candidate pair";
    } else if (trusted == 0) {
      std::vector<std::pair<std::size_t, std::string>> by_count;
      for (const auto& [reason, count] : reasons) by_count.emplace_back(count, reason);
      std::stable_sort(by_count.begin(), by_count.end(),
                       [](const auto& a, const auto& b) { return a.first > b.first; });
      std::string text;
      for (const auto& [count, reason] : by_count) {
        text += (text.empty() ? "" : "; ") + std::to_string(count) + ": " + reason;
      }
      notes[i].alone = "none of its " + std::to_string(pairs) + " pair" +
                       (pairs == 1 ? " was" : "s was") + " trusted (" + text + ")";
    } else {
      notes[i].alone = "its trusted pairs did not enter the graph or were rejected by it (" +
                       (graph_reason.empty() ? std::string("no reason given") : graph_reason) + ")";
    }
  }
  return notes;
}

void write_merge_outputs(const std::string& out_dir, const std::vector<std::string>& names,
                         const std::vector<std::string>& sessions, const std::vector<Map>& maps,
                         const std::vector<Edge>& edges, const MergeResult& result,
                         const MergeOutputOptions& options, const OverlapCheck* overlaps) {
  if (names.size() != maps.size() || result.maps.size() != maps.size() ||
      result.edges.size() != edges.size()) {
    throw InvalidArgument("write_merge_outputs: names, maps, poses and edges differ in number");
  }
  const bool checked = overlaps != nullptr && overlaps->ran;
  if (checked && overlaps->contradicted_per_map.size() != maps.size()) {
    throw InvalidArgument("write_merge_outputs: the overlap check is of other maps");
  }
  create_output_folder(out_dir);
  const fs::path dir(out_dir);
  // The merged maps first: which of their landmarks each map added (for the plots), and how many
  // they leave out (summary.json).
  std::vector<Map> merged(result.num_components);
  std::vector<std::pair<std::size_t, std::size_t>> ranges(maps.size(), {0, 0});
  std::size_t left_out = 0;
  for (std::size_t c = 0; c < result.num_components; ++c) {
    std::vector<std::pair<std::size_t, std::size_t>> r;
    std::size_t n = 0;
    merged[c] = merge_maps(maps, sessions, result, c, options, &r, &n);
    left_out += n;
    for (std::size_t i = 0; i < maps.size(); ++i) {
      if (result.maps[i].component == c) ranges[i] = r[i];
    }
  }
  json poses = json::array();
  for (std::size_t i = 0; i < maps.size(); ++i) {
    const MapPose& p = result.maps[i];
    poses.push_back(
        {{"name", names[i]},
         {"component", p.component},
         {"gauge", p.is_gauge},
         {"T_world_map", matrix_json(p.T_world_map.matrix())},
         {"covariance", matrix_json(p.covariance)},
         {"covariance_valid", p.covariance_valid},
         {"scale", p.scale},
         {"scale_sd", p.scale_sd},
         {"scale_free", p.scale_free},
         {"S_world_map", matrix_json(p.similarity().matrix())},
         {"landmark_centre_world", landmark_centre(maps[i], p.similarity())},
         {"merged_landmarks", {ranges[i].first, ranges[i].second}},
         {"contradicted_pairs", checked ? json(overlaps->contradicted_per_map[i]) : json()}});
  }
  json doc = {{"convention",
               "T_world_map: p_world = scale * R * p_map + t with (R, t) = T (m), S_world_map = "
               "[scale R, t; 0 0 0 1], scale: world units per map unit (1 for a map with metric "
               "scale); covariance: 6x6 of xi = (rho m, phi rad), T = Exp(xi) T_hat, world frame; "
               "each component has its own world frame"},
              {"num_components", result.num_components},
              {"maps", poses}};
  write_output((dir / "poses.json").string(), [&](std::ostream& os) { os << doc.dump(2) << "\n"; });
  write_output((dir / "poses.yaml").string(), [&](std::ostream& os) {
    os << "# lmalign merge: " << doc["convention"].get<std::string>() << "\n";
    os << "num_components: " << result.num_components << "\nmaps:\n";
    for (std::size_t i = 0; i < maps.size(); ++i) {
      const MapPose& p = result.maps[i];
      os << "  - name: \"" << names[i] << "\"\n    component: " << p.component
         << "\n    gauge: " << (p.is_gauge ? "true" : "false") << "\n    T_world_map:\n";
      for (int r = 0; r < 4; ++r) os << "      - " << yaml_row(p.T_world_map.matrix(), r) << "\n";
      os << std::setprecision(17) << "    scale: " << p.scale << "\n    scale_sd: " << p.scale_sd
         << "\n    scale_free: " << (p.scale_free ? "true" : "false") << "\n";
      os << "    covariance_valid: " << (p.covariance_valid ? "true" : "false")
         << "\n    covariance:\n";
      for (int r = 0; r < 6; ++r) os << "      - " << yaml_row(p.covariance, r) << "\n";
    }
  });
  write_output((dir / "edges.csv").string(), [&](std::ostream& os) {
    os << "source,target,trusted,used,rejected,chi2,inliers,inlier_ratio,initialisation,scale,"
          "scale_sd,reason\n";
    os << std::setprecision(10);
    for (std::size_t e = 0; e < edges.size(); ++e) {
      const Edge& ed = edges[e];
      const EdgeReport& r = result.edges[e];
      std::string reason = !r.skip_reason.empty()     ? r.skip_reason
                           : !r.reject_reason.empty() ? r.reject_reason
                           : r.rejected               ? "rejected by the graph"
                                                      : "ok";
      for (char& c : reason) {
        if (c == ',' || c == '\n' || c == '"') c = ';';
      }
      os << names[ed.source] << "," << names[ed.target] << "," << ed.trusted << "," << r.used << ","
         << r.rejected << "," << r.chi2 << "," << ed.num_inliers << "," << ed.inlier_ratio << ","
         << ed.initialisation << "," << ed.scale << "," << ed.scale_sd << "," << reason << "\n";
    }
  });
  const std::vector<MapNote> notes = map_notes(maps, edges, result);
  json alone = json::array(), same = json::array();
  for (std::size_t i = 0; i < maps.size(); ++i) {
    if (!notes[i].alone.empty()) alone.push_back({{"name", names[i]}, {"reason", notes[i].alone}});
    if (notes[i].same_landmarks_as) {
      same.push_back({names[i], names[*notes[i].same_landmarks_as]});
    }
  }
  json folds = json::array();
  for (const SuspectedFold& f : suspected_folds(maps, edges, result)) {
    json fold_maps = json::array(), fold_edges = json::array();
    for (const std::size_t i : f.maps) fold_maps.push_back(names[i]);
    for (const std::size_t e : f.edges) {
      fold_edges.push_back({names[edges[e].source], names[edges[e].target]});
    }
    json S = json::array();
    const Mat4 M = f.S_world_moved.matrix();
    for (int r = 0; r < 4; ++r) S.push_back({M(r, 0), M(r, 1), M(r, 2), M(r, 3)});
    folds.push_back({{"component", result.maps[f.maps.front()].component},
                     {"maps", fold_maps},
                     {"edges", fold_edges},
                     {"motion_m", f.motion_m},
                     {"motion_deg", f.motion_deg},
                     {"S_world_moved", S}});
  }
  json rejected = json::array();
  std::size_t used = 0;
  for (std::size_t e = 0; e < edges.size(); ++e) {
    used += result.edges[e].used ? 1 : 0;
    if (result.edges[e].rejected) {
      rejected.push_back({names[edges[e].source], names[edges[e].target]});
    }
  }
  json check;  // null when the check did not run
  if (checked) {
    json parts = json::array();
    for (std::size_t c = 0; c < overlaps->contradicted_per_component.size(); ++c) {
      if (overlaps->contradicted_per_component[c] > 0) {
        parts.push_back(
            {{"component", c}, {"contradicted", overlaps->contradicted_per_component[c]}});
      }
    }
    check = {{"pairs_judged", overlaps->pairs.size()},
             {"contradicted", overlaps->num_contradicted()},
             {"reference_agreement", overlaps->reference_agreement},
             {"contradicted_components", parts}};
    write_output((dir / "overlap_check.csv").string(), [&](std::ostream& os) {
      os << "map_a,map_b,component,in_footprint,agreement,joined_by_edge,contradicted\n";
      os << std::setprecision(6);
      for (const OverlapPair& p : overlaps->pairs) {
        os << names[p.a] << "," << names[p.b] << "," << p.component << "," << p.in_footprint << ","
           << p.agreement << "," << p.joined_by_edge << "," << p.contradicted << "\n";
      }
    });
  }
  const json summary = {{"num_maps", maps.size()},
                        {"num_candidates", edges.size()},
                        {"num_edges_used", used},
                        {"rejected_edges", rejected},
                        {"num_components", result.num_components},
                        {"final_chi2", result.final_chi2},
                        {"edge_covariance_scale", result.edge_covariance_scale},
                        {"rounds", result.rounds},
                        {"converged", result.converged},
                        {"landmarks_left_out", left_out},
                        {"maps_alone", alone},
                        {"same_landmarks", same},
                        {"suspected_folds", folds},
                        {"overlap_check", check}};
  write_output((dir / "summary.json").string(),
               [&](std::ostream& os) { os << summary.dump(2) << "\n"; });
  for (std::size_t c = 0; c < result.num_components; ++c) {
    const std::string file = result.num_components == 1
                                 ? "merged_map.txt"
                                 : "merged_map_component" + std::to_string(c) + ".txt";
    write_map((dir / file).string(), merged[c]);
  }
}

std::string edge_file_path(const std::string& dir, const std::string& source_name,
                           const std::string& target_name) {
  auto safe = [](std::string s) {
    for (char& c : s) {
      if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.'))
        c = '_';
    }
    return s;
  };
  return (fs::path(dir) / (safe(source_name) + "__" + safe(target_name) + ".json")).string();
}

void write_edge_file(const std::string& path, const Edge& e) {
  const json j = {{"key", e.key},
                  {"source", e.source},
                  {"target", e.target},
                  {"T_target_source", matrix_json(e.T_target_source.matrix())},
                  {"covariance", matrix_json(e.covariance)},
                  {"covariance_valid", e.covariance_valid},
                  {"scale_free", e.scale_free},
                  {"scale", e.scale},
                  {"scale_sd", std::isfinite(e.scale_sd) ? json(e.scale_sd) : json()},
                  {"covariance_7x7", e.covariance_7x7 ? matrix_json(*e.covariance_7x7) : json()},
                  {"trusted", e.trusted},
                  {"trust_reason", e.trust_reason},
                  {"num_inliers", e.num_inliers},
                  {"inlier_ratio", e.inlier_ratio},
                  {"initialisation", e.initialisation},
                  {"summary", e.summary_json.empty() ? json() : json::parse(e.summary_json)}};
  write_output(path, [&](std::ostream& os) { os << j.dump() << "\n"; });
}

std::optional<Edge> read_edge_file(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return std::nullopt;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot read '" + path + "'");
  try {
    const json j = json::parse(in);
    Edge e;
    e.key = j.at("key").get<std::string>();
    e.source = j.at("source").get<std::size_t>();
    e.target = j.at("target").get<std::size_t>();
    e.T_target_source.matrix() = json_matrix(j.at("T_target_source"), 4, 4, "T_target_source");
    e.covariance = json_matrix(j.at("covariance"), 6, 6, "covariance");
    e.covariance_valid = j.at("covariance_valid").get<bool>();
    // Files of a rigid merge written before the scale: no scale fields (a rigid edge).
    if (j.contains("scale_free")) {
      e.scale_free = j.at("scale_free").get<bool>();
      e.scale = j.at("scale").get<double>();
      if (!(std::isfinite(e.scale) && e.scale > 0.0))
        throw ParseError(path, 0, "edge file: scale: not finite and > 0");
      if (!j.at("scale_sd").is_null()) e.scale_sd = j.at("scale_sd").get<double>();
      if (!j.at("covariance_7x7").is_null())
        e.covariance_7x7 = Mat7(json_matrix(j.at("covariance_7x7"), 7, 7, "covariance_7x7"));
    }
    e.trusted = j.at("trusted").get<bool>();
    e.trust_reason = j.at("trust_reason").get<std::string>();
    e.num_inliers = j.at("num_inliers").get<std::size_t>();
    e.inlier_ratio = j.at("inlier_ratio").get<double>();
    e.initialisation = j.at("initialisation").get<std::string>();
    if (j.contains("summary") && !j.at("summary").is_null())
      e.summary_json = j.at("summary").dump();
    return e;
  } catch (const json::exception& ex) {
    throw ParseError(path, 0, std::string("edge file: ") + ex.what());
  } catch (const InvalidArgument& ex) {
    throw ParseError(path, 0, std::string("edge file: ") + ex.what());
  }
}

}  // namespace lmalign
