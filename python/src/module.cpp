// lmalign's Python module (_lmalign, wrapped by python/lmalign/__init__.py; docs/python.md).
// Arrays in and out are float64, C-contiguous; other real dtypes or layouts are converted once,
// anything else is refused with ValueError naming the argument and the expected shape.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "align_binding.hpp"
#include "arrays.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/eval/trajectory.hpp"
#include "lmalign/experiment/cases.hpp"
#include "lmalign/experiment/config.hpp"
#include "lmalign/experiment/report.hpp"
#include "lmalign/experiment/runner.hpp"
#include "lmalign/io/output_file.hpp"
#include "lmalign/map/formats/formats.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/map/split.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/stages/data_scales.hpp"

namespace py = pybind11;
using namespace lmalign;
using namespace lmalign::python;

#ifdef LMALIGN_HAVE_MERGE
namespace lmalign::python {
/// The merge API (merge_binding.cpp): only when lmalign::merge is built (Ceres).
void bind_merge(py::module_& m);
}  // namespace lmalign::python
#endif

namespace {

// ---------------------------------------------------------------- map I/O

/// The one place that reads a map file (a dispatching reader for more formats goes here).
Map read_map_file(const std::filesystem::path& path, std::size_t min_observations,
                  const std::string& format,
                  const std::optional<std::array<long long, 2>>& image_size) {
  MapReadOptions o;
  o.min_observations = min_observations;
  AnyMapReadOptions any(o, parse_map_format(format));
  any.image_size_px = image_size;
  py::gil_scoped_release release;
  return read_any_map(path.string(), any);
}

template <typename F>
py::array_t<std::int64_t> per_landmark(const Map& m, F f) {
  py::array_t<std::int64_t> a(static_cast<py::ssize_t>(m.landmarks.size()));
  for (std::size_t i = 0; i < m.landmarks.size(); ++i) a.mutable_data()[i] = f(m.landmarks[i]);
  return a;
}

// ---------------------------------------------------------------- trajectories

Trajectory trajectory_from(const py::handle& obj, const char* name) {
  if (py::isinstance<py::str>(obj) || py::hasattr(obj, "__fspath__")) {
    return read_tum_trajectory(py::str(py::module_::import("os").attr("fspath")(obj)));
  }
  if (!py::isinstance<py::tuple>(obj) || py::len(obj) != 2) {
    throw py::value_error(std::string(name) +
                          ": expected a TUM trajectory file path or a tuple (timestamps_s (N,), "
                          "T_world_camera (N, 4, 4))");
  }
  const py::tuple t = obj.cast<py::tuple>();
  const Array stamps = as_array(t[0], name, {-1}, "(N,) timestamps in seconds");
  const Array poses = as_array(t[1], name, {-1, 4, 4}, "(N, 4, 4) T_world_camera with N timestamps",
                               stamps.shape(0));
  Trajectory out(static_cast<std::size_t>(stamps.shape(0)));
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i].timestamp_s = stamps.data()[i];
    const Array one = Array::ensure(poses[py::int_(i)]);
    out[i].T_world_camera = transform_from(one, name);
  }
  std::sort(out.begin(), out.end(), [](const StampedPose& a, const StampedPose& b) {
    return a.timestamp_s < b.timestamp_s;
  });
  return out;
}

py::dict stats_out(const ErrorStats& s) {
  py::dict d;
  d["count"] = s.count;
  d["rmse"] = s.rmse;
  d["mean"] = s.mean;
  d["median"] = s.median;
  d["std"] = s.std_dev;
  d["min"] = s.min;
  d["max"] = s.max;
  return d;
}

// ---------------------------------------------------------------- exceptions

PyObject* g_error = nullptr;
PyObject* g_invalid_argument = nullptr;
PyObject* g_io_error = nullptr;
PyObject* g_parse_error = nullptr;

PyObject* new_exception(py::module_& m, const char* name, PyObject* bases, const char* doc) {
  const std::string full = std::string("lmalign.") + name;
  PyObject* type = PyErr_NewExceptionWithDoc(full.c_str(), doc, bases, nullptr);
  if (type == nullptr) throw py::error_already_set();
  m.add_object(name, py::handle(type));
  return type;
}

void raise(PyObject* type, const std::string& message) { PyErr_SetString(type, message.c_str()); }

// ---------------------------------------------------------------- the module, by area

