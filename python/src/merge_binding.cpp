// The merge API of lmalign's Python module (docs/python.md, docs/merge.md): lmalign::merge's pure
// steps, bound one by one so that Python can run the edges anywhere (lmalign/_merge.py runs them
// on Dask), and run_merge() for the in-process path. Compiled only when lmalign::merge is built
// (Ceres found); module.cpp calls bind_merge() then.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "arrays.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/merge/candidates.hpp"
#include "lmalign/merge/edges.hpp"
#include "lmalign/merge/evaluation.hpp"
#include "lmalign/merge/manifest.hpp"
#include "lmalign/merge/merge.hpp"
#include "lmalign/merge/output.hpp"
#include "lmalign/merge/pose_graph.hpp"

namespace lmalign::python {

namespace {

/// A (R, C) matrix from `obj` (float64 array of exactly that shape), bits kept.
template <int R, int C>
Eigen::Matrix<double, R, C> matrix_from(const py::handle& obj, const char* name,
                                        const char* expected) {
  const Array a = as_array(obj, name, {R, C}, expected);
  Eigen::Matrix<double, R, C> m;
  for (int r = 0; r < R; ++r)
    for (int k = 0; k < C; ++k) m(r, k) = a.data()[C * r + k];
  return m;
}

/// A 4x4 transform as stored (pickles round-trip bit for bit; no rigidity re-check).
Isometry3 stored_transform(const py::handle& obj, const char* name) {
  Isometry3 T = Isometry3::Identity();
  T.matrix() = matrix_from<4, 4>(obj, name, "(4, 4)");
  return T;
}

/// A 6x6 covariance: finite, symmetric (1e-9 relative), positive definite.
Mat6 covariance_from(const py::handle& obj, const char* name) {
  const Mat6 c = matrix_from<6, 6>(obj, name, "(6, 6)");
  const double scale = std::max(1.0, c.cwiseAbs().maxCoeff());
  if (!c.allFinite() || (c - c.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale ||
      Eigen::LLT<Mat6>(c).info() != Eigen::Success) {
    throw InvalidArgument(std::string(name) +
                          ": expected a symmetric positive definite (6, 6) covariance");
  }
  return c;
}

// (N, 4, 4) similarities [sR t; 0 0 0 1] (rigid ones: s = 1); one line naming the entry.
std::vector<Similarity3> similarities_from(const py::handle& obj, const char* name, std::size_t n) {
  const Array a = as_array(obj, name, {-1, 4, 4}, "(N, 4, 4) with N the number of maps",
                           static_cast<py::ssize_t>(n));
  std::vector<Similarity3> out;
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    Mat4 M;
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) M(r, c) = a.at(i, r, c);
    }
    out.push_back(similarity_from_matrix(M, std::string(name) + "[" + std::to_string(i) + "]"));
  }
  return out;
}

py::object optional_transform_out(const std::optional<Isometry3>& T) {
  if (!T) return py::none();
  return matrix_out<4, 4>(T->matrix());
}

py::object prior_sigma_out(const std::optional<PriorSigma>& p) {
  if (!p) return py::none();
  return py::make_tuple(p->rotation_deg, p->translation_m);
}

std::optional<PriorSigma> prior_sigma_from(const py::handle& obj) {
  if (obj.is_none()) return std::nullopt;
  const std::vector<double> v = vector_from(obj, "prior_sigma", 2);
  PriorSigma p{v[0], v[1]};
  std::string why;
  if (!p.is_valid(&why)) throw InvalidArgument("prior_sigma: " + why);
  return p;
}

// A scale mode from Python ("auto", "free", "fixed"); InvalidArgument naming the option.
ScaleMode scale_mode_from(const std::string& scale) {
  if (scale != "auto" && scale != "free" && scale != "fixed") {
    throw InvalidArgument("scale: expected 'auto', 'free' or 'fixed', got '" + scale + "'");
  }
  return parse_scale_mode(scale);
}

// The edges' options from Python's arguments: scale is 'auto', 'free' or 'fixed' (EdgeOptions::
// scale; InvalidArgument naming the option otherwise).
EdgeOptions edge_options(std::optional<int> max_iterations, const std::string& scale = "auto") {
  EdgeOptions o;
  o.max_iterations = max_iterations;
  o.scale = scale_mode_from(scale);
  return o;
}

py::tuple edge_state(const Edge& e) {
  return py::make_tuple(
      e.source, e.target, matrix_out<4, 4>(e.T_target_source.matrix()),
      matrix_out<6, 6>(e.covariance), e.covariance_valid, e.trusted, e.trust_reason, e.num_inliers,
      e.inlier_ratio, e.initialisation, e.key, e.summary_json, e.scale_free, e.scale, e.scale_sd,
      e.covariance_7x7 ? py::object(matrix_out<7, 7>(*e.covariance_7x7)) : py::object(py::none()));
}

