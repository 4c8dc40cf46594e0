// Arrays in and out of lmalign's Python module (docs/python.md), shared by the binding files:
// float64, C-contiguous; other real dtypes or layouts are converted once, anything else is
// refused with ValueError naming the argument and the expected shape.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>
#include <vector>

#include "lmalign/core/error.hpp"
#include "lmalign/core/types.hpp"
#include "lmalign/map/map.hpp"

namespace lmalign::python {

namespace py = pybind11;

// ---------------------------------------------------------------- arrays in

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

inline std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

/// `obj` as a float64 C-contiguous array of the given shape (-1: any size, the same N as
/// `n` when n >= 0). Real dtypes (float, int, uint) are converted once; others are refused.
inline Array as_array(const py::handle& obj, const char* name, std::vector<py::ssize_t> shape,
                      const char* expected, py::ssize_t n = -1) {
  py::array a;
  try {
    a = py::module_::import("numpy").attr("asarray")(obj);
  } catch (const py::error_already_set& e) {  // e.g. a ragged nested list
    throw py::value_error(std::string(name) + ": expected an array of shape " + expected +
                          ", got an object numpy cannot convert (" + e.what() + ")");
  }
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    throw py::value_error(std::string(name) + ": expected a real array of shape " + expected +
                          " (float64), got dtype " + py::str(a.dtype()).cast<std::string>());
  }
  bool ok = a.ndim() == static_cast<py::ssize_t>(shape.size());
  for (std::size_t i = 0; ok && i < shape.size(); ++i) {
    const py::ssize_t want = shape[i] >= 0 ? shape[i] : n;
    ok = want < 0 || a.shape(static_cast<py::ssize_t>(i)) == want;
  }
  if (!ok) {
    throw py::value_error(std::string(name) + ": expected shape " + expected + ", got " +
                          shape_text(a));
  }
  return Array::ensure(a);
}

inline Points3 points_from(const py::handle& obj, const char* name) {
  const Array a = as_array(obj, name, {-1, 3}, "(N, 3)");
  Points3 p(static_cast<std::size_t>(a.shape(0)));
  const double* d = a.data();
  for (std::size_t i = 0; i < p.size(); ++i) p[i] = Vec3(d[3 * i], d[3 * i + 1], d[3 * i + 2]);
  return p;
}

inline std::vector<Mat3> covariances_from(const py::handle& obj, const char* name, py::ssize_t n) {
  const Array a = as_array(obj, name, {-1, 3, 3}, "(N, 3, 3) with N the number of points", n);
  std::vector<Mat3> c(static_cast<std::size_t>(a.shape(0)));
  const double* d = a.data();
  for (std::size_t i = 0; i < c.size(); ++i) {
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) c[i](r, k) = d[9 * i + 3 * r + k];
  }
  return c;
}

inline std::vector<double> vector_from(const py::handle& obj, const char* name, py::ssize_t n) {
  const Array a = as_array(obj, name, {-1}, "(N,) with N the number of points", n);
  return std::vector<double>(a.data(), a.data() + a.shape(0));
}

/// A 4x4 rigid transform: last row (0, 0, 0, 1), rotation orthonormal with det +1 (1e-6).
inline Isometry3 transform_from(const py::handle& obj, const char* name) {
  const Array a = as_array(obj, name, {4, 4}, "(4, 4)");
  Mat4 m;
  for (int r = 0; r < 4; ++r)
    for (int k = 0; k < 4; ++k) m(r, k) = a.data()[4 * r + k];
  const Mat3 R = m.topLeftCorner<3, 3>();
  if (!m.allFinite() || m.row(3) != Eigen::RowVector4d(0, 0, 0, 1) ||
      !(R.transpose() * R).isApprox(Mat3::Identity(), 1e-6) || !(R.determinant() > 0)) {
    throw InvalidArgument(std::string(name) +
                          ": expected a rigid 4x4 transform (finite, rotation orthonormal with "
                          "determinant +1, last row 0 0 0 1)");
  }
  Isometry3 T = Isometry3::Identity();
  T.matrix() = m;
  return T;
}

// ---------------------------------------------------------------- arrays out

inline py::array_t<double> points_out(const Points3& p) {
  py::array_t<double> a({static_cast<py::ssize_t>(p.size()), py::ssize_t{3}});
  double* d = a.mutable_data();
  for (std::size_t i = 0; i < p.size(); ++i)
    for (int k = 0; k < 3; ++k) d[3 * i + k] = p[i][k];
  return a;
}

inline py::array_t<double> covariances_out(const std::vector<Mat3>& c) {
  py::array_t<double> a({static_cast<py::ssize_t>(c.size()), py::ssize_t{3}, py::ssize_t{3}});
  double* d = a.mutable_data();
  for (std::size_t i = 0; i < c.size(); ++i)
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) d[9 * i + 3 * r + k] = c[i](r, k);
  return a;
}

/// (N, 4, 4) from n poses, pose(i) giving the i-th (an Isometry3).
template <typename F>
py::array_t<double> poses_out(std::size_t n, F pose) {
  py::array_t<double> a({static_cast<py::ssize_t>(n), py::ssize_t{4}, py::ssize_t{4}});
  for (std::size_t i = 0; i < n; ++i) {
    const Mat4 T = pose(i).matrix();
    for (int r = 0; r < 4; ++r)
      for (int k = 0; k < 4; ++k) a.mutable_data()[16 * i + 4 * r + k] = T(r, k);
  }
  return a;
}

template <int R, int C>
py::array_t<double> matrix_out(const Eigen::Matrix<double, R, C>& m) {
  py::array_t<double> a({py::ssize_t{R}, py::ssize_t{C}});
  for (int r = 0; r < R; ++r)
    for (int k = 0; k < C; ++k) a.mutable_data()[C * r + k] = m(r, k);
  return a;
}

/// Builds the map's lazy frame-id index while the GIL is held: a Map may be shared by Python
/// threads, and the first find_frame() must not run on two of them at once
/// (docs/architecture.md, "Thread safety"); lookups afterwards are concurrent reads.
inline const Map& with_frame_index(const Map& map) {
  if (!map.frames.empty()) map.frame_index(map.frames.front().id);
  return map;
}

}  // namespace lmalign::python