void bind_exceptions(py::module_& m) {
  g_error = new_exception(m, "Error", PyExc_Exception,
                          "Base class of every error lmalign raises on purpose.");
  g_invalid_argument = new_exception(
      m, "InvalidArgument",
      py::make_tuple(py::handle(g_error), py::handle(PyExc_ValueError)).release().ptr(),
      "A bad argument or option value (also a ValueError); the message names it.");
  g_io_error = new_exception(
      m, "IoError", py::make_tuple(py::handle(g_error), py::handle(PyExc_OSError)).release().ptr(),
      "A file could not be opened, read or written (also an OSError); the message names the "
      "path and the reason.");
  g_parse_error = new_exception(
      m, "ParseError",
      py::make_tuple(py::handle(g_error), py::handle(PyExc_ValueError)).release().ptr(),
      "A malformed input file (also a ValueError). Attributes: file (str), line (int, 1-based; "
      "0 = the file as a whole), detail (the message without 'file:line: ').");
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const ParseError& e) {
      py::object exc = py::reinterpret_borrow<py::object>(g_parse_error)(e.what());
      exc.attr("file") = e.file();
      exc.attr("line") = e.line();
      exc.attr("detail") = e.detail();
      PyErr_SetObject(g_parse_error, exc.ptr());
    } catch (const InvalidArgument& e) {
      raise(g_invalid_argument, e.what());
    } catch (const IoError& e) {
      raise(g_io_error, e.what());
    } catch (const Error& e) {
      raise(g_error, e.what());
    }
  });
}

void bind_map(py::module_& m) {
  py::class_<Map>(m, "Map",
                  "A landmark map: frames (keyframe poses) and landmarks, in the map's world "
                  "frame; metres, m^2. Array properties are copies (float64, C-contiguous).")
      .def_property_readonly(
          "positions", [](const Map& map) { return points_out(map.positions()); },
          "(N, 3) float64: landmark positions p_world, metres.")
      .def_property_readonly(
          "covariances", [](const Map& map) { return covariances_out(map.covariances_m2()); },
          "(N, 3, 3) float64: landmark position covariances in the world frame, m^2.")
      .def_property_readonly(
          "observation_counts",
          [](const Map& map) {
            return per_landmark(map, [](const Landmark& l) {
              return static_cast<std::int64_t>(l.num_observations());
            });
          },
          "(N,) int64: number of observations of each landmark.")
      .def_property_readonly(
          "scale", [](const Map& map) { return map_scale_name(map.header.scale); },
          "'metric' (lengths in metres: RGB-D and stereo SLAM, our format by default), "
          "'arbitrary' (one unknown scale: COLMAP, Bundler, monocular stella_vslam) or 'unknown' "
          "(a point cloud that does not say); docs/map-format.md.")
      .def_property_readonly(
          "covariance_assumed", [](const Map& map) { return map.header.covariance_assumed; },
          "True when the covariances were not in the file but assumed: isotropic, half the "
          "local landmark spacing (point clouds without covariances).")
      .def_property_readonly(
          "landmark_ids",
          [](const Map& map) { return per_landmark(map, [](const Landmark& l) { return l.id; }); },
          "(N,) int64: landmark ids, in landmark order.")
      .def_property_readonly(
          "frame_ids",
          [](const Map& map) {
            py::array_t<std::int64_t> a(static_cast<py::ssize_t>(map.frames.size()));
            for (std::size_t i = 0; i < map.frames.size(); ++i)
              a.mutable_data()[i] = map.frames[i].id;
            return a;
          },
          "(F,) int64: frame (keyframe) ids, in file order.")
      .def_property_readonly(
          "frame_poses",
          [](const Map& map) {
            return poses_out(map.frames.size(),
                             [&](std::size_t i) { return map.frames[i].T_world_camera(); });
          },
          "(F, 4, 4) float64: T_world_camera of each frame (p_world = T @ p_camera), metres.")
      .def_property_readonly("num_frames", [](const Map& map) { return map.frames.size(); })
      .def(
          "__len__", [](const Map& map) { return map.landmarks.size(); }, "Number of landmarks.")
      .def(
          "transformed",
          [](const Map& map, const py::handle& T) {
            return transform_map(with_frame_index(map), transform_from(T, "T_new_old"));
          },
          py::arg("T_new_old"),
          "The map expressed in frame `new`: positions, covariances (R C R^T) and frame poses "
          "moved by the rigid (4, 4) T_new_old. Raises InvalidArgument if it is not rigid.")
      .def("__repr__", [](const Map& map) {
        return "<lmalign.Map: " + std::to_string(map.landmarks.size()) + " landmarks, " +
               std::to_string(map.frames.size()) + " frames>";
      });

  // The format names come from the one registry (map_formats(), formats.hpp).
  static const std::string read_map_doc =
      "Reads a map in any format lmalign reads (docs/map-format.md, map_formats()): format " +
      map_format_names() +
      " ('auto': by content). image_size (width, height) px: Bundler only, for pixels from the "
      "top-left corner (without it they stay centred; writing such a map in the lmalign text "
      "format is refused). Landmarks with fewer than min_observations observations are dropped "
      "(2: the paper's loader, and `lmalign align`'s default); formats without covariances get "
      "them re-estimated from the observations, landmarks whose covariance cannot be estimated "
      "are dropped; point clouds without any get them assumed from their spacing.\n"
      "Raises ParseError (file, line or byte offset), IoError, InvalidArgument.";
  m.def("read_map", &read_map_file, py::arg("path"), py::arg("min_observations") = 2,
        py::arg("format") = "auto", py::arg("image_size") = py::none(), read_map_doc.c_str());
  m.def(
      "map_formats",
      []() {
        py::list rows;
        for (const MapFormatInfo& f : map_formats()) {
          py::dict row;
          row["name"] = f.name;
          row["doc"] = f.doc;
          row["detected_by"] = f.detected_by;
          row["writes"] = f.write != nullptr;
          rows.append(row);
        }
        return rows;
      },
      "Every map format read_map() reads, in the order format 'auto' tries them: a list of dicts "
      "with name (read_map's format), doc, detected_by (what 'auto' looks for) and writes (True "
      "when lmalign writes it: `lmalign convert`'s outputs).");
  m.def(
      "write_map",
      [](const std::filesystem::path& path, const Map& map) {
        with_frame_index(map);
        py::gil_scoped_release release;
        write_map(path.string(), map);
      },
      py::arg("path"), py::arg("map"),
      "Writes a map file through lmalign's one output writer (docs/robustness.md, \"Outputs\"): "
      "a regular file or a new path atomically (temporary file, then rename), through a "
      "symlink to its target, a FIFO or character device in place, '-' to the standard "
      "output; write -> read is exact.\n"
      "Raises IoError (naming the path: a missing directory, a directory, a write error), "
      "InvalidArgument (map invalid).");
  m.def(
      "_write_output",
      [](const std::filesystem::path& path, const py::bytes& data) {
        const std::string bytes = data;
        py::gil_scoped_release release;
        write_output(path.string(), [&](std::ostream& out) {
          out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
        });
      },
      py::arg("path"), py::arg("data"),
      "The one output writer (io/output_file.hpp) for bytes: the package's own files (plots). "
      "Raises IoError naming the path.");
  m.def(
      "_create_output_folder",
      [](const std::filesystem::path& folder) { create_output_folder(folder.string()); },
      py::arg("folder"), "Creates an output folder (io/output_file.hpp). Raises IoError.");
}