Edge edge_from_state(const py::tuple& t) {
  if (t.size() != 16) throw InvalidArgument("Edge: pickled state of a different version");
  Edge e;
  e.source = t[0].cast<std::size_t>();
  e.target = t[1].cast<std::size_t>();
  e.T_target_source = stored_transform(t[2], "Edge.T_target_source");
  e.covariance = matrix_from<6, 6>(t[3], "Edge.covariance", "(6, 6)");
  e.covariance_valid = t[4].cast<bool>();
  e.trusted = t[5].cast<bool>();
  e.trust_reason = t[6].cast<std::string>();
  e.num_inliers = t[7].cast<std::size_t>();
  e.inlier_ratio = t[8].cast<double>();
  e.initialisation = t[9].cast<std::string>();
  e.key = t[10].cast<std::string>();
  e.summary_json = t[11].cast<std::string>();
  e.scale_free = t[12].cast<bool>();
  e.scale = t[13].cast<double>();
  e.scale_sd = t[14].cast<double>();
  if (!t[15].is_none())
    e.covariance_7x7 = matrix_from<7, 7>(t[15], "Edge.covariance_7x7", "(7, 7)");
  return e;
}

py::tuple pair_state(const CandidatePair& c) {
  return py::make_tuple(c.source, c.target, c.rank, optional_transform_out(c.initial_guess),
                        prior_sigma_out(c.prior), c.source_metric, c.target_metric,
                        c.covariances_assumed, c.prior_complete_search, c.verified_matches,
                        c.complete_search);
}

CandidatePair pair_from_state(const py::tuple& t) {
  if (t.size() != 11) {
    throw InvalidArgument("CandidatePair: pickled state of a different version");
  }
  CandidatePair c;
  c.source = t[0].cast<std::size_t>();
  c.target = t[1].cast<std::size_t>();
  c.rank = t[2].cast<double>();
  if (!t[3].is_none()) c.initial_guess = stored_transform(t[3], "CandidatePair.initial_guess");
  if (!t[4].is_none()) {
    const auto v = t[4].cast<std::pair<double, double>>();
    c.prior = PriorSigma{v.first, v.second};
  }
  c.source_metric = t[5].cast<bool>();
  c.target_metric = t[6].cast<bool>();
  c.covariances_assumed = t[7].cast<bool>();
  c.prior_complete_search = t[8].cast<std::string>();
  c.verified_matches = t[9].cast<std::size_t>();
  c.complete_search = t[10].cast<std::string>();
  return c;
}

py::object prior_out(const std::optional<MapPrior>& p) {
  if (!p) return py::none();
  return py::cast(*p);
}

py::tuple entry_state(const ManifestEntry& e) {
  py::object prior = py::none();
  if (e.prior)
    prior = py::make_tuple(matrix_out<4, 4>(e.prior->T_world_map.matrix()),
                           matrix_out<6, 6>(e.prior->covariance));
  return py::make_tuple(e.name, e.path, map_format_name(e.format), e.session, prior);
}

ManifestEntry entry_from_state(const py::tuple& t) {
  if (t.size() != 5) throw InvalidArgument("ManifestEntry: pickled state of a different version");
  ManifestEntry e;
  e.name = t[0].cast<std::string>();
  e.path = t[1].cast<std::string>();
  e.format = parse_map_format(t[2].cast<std::string>());
  e.session = t[3].cast<std::string>();
  if (!t[4].is_none()) {
    const py::tuple p = t[4].cast<py::tuple>();
    MapPrior prior;
    prior.T_world_map = stored_transform(p[0], "ManifestEntry.prior.T_world_map");
    prior.covariance = matrix_from<6, 6>(p[1], "ManifestEntry.prior.covariance", "(6, 6)");
    e.prior = prior;
  }
  return e;
}

}  // namespace