void bind_geometry(py::module_& m) {
  m.def(
      "pose_from_xyz_rpy_deg",
      [](double x, double y, double z, double roll, double pitch, double yaw) {
        return matrix_out<4, 4>(pose_from_xyz_rpy_deg(x, y, z, roll, pitch, yaw).matrix());
      },
      py::arg("x_m"), py::arg("y_m"), py::arg("z_m"), py::arg("roll_deg"), py::arg("pitch_deg"),
      py::arg("yaw_deg"),
      "(4, 4) rigid transform with translation (x, y, z) m and R = Rz(yaw) Ry(pitch) Rx(roll), "
      "degrees (the paper's displacement, `lmalign align --displace`).");
  m.def(
      "transform_points",
      [](const py::handle& T, const py::handle& points) {
        return points_out(transform_points(transform_from(T, "T"), points_from(points, "points")));
      },
      py::arg("T"), py::arg("points"),
      "(N, 3) points moved by the rigid (4, 4) T: T @ p for each row, metres. Bit-identical to "
      "what the CLI's --displace does.");
  m.def(
      "transform_covariances",
      [](const py::handle& T, const py::handle& covariances) {
        const Array a = as_array(covariances, "covariances", {-1, 3, 3}, "(N, 3, 3)");
        return covariances_out(
            transform_covariances(transform_from(T, "T"), covariances_from(a, "covariances", -1)));
      },
      py::arg("T"), py::arg("covariances"), "(N, 3, 3) covariances (m^2) rotated by T: R C R^T.");
}

using AlignmentResultClass = py::class_<python::AlignOutcome>;

// AlignmentResult: the estimate and its run.
void bind_alignment_estimate(AlignmentResultClass& c) {
  c.def_property_readonly(
       "T_target_source",
       [](const python::AlignOutcome& o) {
         return matrix_out<4, 4>(o.summary.registration.T_target_source.matrix());
       },
       "(4, 4) float64: the estimate, p_target = T_target_source @ p_source (metres).")
      .def_property_readonly("strategy", [](const python::AlignOutcome& o) { return o.strategy; })
      .def_property_readonly(
          "converged",
          [](const python::AlignOutcome& o) { return o.summary.registration.converged; },
          "True when a convergence criterion stopped the run (not the budget).")
      .def_property_readonly(
          "termination",
          [](const python::AlignOutcome& o) {
            return to_string(o.summary.registration.termination);
          },
          "Why the run stopped: 'transform', 'max_iterations', 'no_correspondences', ...")
      .def_property_readonly(
          "iterations",
          [](const python::AlignOutcome& o) { return o.summary.registration.iterations; })
      .def_property_readonly(
          "num_correspondences",
          [](const python::AlignOutcome& o) { return o.summary.registration.num_correspondences; })
      .def_property_readonly(
          "initial_score_m2",
          [](const python::AlignOutcome& o) { return o.summary.registration.initial_score_m2; },
          "PCL fitness score at the initial guess: mean squared nearest-neighbour distance, m^2.")
      .def_property_readonly(
          "final_score_m2",
          [](const python::AlignOutcome& o) { return o.summary.registration.final_score_m2; },
          "PCL fitness score at the estimate, m^2.")
      .def_property_readonly(
          "wall_time_s",
          [](const python::AlignOutcome& o) { return o.summary.registration.wall_time_s; },
          "Wall time of the alignment (not of target preparation nor of the verdict), seconds.")
      .def_property_readonly(
          "started_s", [](const python::AlignOutcome& o) { return o.started_s; },
          "When the alignment began (after the target preparation), seconds on the clock of "
          "time.monotonic() (Linux: CLOCK_MONOTONIC).")
      .def_property_readonly(
          "finished_s", [](const python::AlignOutcome& o) { return o.finished_s; },
          "When the alignment and its trust verdict ended, seconds on the clock of "
          "time.monotonic().");
}

// AlignmentResult: the trust verdict and what it measured.
void bind_alignment_verdict(AlignmentResultClass& c) {
  c.def_property_readonly(
       "trustworthy", [](const python::AlignOutcome& o) { return o.summary.verdict.trustworthy; },
       "The verdict of the strategy's trust judge, without ground truth (docs/accuracy.md).")
      .def_property_readonly(
          "trust_reason", [](const python::AlignOutcome& o) { return o.summary.verdict.reason; },
          "'ok', or why the estimate is not trusted; either followed by '; N source landmarks "
          "... left out' when landmarks beyond the supported range were left out, and by a note "
          "when the covariances it weighed by were assumed (covariances_assumed).")
      .def_property_readonly(
          "source_landmarks_left_out",
          [](const python::AlignOutcome& o) { return o.summary.source_left_out; },
          "Source landmarks left out of the alignment for a coordinate beyond the supported range "
          "(|x| > 1e15 m; docs/robustness.md).")
      .def_property_readonly(
          "target_landmarks_left_out",
          [](const python::AlignOutcome& o) { return o.summary.target_left_out; },
          "Target landmarks left out likewise.")
      .def_property_readonly(
          "usable", [](const python::AlignOutcome& o) { return o.summary.IsSolutionUsable(); },
          "True when the estimate is finite and determined (Summary::IsSolutionUsable; says "
          "nothing of trust).")
      .def_property_readonly(
          "covariances_assumed",
          [](const python::AlignOutcome& o) { return o.summary.covariances_assumed; },
          "True when the strategy uses covariances (a covariance confidence or a distribution "
          "matcher: covariance, adaptive) "
          "and a map's covariances were assumed from its landmark spacing (a point cloud "
          "without any: Map.covariance_assumed).")
      .def_property_readonly(
          "inlier_fraction",
          [](const python::AlignOutcome& o) -> py::object {
            if (std::isnan(o.summary.verdict.inlier_fraction)) return py::none();
            return py::float_(o.summary.verdict.inlier_fraction);
          },
          "Judge 'inliers' (the paper's and the robust presets): source landmarks within 5 cm of "
          "a target landmark, of all; else None (see gated_inlier_ratio).")
      .def_property_readonly(
          "overlap_fraction",
          [](const python::AlignOutcome& o) -> py::object {
            if (std::isnan(o.summary.verdict.overlap_fraction)) return py::none();
            return py::float_(o.summary.verdict.overlap_fraction);
          },
          "Judge 'inliers': source landmarks within 20 cm, of all; else None.")
      .def_property_readonly(
          "gated_inlier_ratio",
          [](const python::AlignOutcome& o) -> py::object {
            if (!(o.summary.verdict.expected_nis > 0.0)) return py::none();
            return py::float_(o.summary.verdict.inlier_ratio);
          },
          "Judge 'gated' (the adaptive default) only, else None: covariance-gated inliers over the "
          "landmarks near a target landmark.")
      .def_property_readonly(
          "ambiguity",
          [](const python::AlignOutcome& o) -> py::object {
            if (!(o.summary.verdict.expected_nis > 0.0)) return py::none();
            return py::float_(o.summary.verdict.ambiguity);
          },
          "Judge 'gated' only (else None): the best distinct pose's score over the best's.")
      .def_property_readonly(
          "mean_nis",
          [](const python::AlignOutcome& o) -> py::object {
            if (!(o.summary.verdict.expected_nis > 0.0)) return py::none();
            return py::float_(o.summary.verdict.mean_nis);
          },
          "Judge 'gated' only (else None): mean Mahalanobis d^2 of the gated inliers at the "
          "estimate (dimensionless; 2.89 expected when the landmark covariances hold).")
      .def_property_readonly(
          "covariance_scale",
          [](const python::AlignOutcome& o) -> py::object {
            if (!(o.summary.verdict.expected_nis > 0.0)) return py::none();
            return py::float_(o.summary.verdict.covariance_scale);
          },
          "Judge 'gated' only (else None): the factor k^2 the landmark covariances need for the "
          "gated inliers' residuals (robust, from their median d^2; 1 when they hold). The "
          "reported covariance includes it when it is above 1.")
      .def_property_readonly(
          "alias_waived_by_prior",
          [](const python::AlignOutcome& o) -> py::object {
            if (!(o.summary.verdict.expected_nis > 0.0)) return py::none();
            return py::bool_(o.summary.verdict.alias_waived_by_prior);
          },
          "Judge 'gated' only (else None): with a prior, True when the alias test would have "
          "refused the answer (a rival at trust.alias_ambiguity, the residuals above their "
          "covariances) but the prior told that rival apart (the answer inside its window, the "
          "rival outside): trusted on the prior's word, and checked by the complete search.")
      .def_property_readonly(
          "rival_T_target_source",
          [](const python::AlignOutcome& o) -> py::object {
            if (!o.summary.verdict.rival_T_target_source) return py::none();
            return matrix_out<4, 4>(o.summary.verdict.rival_T_target_source->matrix());
          },
          "Judge 'gated' only (else None, also when there is none): the best distinct refined "
          "pose, (4, 4) float64 T_target_source (metres), whose score over the best's is "
          "`ambiguity`.");
}