namespace {

// The merge API: manifest.
void bind_manifest(py::module_& m) {
  py::class_<MapPrior>(m, "MapPrior",
                       "A prior pose of a map in the common world frame: T_world_map (4, 4), "
                       "p_world = T_world_map @ p_map, metres, and its (6, 6) covariance of a left "
                       "perturbation in the world frame, xi = (rho m, phi rad): rows 0-2 "
                       "translation (m^2), 3-5 rotation (rad^2) (merge/manifest.hpp).")
      .def(py::init([](const py::handle& T, const py::handle& covariance) {
             MapPrior p;
             p.T_world_map = transform_from(T, "T_world_map");
             p.covariance = covariance_from(covariance, "covariance");
             check_prior_in_supported_range(p, "MapPrior");
             return p;
           }),
           py::arg("T_world_map"), py::arg("covariance"),
           "Raises InvalidArgument if T_world_map is not rigid, the covariance is not "
           "symmetric positive definite, or the translation or a standard deviation is beyond "
           "the supported range (1e15 m; docs/robustness.md), ValueError on a wrong shape.")
      .def_property_readonly(
          "T_world_map", [](const MapPrior& p) { return matrix_out<4, 4>(p.T_world_map.matrix()); },
          "(4, 4) float64, metres.")
      .def_readonly("scale", &MapPrior::scale,
                    "World units per map unit (a similarity prior in the manifest; 1 otherwise): "
                    "holds the scale of a map without metric scale.")
      .def_property_readonly(
          "covariance", [](const MapPrior& p) { return matrix_out<6, 6>(p.covariance); },
          "(6, 6) float64: (rho m, phi rad), left perturbation, world frame.");

  py::class_<ManifestEntry>(m, "ManifestEntry", "One mini-map of a merge manifest.")
      .def_readonly("name", &ManifestEntry::name, "Unique name.")
      .def_readonly("path", &ManifestEntry::path, "Map file, resolved against the manifest.")
      .def_property_readonly(
          "format", [](const ManifestEntry& e) { return map_format_name(e.format); },
          "Map format name ('auto', 'lmalign', 'colmap-text', ...).")
      .def_readonly("session", &ManifestEntry::session, "'' = none.")
      .def_property_readonly(
          "prior", [](const ManifestEntry& e) { return prior_out(e.prior); }, "MapPrior or None.")
      .def(py::pickle([](const ManifestEntry& e) { return entry_state(e); },
                      [](const py::tuple& t) { return entry_from_state(t); }));

  py::class_<Manifest>(m, "Manifest", "A merge manifest (docs/merge.md, 'Manifest').")
      .def_readonly("file", &Manifest::file, "Where it was read from.")
      .def_readonly("maps", &Manifest::maps, "List of ManifestEntry, in manifest order.")
      .def_property_readonly(
          "names",
          [](const Manifest& mf) {
            std::vector<std::string> v;
            for (const auto& e : mf.maps) v.push_back(e.name);
            return v;
          },
          "Map names, in manifest order.")
      .def_property_readonly(
          "priors",
          [](const Manifest& mf) {
            py::list l;
            for (const auto& e : mf.maps) l.append(prior_out(e.prior));
            return l;
          },
          "MapPrior or None per map, in manifest order.");

  m.def(
      "read_manifest",
      [](const std::filesystem::path& path) { return read_manifest(path.string()); },
      py::arg("path"),
      "Reads a merge manifest (YAML, docs/merge.md): maps with name, path (relative to the "
      "manifest's folder), format, session, optional prior. Raises ParseError (file, line, "
      "field: empty manifest, duplicate name, prior not rigid, covariance not symmetric positive "
      "definite, unknown key), IoError.");
  m.def(
      "load_manifest_maps",
      [](const Manifest& manifest) {
        py::gil_scoped_release release;
        return load_manifest_maps(manifest);
      },
      py::arg("manifest"),
      "Reads every map of the manifest (its format, default options), in order. Raises "
      "ParseError / IoError / InvalidArgument naming the map and its file.");
  m.def(
      "read_manifest_map",
      [](const ManifestEntry& entry) {
        Manifest one;
        one.maps.push_back(entry);
        py::gil_scoped_release release;
        return std::move(load_manifest_maps(one).front());
      },
      py::arg("entry"),
      "Reads one map of a manifest exactly as load_manifest_maps() does (what a Dask task "
      "does). Raises as load_manifest_maps().");
}

// The merge API: candidates.
void bind_candidates(py::module_& m) {
  py::class_<CandidatePair>(m, "CandidatePair",
                            "A pair of maps to align (merge/candidates.hpp): the edge estimates "
                            "T_target_source, p_target = T @ p_source. Picklable.")
      .def(py::init([](std::size_t source, std::size_t target, const py::handle& initial_guess,
                       const py::handle& prior_sigma) {
             if (source == target) throw InvalidArgument("CandidatePair: source == target");
             CandidatePair c;
             c.source = source;
             c.target = target;
             if (!initial_guess.is_none())
               c.initial_guess = transform_from(initial_guess, "initial_guess");
             c.prior = prior_sigma_from(prior_sigma);
             return c;
           }),
           py::arg("source"), py::arg("target"), py::arg("initial_guess") = py::none(),
           py::arg("prior_sigma") = py::none(),
           "source, target: map indices. initial_guess: (4, 4) rigid T_target_source or None. "
           "prior_sigma: (rot_deg, trans_m) of the guess, or None.")
      .def_readonly("source", &CandidatePair::source, "Map index.")
      .def_readonly("target", &CandidatePair::target, "Map index.")
      .def_readonly("rank", &CandidatePair::rank,
                    "Rank key, smaller = more promising (0 for 'every pair').")
      .def_property_readonly(
          "initial_guess",
          [](const CandidatePair& c) { return optional_transform_out(c.initial_guess); },
          "(4, 4) T_target_source from the two priors, or None.")
      .def_property_readonly(
          "prior_sigma", [](const CandidatePair& c) { return prior_sigma_out(c.prior); },
          "(rot_deg, trans_m) of the relative prior, or None.")
      .def_readonly("source_metric", &CandidatePair::source_metric,
                    "Whether the source map's lengths are metres (its header); with "
                    "scale='auto' a pair with a map that is not metric is aligned as a "
                    "similarity.")
      .def_readonly("target_metric", &CandidatePair::target_metric,
                    "Whether the target map's lengths are metres (its header).")
      .def_readonly("prior_complete_search", &CandidatePair::prior_complete_search,
                    "With a prior: the edge's init.prior_complete_search ('rescue' for merges "
                    "of at most 12 maps: an untrusted prior-bounded alignment also gets the "
                    "complete search; 'check' beyond: the maps' first pass alone rescues it).")
      .def_readonly("complete_search", &CandidatePair::complete_search,
                    "Without a prior: the edge's search.complete_search ('rescue' for merges of "
                    "at most 12 maps; 'check' beyond: the complete search only checks a trusted "
                    "first-pass answer; a pair whose first pass finds no correspondence pose "
                    "gets no answer).")
      .def_readonly("verified_matches", &CandidatePair::verified_matches,
                    "Retrieved pairs (no priors, more than all_pairs_max_maps maps): the matches "
                    "in the correspondence search's largest clique between the two maps' "
                    "sketches (0: none found, or not verified).")
      .def(py::pickle([](const CandidatePair& c) { return pair_state(c); },
                      [](const py::tuple& t) { return pair_from_state(t); }))
      .def("__repr__", [](const CandidatePair& c) {
        return "<lmalign.CandidatePair " + std::to_string(c.source) + " -> " +
               std::to_string(c.target) + ">";
      });

  m.def(
      "plan_candidates",
      [](const std::vector<Map>& maps,
         const std::optional<std::vector<std::optional<MapPrior>>>& priors_in,
         std::size_t max_pairs, std::size_t keep_per_map, std::size_t all_pairs_max_maps,
         std::size_t verify_per_map) {
        std::vector<std::optional<MapPrior>> priors =
            priors_in.value_or(std::vector<std::optional<MapPrior>>(maps.size()));
        CandidateOptions o;
        o.max_pairs = max_pairs;
        o.keep_per_map = keep_per_map;
        o.all_pairs_max_maps = all_pairs_max_maps;
        o.verify_per_map = verify_per_map;
        std::string why;
        if (!o.is_valid(&why)) throw InvalidArgument("plan_candidates: " + why);
        py::gil_scoped_release release;
        std::vector<MapSummary> summaries;
        for (std::size_t i = 0; i < maps.size(); ++i)
          summaries.push_back(summarise_map(maps[i], o, i + 1));  // run_merge()'s seeds
        return plan_candidates(summaries, priors, o);
      },
      py::arg("maps"), py::arg("priors") = py::none(), py::kw_only(), py::arg("max_pairs") = 0,
      py::arg("keep_per_map") = CandidateOptions{}.keep_per_map,
      py::arg("all_pairs_max_maps") = CandidateOptions{}.all_pairs_max_maps,
      py::arg("verify_per_map") = CandidateOptions{}.verify_per_map,
      "The candidate pairs of `maps` (docs/merge.md, 'Candidates'), as `lmalign merge` plans "
      "them: with priors on both maps, pairs whose prior-placed extents overlap; else every "
      "pair up to all_pairs_max_maps maps, more maps keep their keep_per_map most similar "
      "(map retrieval: a bag of words over the landmarks' yaw-invariant descriptors; each map's "
      "verify_per_map most similar verified by the correspondence search's largest clique, "
      "the keep_per_map best verified kept; 0 = no verification); at most "
      "max_pairs (0 = no limit), best first. priors: "
      "one MapPrior or None per map (default none). Deterministic. Raises InvalidArgument.");
}

// The merge API: edges.
void bind_edges(py::module_& m) {
  py::class_<Edge>(m, "Edge",
                   "One aligned pair (merge/edges.hpp). Picklable (bit for bit), so that it can "
                   "come back from a Dask worker.")
      .def_readonly("source", &Edge::source, "Map index.")
      .def_readonly("target", &Edge::target, "Map index.")
      .def_property_readonly(
          "T_target_source",
          [](const Edge& e) { return matrix_out<4, 4>(e.T_target_source.matrix()); },
          "(4, 4) float64: p_target = T @ p_source, metres.")
      .def_property_readonly(
          "covariance", [](const Edge& e) { return matrix_out<6, 6>(e.covariance); },
          "(6, 6) float64: xi = (rho m, phi rad), left perturbation in the target frame.")
      .def_readonly("covariance_valid", &Edge::covariance_valid)
      .def_readonly("scale_free", &Edge::scale_free,
                    "Whether the alignment estimated the scale (Sim(3)).")
      .def_readonly("scale", &Edge::scale,
                    "Target units per source unit: p_target = scale * R @ p_source + t (1: rigid).")
      .def_readonly("scale_sd", &Edge::scale_sd, "Its standard deviation (NaN when fixed).")
      .def_readonly("trusted", &Edge::trusted, "The strategy's trust verdict.")
      .def_readonly("trust_reason", &Edge::trust_reason, "'ok', or why not trusted.")
      .def_readonly("num_inliers", &Edge::num_inliers)
      .def_readonly("inlier_ratio", &Edge::inlier_ratio)
      .def_readonly("initialisation", &Edge::initialisation,
                    "The initialiser's: 'global', 'prior', 'given', ...")
      .def_readonly("summary_json", &Edge::summary_json,
                    "The alignment's summary as JSON text (lmalign.AlignmentResult.to_json()'s "
                    "serialisation); '' for an edge read from a file written without it.")
      .def_readonly("key", &Edge::key, "edge_key() of its inputs ('' if not set).")
      .def(
          "with_key",
          [](const Edge& e, const std::string& key) {
            Edge out = e;
            out.key = key;
            return out;
          },
          py::arg("key"), "A copy with `key` set (the resume cache's key).")
      .def(py::pickle([](const Edge& e) { return edge_state(e); },
                      [](const py::tuple& t) { return edge_from_state(t); }))
      .def(
          "__eq__",
          [](const Edge& a, const Edge& b) {
            return a.source == b.source && a.target == b.target &&
                   a.T_target_source.matrix() == b.T_target_source.matrix() &&
                   a.covariance == b.covariance && a.covariance_valid == b.covariance_valid &&
                   a.trusted == b.trusted && a.trust_reason == b.trust_reason &&
                   a.num_inliers == b.num_inliers && a.inlier_ratio == b.inlier_ratio &&
                   a.initialisation == b.initialisation && a.key == b.key &&
                   a.scale_free == b.scale_free && a.scale == b.scale &&
                   (a.scale_sd == b.scale_sd ||
                    (std::isnan(a.scale_sd) && std::isnan(b.scale_sd))) &&
                   a.covariance_7x7 == b.covariance_7x7;
          },
          "Every field equal, bit for bit.")
      .def("__repr__", [](const Edge& e) {
        return "<lmalign.Edge " + std::to_string(e.source) + " -> " + std::to_string(e.target) +
               (e.trusted ? ", trusted>" : ", untrusted: " + e.trust_reason + ">");
      });

  m.def(
      "align_edge",
      [](const Map& source, const Map& target, const CandidatePair& pair,
         std::optional<int> max_iterations, const std::string& scale) {
        with_frame_index(source);
        with_frame_index(target);
        const EdgeOptions o = edge_options(max_iterations, scale);
        py::gil_scoped_release release;
        return align_edge(source, target, pair, o);
      },
      py::arg("source"), py::arg("target"), py::arg("pair"), py::arg("max_iterations") = py::none(),
      py::kw_only(), py::arg("scale") = "auto",
      "Aligns the map `source` (pair.source) onto `target` (pair.target) with the recommended "
      "strategy (lmalign.RECOMMENDED_STRATEGY), the pair's initial guess and prior sigma bounding "
      "its search; returns an Edge (key ''). scale: 'auto' (a similarity, Sim(3), when either "
      "map has no metric scale: pair.source_metric / pair.target_metric, from the maps' "
      "headers), 'free' (always a similarity) or 'fixed' (rigid, Edge.scale 1), as `lmalign "
      "merge --scale`. Pure and deterministic (any thread count, any machine with the same "
      "build). The GIL is released. Raises InvalidArgument (also for another scale).");
  m.def(
      "map_fingerprint", [](const Map& map) { return map_fingerprint(map); }, py::arg("map"),
      "16 hex digits: FNV-1a of the map's landmark positions and covariances (bit patterns).");
  m.def(
      "edge_key",
      [](const std::string& source_fingerprint, const std::string& target_fingerprint,
         const CandidatePair& pair, std::optional<int> max_iterations, const std::string& scale) {
        return edge_key(source_fingerprint, target_fingerprint, pair,
                        edge_options(max_iterations, scale));
      },
      py::arg("source_fingerprint"), py::arg("target_fingerprint"), py::arg("pair"),
      py::arg("max_iterations") = py::none(), py::kw_only(), py::arg("scale") = "auto",
      "The resume cache key of an edge (both maps' fingerprints, the pair, the options, the "
      "scale mode as align_edge's). Raises InvalidArgument.");
  m.def(
      "edge_file_path",
      [](const std::filesystem::path& dir, const std::string& s, const std::string& t) {
        return edge_file_path(dir.string(), s, t);
      },
      py::arg("dir"), py::arg("source_name"), py::arg("target_name"),
      "<dir>/<source_name>__<target_name>.json (unsafe characters replaced by '_').");
  m.def(
      "write_edge_file",
      [](const std::filesystem::path& path, const Edge& e) { write_edge_file(path.string(), e); },
      py::arg("path"), py::arg("edge"),
      "Writes one edge atomically (JSON, doubles round-trip exactly). Raises IoError.");
  m.def(
      "read_edge_file",
      [](const std::filesystem::path& path) { return read_edge_file(path.string()); },
      py::arg("path"), "The edge in the file, or None if it does not exist. Raises ParseError.");
}

// The merge API: pose graph.
void bind_pose_graph(py::module_& m) {
  py::class_<MapPose>(m, "MapPose", "One map's place after the pose graph.")
      .def_property_readonly(
          "T_world_map", [](const MapPose& p) { return matrix_out<4, 4>(p.T_world_map.matrix()); },
          "(4, 4) float64: p_world = T @ p_map, metres (the world of its component).")
      .def_property_readonly(
          "covariance", [](const MapPose& p) { return matrix_out<6, 6>(p.covariance); },
          "(6, 6) float64 marginal: (rho m, phi rad), left perturbation, world frame; zero for a "
          "gauge map.")
      .def_readonly("covariance_valid", &MapPose::covariance_valid)
      .def_readonly("component", &MapPose::component, "0-based connected component.")
      .def_readonly("is_gauge", &MapPose::is_gauge, "Fixed at identity (component without priors).")
      .def_readonly("scale", &MapPose::scale,
                    "World units per map unit: p_world = scale * R @ p_map + t, (R, t) = "
                    "T_world_map; 1 for a map with metric scale.")
      .def_readonly("scale_sd", &MapPose::scale_sd, "Its standard deviation (0 when held).")
      .def_readonly("scale_free", &MapPose::scale_free,
                    "Estimated (a map without metric scale that is not held).");
  py::class_<EdgeReport>(m, "EdgeReport", "One edge's fate in the pose graph.")
      .def_readonly("used", &EdgeReport::used, "Trusted with a usable covariance: in the graph.")
      .def_readonly("rejected", &EdgeReport::rejected, "Used, then rejected after optimisation.")
      .def_readonly("chi2", &EdgeReport::chi2, "Whitened chi^2 at the final poses (0 if unused).")
      .def_readonly("skip_reason", &EdgeReport::skip_reason, "Why not used ('' if used).")
      .def_readonly("reject_reason", &EdgeReport::reject_reason,
                    "Why rejected, when by the cycle check ('' otherwise).");
  py::class_<MergeResult>(m, "PoseGraphResult",
                          "solve_pose_graph()'s result (C++ lmalign::MergeResult).")
      .def_readonly("maps", &MergeResult::maps, "List of MapPose, one per map.")
      .def_readonly("edges", &MergeResult::edges, "List of EdgeReport, one per edge given.")
      .def_readonly("num_components", &MergeResult::num_components)
      .def_readonly("final_chi2", &MergeResult::final_chi2, "Sum over kept edges and priors.")
      .def_readonly("edge_covariance_scale", &MergeResult::edge_covariance_scale)
      .def_readonly("rounds", &MergeResult::rounds)
      .def_readonly("converged", &MergeResult::converged);

  m.def(
      "solve_pose_graph",
      [](std::size_t num_maps, const std::optional<std::vector<std::optional<MapPrior>>>& priors,
         const std::vector<Edge>& edges, const std::optional<std::vector<Map>>& maps,
         const std::string& scale, const std::string& overlap_check) {
        const auto p = priors.value_or(std::vector<std::optional<MapPrior>>(num_maps));
        const ScaleMode mode = scale_mode_from(scale);
        MergeOptions o;
        set_overlap_check_mode(overlap_check, &o);
        if (maps) {
          if (maps->size() != num_maps) throw InvalidArgument("maps: one per map expected");
          o.edges.scale = mode;
          py::gil_scoped_release release;
          return solve_and_check(*maps, p, edges, o).result;
        }
        py::gil_scoped_release release;
        return solve_pose_graph(num_maps, p, edges, {}, {});
      },
      py::arg("num_maps"), py::arg("priors"), py::arg("edges"), py::kw_only(),
      py::arg("maps") = py::none(), py::arg("scale") = "auto", py::arg("overlap_check") = "repair",
      "The robust SE(3) pose graph of the trusted edges and the priors (Ceres; docs/merge.md, "
      "'Pose graph'), as `lmalign merge` solves it; one machine, the GIL released. priors: one "
      "MapPrior or None per map (None: no priors). maps: the maps (their headers say which have "
      "no metric scale; those get a scale of their own, Sim(3), unless scale='fixed'); None: "
      "every map metric. With maps, the merged map is also checked against itself and a part that "
      "contradicts itself repaired (docs/merge.md, 'Maps the graph puts on top of each other'), "
      "as the merge does; overlap_check: 'repair' (that), 'check' (no repair) or 'off' (neither), "
      "as `lmalign merge --overlap-check`. Returns a PoseGraphResult. Raises "
      "InvalidArgument (sizes, an edge naming a map out of range).");
  py::class_<OverlapCheck>(m, "OverlapCheck",
                           "check_overlaps()'s result (C++ lmalign::OverlapCheck; docs/merge.md, "
                           "'Maps the graph puts on top of each other').")
      .def_readonly("reference_agreement", &OverlapCheck::reference_agreement,
                    "Median agreement (0-1) of the pairs a kept edge joins.")
      .def_readonly("contradicted_per_map", &OverlapCheck::contradicted_per_map)
      .def_readonly("contradicted_per_component", &OverlapCheck::contradicted_per_component)
      .def_property_readonly(
          "pairs",
          [](const OverlapCheck& c) {
            py::list out;
            for (const OverlapPair& p : c.pairs) {
              out.append(py::make_tuple(p.a, p.b, p.component, p.in_footprint, p.agreement,
                                        p.joined_by_edge, p.contradicted));
            }
            return out;
          },
          "Judged pairs: (a, b, component, in_footprint, agreement, joined_by_edge, "
          "contradicted), a < b map indices.")
      .def("num_contradicted", &OverlapCheck::num_contradicted);
  m.def(
      "check_overlaps",
      [](const std::vector<Map>& maps, const MergeResult& result, const std::vector<Edge>& edges,
         int threads) {
        OverlapCheckOptions o;
        o.threads = threads;
        py::gil_scoped_release release;
        return check_overlaps(maps, result, edges, o);
      },
      py::arg("maps"), py::arg("result"), py::arg("edges"), py::kw_only(), py::arg("threads") = 0,
      "The merged map checked against itself: every pair of maps of one part that the poses "
      "make overlap, compared landmark by landmark (docs/merge.md). Deterministic for any thread "
      "count. Raises InvalidArgument (sizes).");
  m.def(
      "write_merge_outputs",
      [](const std::filesystem::path& out_dir, const std::vector<std::string>& names,
         const std::vector<std::string>& sessions, const std::vector<Map>& maps,
         const std::vector<Edge>& edges, const MergeResult& result, bool fuse_landmarks,
         const std::optional<OverlapCheck>& overlaps) {
        for (const Map& map : maps) with_frame_index(map);
        MergeOutputOptions o;
        o.fuse_landmarks = fuse_landmarks;
        py::gil_scoped_release release;
        write_merge_outputs(out_dir.string(), names, sessions, maps, edges, result, o,
                            overlaps ? &*overlaps : nullptr);
      },
      py::arg("out_dir"), py::arg("names"), py::arg("sessions"), py::arg("maps"), py::arg("edges"),
      py::arg("result"), py::arg("fuse_landmarks") = true, py::arg("overlaps") = py::none(),
      "Writes poses.yaml, poses.json, edges.csv, summary.json and the merged map(s) into out_dir "
      "(created), each atomically, as `lmalign merge`; with overlaps (check_overlaps()), also "
      "overlap_check.csv and the check's fields. Raises IoError, InvalidArgument.");
}

// The merge API: ground truth.
void bind_ground_truth(py::module_& m) {
  m.def(
      "read_ground_truth",
      [](const std::filesystem::path& path, const std::vector<std::string>& names) {
        const std::vector<Similarity3> t = read_ground_truth_similarities(path.string(), names);
        const auto n = static_cast<py::ssize_t>(t.size());
        py::array_t<double> out({n, py::ssize_t(4), py::ssize_t(4)});
        for (py::ssize_t i = 0; i < n; ++i) {
          const Mat4 M = t[static_cast<std::size_t>(i)].matrix();
          for (int r = 0; r < 4; ++r) {
            for (int c = 0; c < 4; ++c) out.mutable_at(i, r, c) = M(r, c);
          }
        }
        return out;
      },
      py::arg("path"), py::arg("names"),
      "(N, 4, 4) S_world_map_true per name from YAML 'maps: {name: 4x4 rows}' (rigid, or a "
      "similarity [sR t; 0 0 0 1] for a map without metric scale). Raises ParseError.");
  m.def(
      "evaluate_merge",
      [](const MergeResult& result, const std::vector<Edge>& edges, const py::handle& truth,
         double rotation_deg, double translation_m) {
        const std::vector<Similarity3> t = similarities_from(truth, "truth", result.maps.size());
        GroundTruthThresholds th;
        th.rotation_deg = rotation_deg;
        th.translation_m = translation_m;
        const MergeEvaluation ev = evaluate_merge(result, edges, t, th);
        const auto n = static_cast<py::ssize_t>(ev.maps.size());
        py::array_t<double> rot(n), trans(n), scale_error(n);
        py::array_t<bool> within(n), placed(n), connected(n);
        for (py::ssize_t i = 0; i < n; ++i) {
          rot.mutable_data()[i] = ev.maps[i].rotation_deg;
          trans.mutable_data()[i] = ev.maps[i].translation_m;
          scale_error.mutable_data()[i] = ev.maps[i].scale_error;
          within.mutable_data()[i] = ev.maps[i].within;
          placed.mutable_data()[i] = ev.maps[i].placed;
          connected.mutable_data()[i] = ev.maps[i].connected;
        }
        py::dict d;
        d["rotation_deg"] = rot;
        d["translation_m"] = trans;
        d["scale_error"] = scale_error;
        d["max_scale_error"] = ev.max_scale_error;
        d["max_pair_scale_error"] = ev.max_pair_scale_error;
        d["within"] = within;
        d["placed"] = placed;
        d["connected"] = connected;
        d["num_parts"] = ev.num_parts;
        d["num_edge_parts"] = ev.num_edge_parts;
        d["largest_part"] = ev.largest_part;
        d["num_placed"] = ev.placed;
        d["fraction_within"] = ev.fraction_within;
        d["pair_fraction_within"] = ev.pair_fraction_within;
        d["pairs_within"] = ev.pairs_within;
        d["max_rotation_deg"] = ev.max_rotation_deg;
        d["max_translation_m"] = ev.max_translation_m;
        d["edge_precision"] = ev.edge_precision;
        d["edge_recall"] = ev.edge_recall;
        d["kept_edges"] = ev.kept_edges;
        d["false_kept_edges"] = ev.false_kept_edges;
        d["edge_true"] = ev.edge_true;
        return d;
      },
      py::arg("result"), py::arg("edges"), py::arg("truth"), py::arg("rotation_deg") = 5.0,
      py::arg("translation_m") = 0.10,
      "Ground-truth evaluation (docs/merge.md): each part's frame fitted to the truth, then per "
      "map the rotation (deg) and translation (m) error (NaN: alone in a part without priors). "
      "A map is placed when in a part held by priors or, without priors, in the largest part of "
      ">= 2 maps. truth: (N, 4, 4) T_world_map_true. Returns a dict: rotation_deg (N,), "
      "translation_m (N,), within (N,) bool (placed and within the thresholds), placed (N,), "
      "connected (N,) (a kept edge joins it to another map), num_parts (the graph's components), "
      "num_edge_parts (those of the kept edges alone), largest_part, num_placed, "
      "fraction_within (of all maps), pair_fraction_within (of all pairs, relative poses; NaN "
      "above 2000 maps), pairs_within, max_rotation_deg, max_translation_m, edge_precision, "
      "edge_recall, kept_edges, false_kept_edges, edge_true (list of bool per edge). Raises "
      "InvalidArgument.");
}

// The merge API: in process.
void bind_in_process(py::module_& m) {
  m.def(
      "_run_merge",
      [](const std::vector<Map>& maps, const std::vector<std::string>& names,
         const std::vector<std::optional<MapPrior>>& priors, std::size_t max_pairs, int threads,
         const std::string& edge_cache_dir, const std::string& scale,
         const std::string& overlap_check) {
        for (const Map& map : maps) with_frame_index(map);
        MergeOptions o;
        o.edges.scale = scale_mode_from(scale);
        set_overlap_check_mode(overlap_check, &o);
        o.candidates.max_pairs = max_pairs;
        o.threads = threads;
        o.edge_cache_dir = edge_cache_dir;
        MergeRun run;
        {
          py::gil_scoped_release release;
          run = run_merge(maps, names, priors, o);
        }
        return py::make_tuple(run.candidates, run.edges, run.result, run.edges_reused,
                              run.seconds_edges, run.seconds_graph);
      },
      py::arg("maps"), py::arg("names"), py::arg("priors"), py::arg("max_pairs"),
      py::arg("threads"), py::arg("edge_cache_dir"), py::arg("scale") = "auto",
      py::arg("overlap_check") = "repair");
}

}  // namespace

void bind_merge(py::module_& m) {
  bind_manifest(m);
  bind_candidates(m);
  bind_edges(m);
  bind_pose_graph(m);
  bind_ground_truth(m);
  bind_in_process(m);
}

}  // namespace lmalign::python