// AlignmentResult: the scale, the uncertainty and the reports.
void bind_alignment_uncertainty(AlignmentResultClass& c) {
  c.def_property_readonly(
       "scale", [](const python::AlignOutcome& o) { return o.summary.scale.scale; },
       "Target units per source unit: p_target = scale * R @ p_source + t (1.0 when the scale "
       "was fixed).")
      .def_property_readonly(
          "scale_sd",
          [](const python::AlignOutcome& o) -> py::object {
            if (!std::isfinite(o.summary.scale.scale_sd)) return py::none();
            return py::float_(o.summary.scale.scale_sd);
          },
          "Standard deviation of `scale` (from the 7x7 covariance), None when the scale was "
          "fixed or it is not determined.")
      .def_property_readonly(
          "scale_mode",
          [](const python::AlignOutcome& o) { return o.summary.scale.free ? "free" : "fixed"; },
          "'free' when the scale was estimated, else 'fixed' (scale= resolved).")
      .def_property_readonly(
          "S_target_source",
          [](const python::AlignOutcome& o) {
            return matrix_out<4, 4>(o.summary.similarity().matrix());
          },
          "(4, 4) float64: the similarity [scale * R, t; 0 1] (T_target_source when the scale "
          "is fixed); p_target = S_target_source @ p_source.")
      .def_property_readonly(
          "translation_sd_m",
          [](const python::AlignOutcome& o) { return o.summary.covariance.translation_sd_m(); },
          "Standard deviation of the translation along its worst axis, metres.")
      .def_property_readonly(
          "rotation_sd_deg",
          [](const python::AlignOutcome& o) { return o.summary.covariance.rotation_sd_deg(); },
          "Standard deviation of the rotation about its worst axis, degrees.")
      .def_property_readonly(
          "covariance",
          [](const python::AlignOutcome& o) -> py::object {
            if (!o.summary.covariance.valid) return py::none();
            return matrix_out<6, 6>(o.summary.covariance.covariance);
          },
          "(6, 6) float64 or None: covariance of xi = (tx, ty, tz [m], rx, ry, rz [rad]), a left "
          "perturbation in the target frame (the CLI's covariance_6x6), as the strategy reports "
          "it; None when it is not determined.")
      .def(
          "brief_report", [](const python::AlignOutcome& o) { return o.summary.BriefReport(); },
          "One line: the strategy, termination, iterations, scores, time, the verdict.")
      .def(
          "full_report", [](const python::AlignOutcome& o) { return o.summary.FullReport(); },
          "Every stage's report, one per line (Summary::FullReport).")
      .def(
          "to_json",
          [](const python::AlignOutcome& o, int indent) { return to_json(o.summary, indent); },
          py::arg("indent") = -1,
          "The result as JSON text: the entry `lmalign align --json` writes for it (without the "
          "ground-truth errors only the CLI computes).")
      .def("__repr__", [](const python::AlignOutcome& o) {
        return "<lmalign.AlignmentResult " + o.summary.BriefReport() + ">";
      });
}

void bind_align(py::module_& m) {
  AlignmentResultClass result(m, "AlignmentResult",
                              "What lmalign.align() returns (see its docstring).");
  bind_alignment_estimate(result);
  bind_alignment_verdict(result);
  bind_alignment_uncertainty(result);

  m.def(
      "_align",
      [](const py::handle& source, const py::handle& target, const std::string& strategy,
         const py::handle& initial_guess, const py::handle& prior_sigma, int threads,
         const py::handle& source_covariances, const py::handle& target_covariances,
         const py::handle& target_weights, int k, std::optional<int> max_iterations,
         std::optional<double> max_distance_m, const std::string& covariance_norm,
         const py::handle& settings, const std::string& scale) {
        python::AlignRequest req;
        req.scale = parse_scale_mode(scale);
        req.strategy = strategy;
        req.k = k;
        req.max_iterations = max_iterations;
        req.max_distance_m = max_distance_m;
        req.threads = threads;
        if (!settings.is_none()) {
          if (!py::isinstance<py::dict>(settings)) {
            throw InvalidArgument("settings: expected a dict {key: value}");
          }
          for (const auto& kv : settings.cast<py::dict>()) {
            const std::string key = py::str(kv.first);
            const py::handle v = kv.second;
            SettingValue value;
            if (py::isinstance<py::bool_>(v)) {
              value = v.cast<bool>();
            } else if (py::isinstance<py::int_>(v)) {
              value = v.cast<long long>();
            } else if (py::isinstance<py::float_>(v)) {
              value = v.cast<double>();
            } else if (py::isinstance<py::str>(v)) {
              value = v.cast<std::string>();
            } else if (py::isinstance<py::sequence>(v)) {
              value = vector_from(v, ("settings['" + key + "']").c_str(), -1);
            } else {
              throw InvalidArgument("settings['" + key +
                                    "']: expected a bool, a number, a name or a list of numbers");
            }
            req.settings.emplace_back(key, value);
          }
        }
        if (!initial_guess.is_none())
          req.initial_guess = transform_from(initial_guess, "initial_guess");
        if (!prior_sigma.is_none()) {
          const std::vector<double> ps = vector_from(prior_sigma, "prior_sigma", 2);
          req.prior = PriorSigma{ps[0], ps[1]};
          std::string why;
          if (!req.prior->is_valid(&why)) throw InvalidArgument("prior_sigma: " + why);
        }
        WeightOptions wopt;
        wopt.covariance_norm = parse_covariance_norm(covariance_norm);
        // Source: a Map, or (N, 3) points with optional (N, 3, 3) covariances.
        Points3 source_points;
        std::vector<Mat3> source_cov;
        std::vector<Vec3> source_views;
        if (py::isinstance<Map>(source)) {
          if (!source_covariances.is_none())
            throw InvalidArgument(
                "source_covariances: give them only with an array source (a Map has its own)");
          const Map& s = source.cast<const Map&>();
          source_points = s.positions();
          source_cov = s.covariances_m2();
          source_views = s.view_directions();
          req.source_up = estimate_up_axis(s);
          req.source_header = s.header;
        } else {
          source_points = points_from(source, "source");
          if (!source_covariances.is_none())
            source_cov = covariances_from(source_covariances, "source_covariances",
                                          static_cast<py::ssize_t>(source_points.size()));
        }
        // Target: a Map (weights and covariances from it), or points with optional extras.
        std::optional<PreparedTarget> prepared;
        if (py::isinstance<Map>(target)) {
          if (!target_covariances.is_none() || !target_weights.is_none())
            throw InvalidArgument(
                "target_covariances / target_weights: give them only with an array target");
          const Map& t = with_frame_index(target.cast<const Map&>());
          req.target_header = t.header;
          py::gil_scoped_release release;
          prepared.emplace(t, wopt);
        } else {
          Points3 tp = points_from(target, "target");
          const auto n = static_cast<py::ssize_t>(tp.size());
          std::vector<Mat3> tc;
          if (!target_covariances.is_none())
            tc = covariances_from(target_covariances, "target_covariances", n);
          std::vector<double> tw;
          if (!target_weights.is_none()) tw = vector_from(target_weights, "target_weights", n);
          py::gil_scoped_release release;
          prepared.emplace(std::move(tp));
          if (!tc.empty()) prepared->set_covariances(std::move(tc));
          if (!tw.empty()) {
            for (WeightKind kind :
                 {WeightKind::kCovariance, WeightKind::kObservations, WeightKind::kMeanDistance})
              prepared->set_weights(kind, tw);
          }
        }
        py::gil_scoped_release release;
        return python::run_alignment(source_points, source_cov, source_views, *prepared, req);
      },
      py::arg("source"), py::arg("target"), py::arg("strategy"), py::arg("initial_guess"),
      py::arg("prior_sigma"), py::arg("threads"), py::arg("source_covariances"),
      py::arg("target_covariances"), py::arg("target_weights"), py::arg("k"),
      py::arg("max_iterations"), py::arg("max_distance_m"), py::arg("covariance_norm"),
      py::arg("settings"), py::arg("scale"));

  m.def(
      "strategies", []() { return preset_names(); },
      "Every strategy name align() accepts (the presets, configs/presets/): the paper's four, "
      "then lmalign's own.");
  m.def(
      "options",
      [](const std::string& strategy) {
        const Preset preset = find_preset(strategy);
        const Pipeline pipeline(preset.spec);
        py::list rows;
        for (const SettingRow& row : pipeline.settings().table()) {
          py::dict d;
          d["key"] = row.key;
          d["value"] = row.text(pipeline.settings().value(row.key));
          d["unit"] = row.unit;
          d["bound"] = row.bound.text(row.type);
          d["doc"] = row.doc;
          rows.append(d);
        }
        return rows;
      },
      py::arg("strategy"),
      "The strategy's settings, one dict per setting: key, value (as text), unit, bound, doc "
      "(`lmalign options NAME`). Any of them can be given to align(..., settings={key: value}).");
  m.attr("RECOMMENDED_STRATEGY") = recommended_preset().name;
}

void bind_split(py::module_& m) {
  m.def(
      "split",
      [](const Map& map, Id first, Id last, std::size_t min_observations, bool retriangulate,
         double min_parallax_deg, bool return_stats) -> py::object {
        SplitOptions o;
        o.first_frame_id = first;
        o.last_frame_id = last;
        o.min_observations = min_observations;
        o.retriangulate = retriangulate;
        o.min_parallax_deg = min_parallax_deg;
        with_frame_index(map);
        SplitStats stats;
        Map mini;
        {
          py::gil_scoped_release release;
          mini = split_map(map, o, &stats);
        }
        if (!return_stats) return py::cast(std::move(mini));
        py::dict d;
        d["frames_kept"] = stats.frames_kept;
        d["landmarks_kept"] = stats.landmarks_kept;
        d["landmarks_outside_window"] = stats.landmarks_outside_window;
        d["dropped_too_few_observations"] = stats.dropped_too_few_observations;
        d["dropped_low_parallax"] = stats.dropped_low_parallax;
        d["dropped_triangulation_failed"] = stats.dropped_triangulation_failed;
        return py::make_tuple(std::move(mini), d);
      },
      py::arg("map"), py::arg("first_frame_id"), py::arg("last_frame_id"),
      py::arg("min_observations") = 2, py::arg("retriangulate") = false,
      py::arg("min_parallax_deg") = 2.0, py::arg("return_stats") = false,
      "The mini-map of frames [first_frame_id, last_frame_id] (inclusive), as `lmalign split` "
      "(docs/split.md): those frames, and the landmarks with >= min_observations observations "
      "among them (observations outside the window removed). retriangulate=True re-estimates "
      "positions and covariances from the window alone and drops landmarks below "
      "min_parallax_deg. Same world frame, ids kept. return_stats=True returns (map, dict) "
      "with what `lmalign split` prints: frames_kept, landmarks_kept, "
      "landmarks_outside_window, dropped_too_few_observations, dropped_low_parallax, "
      "dropped_triangulation_failed. Raises InvalidArgument.");
}

void bind_trajectories(py::module_& m) {
  m.def(
      "read_tum_trajectory",
      [](const std::filesystem::path& path) {
        const Trajectory t = read_tum_trajectory(path.string());
        py::array_t<double> stamps(static_cast<py::ssize_t>(t.size()));
        for (std::size_t i = 0; i < t.size(); ++i) stamps.mutable_data()[i] = t[i].timestamp_s;
        return py::make_tuple(
            stamps, poses_out(t.size(), [&](std::size_t i) { return t[i].T_world_camera; }));
      },
      py::arg("path"),
      "Reads a TUM trajectory file: (timestamps_s (N,), T_world_camera (N, 4, 4)), sorted by "
      "time. Raises ParseError (file, line), IoError.");
  m.def(
      "evaluate_trajectory",
      [](const py::handle& estimate, const py::handle& ground_truth, double max_difference_s,
         double offset_s, double delta_s, bool align) {
        const Trajectory est = trajectory_from(estimate, "estimate");
        const Trajectory gt = trajectory_from(ground_truth, "ground_truth");
        AteOptions ao;
        ao.max_difference_s = max_difference_s;
        ao.offset_s = offset_s;
        ao.align = align;
        RpeOptions ro;
        ro.max_difference_s = max_difference_s;
        ro.offset_s = offset_s;
        ro.delta_s = delta_s;
        AteResult ate;
        RpeResult rpe;
        {
          py::gil_scoped_release release;
          ate = absolute_trajectory_error(est, gt, ao);
          rpe = relative_pose_error(est, gt, ro);
        }
        py::dict d;
        d["pairs"] = ate.pairs.size();
        d["T_gt_est"] = matrix_out<4, 4>(ate.T_gt_est.matrix());
        d["ate_translation_m"] = stats_out(ate.translation_m);
        d["ate_rotation_deg"] = stats_out(ate.rotation_deg);
        d["rpe_translation_m"] = stats_out(rpe.translation_m);
        d["rpe_rotation_deg"] = stats_out(rpe.rotation_deg);
        return d;
      },
      py::arg("estimate"), py::arg("ground_truth"), py::arg("max_difference_s") = 0.02,
      py::arg("offset_s") = 0.0, py::arg("delta_s") = 1.0, py::arg("align") = true,
      "Absolute trajectory error and relative pose error as the TUM RGB-D benchmark defines "
      "them (`lmalign eval-trajectory`). estimate, ground_truth: a TUM file path, or a tuple "
      "(timestamps_s (N,), T_world_camera (N, 4, 4)). Returns a dict: pairs, T_gt_est (4, 4; "
      "maps the estimate's world onto the ground truth's), ate_translation_m, ate_rotation_deg, "
      "rpe_translation_m, rpe_rotation_deg (each: count, rmse, mean, median, std, min, max). "
      "Raises InvalidArgument (fewer than 3 associated poses), ParseError, IoError.");
}

void bind_experiment(py::module_& m) {
  m.def(
      "_experiment",
      [](const std::filesystem::path& config_path, const std::filesystem::path& output_dir,
         const std::vector<std::string>& only, int threads, const std::string& data_dir) {
        namespace fs = std::filesystem;
        ConfigLoadOptions lo;
        lo.data_dir = data_dir;
        ExperimentConfig config = load_experiment_config(config_path.string(), lo);
        if (!only.empty()) select_experiments(config, only);
        const ExperimentInputs in = load_experiment_inputs(config);
        const Points3 source_points = in.source.positions();
        const std::vector<Case> cases = expand_cases(config, source_points);
        const fs::path& out = output_dir;
        create_output_folder(output_dir.string());
        write_output((out / "config.yaml").string(),
                     [&](std::ostream& o) { o << resolved_config_yaml(config); });
        RunnerOptions ro;
        ro.threads = threads;
        SourceDescription source_description;
        describe_inputs(in, source_description, ro);
        RunnerOutcome outcome;
        {
          py::gil_scoped_release release;
          const PreparedTarget target(in.target, WeightOptions{config.covariance_norm});
          outcome = run_cases(config, cases, source_points, target, in.ground_truth, ro);
        }
        write_output((out / "results.csv").string(),
                     [&](std::ostream& o) { write_results_csv(o, cases, outcome.records); });
        const ReportSummary summary = summarize(config, cases, outcome);
        write_output((out / "summary.json").string(),
                     [&](std::ostream& o) { write_summary_json(o, config, summary); });
        write_output((out / "tables.md").string(), [&](std::ostream& o) {
          write_tables_markdown(o, config, cases, outcome, summary);
        });
        return py::make_tuple(outcome.cases_finished, outcome.records.size());
      },
      py::arg("config"), py::arg("output_dir"), py::arg("only"), py::arg("threads"),
      py::arg("data_dir"));
}

}  // namespace

PYBIND11_MODULE(_lmalign, m) {
  m.doc() = "lmalign's compiled core; use the lmalign package (docs/python.md).";
  bind_exceptions(m);
  bind_map(m);
  bind_geometry(m);
  bind_align(m);
  bind_split(m);
  bind_trajectories(m);
  bind_experiment(m);

  // ------------------------------------------------------------ merge (lmalign::merge)
#ifdef LMALIGN_HAVE_MERGE
  m.attr("HAVE_MERGE") = true;
  bind_merge(m);
#else
  m.attr("HAVE_MERGE") = false;
#endif
}
