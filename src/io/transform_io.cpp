#include "lmalign/io/transform_io.hpp"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <vector>

#include "lmalign/core/error.hpp"
#include "lmalign/core/similarity.hpp"
#include "lmalign/core/text.hpp"
#include "lmalign/io/output_file.hpp"

namespace lmalign {

namespace {

// The 4x4 matrix of a transform file (rows, numbers, finiteness checked).
Mat4 read_matrix4(const std::string& path) {
  std::ifstream in(path);
  if (!in) {
    throw IoError("cannot open transform file '" + path + "': " + std::strerror(errno));
  }
  Mat4 M;
  int row = 0;
  std::size_t line_no = 0;
  std::string line;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto toks = split_whitespace(line);
    if (toks.empty() || toks[0][0] == '#') continue;
    if (row == 4) throw ParseError(path, line_no, "extra row: a 4x4 matrix has 4 rows");
    if (toks.size() != 4) {
      throw ParseError(path, line_no,
                       "row has " + std::to_string(toks.size()) + " values, expected 4");
    }
    for (int c = 0; c < 4; ++c) {
      const std::string& t = toks[c];
      double v = 0.0;
      auto r = std::from_chars(t.data(), t.data() + t.size(), v);
      if (r.ec != std::errc() || r.ptr != t.data() + t.size()) {
        throw ParseError(path, line_no,
                         "value " + std::to_string(c + 1) + " is not a number: '" + t + "'");
      }
      if (!std::isfinite(v)) {
        throw ParseError(path, line_no,
                         "value " + std::to_string(c + 1) + " is not finite: '" + t + "'");
      }
      M(row, c) = v;
    }
    ++row;
  }
  if (in.bad()) throw IoError("cannot read transform file '" + path + "'");
  if (row != 4) {
    throw ParseError(path, 0,
                     "expected 4 rows of 4 numbers (a 4x4 matrix), found " + std::to_string(row));
  }
  return M;
}

}  // namespace

Isometry3 read_transform(const std::string& path) {
  const Mat4 M = read_matrix4(path);
  if (M(3, 0) != 0.0 || M(3, 1) != 0.0 || M(3, 2) != 0.0 || M(3, 3) != 1.0) {
    throw ParseError(path, 0, "last row must be 0 0 0 1 (a rigid transform)");
  }
  const Mat3 R = M.topLeftCorner<3, 3>();
  if (!(R * R.transpose()).isApprox(Mat3::Identity(), 1e-6) ||
      std::abs(R.determinant() - 1.0) > 1e-6) {
    throw ParseError(path, 0, "the 3x3 rotation block is not a rotation (orthonormal, det +1)");
  }
  Isometry3 T = Isometry3::Identity();
  T.matrix() = M;
  return T;
}

Similarity3 read_similarity(const std::string& path) {
  const Mat4 M = read_matrix4(path);
  try {
    return similarity_from_matrix(M, "a similarity [sR t; 0 0 0 1]");
  } catch (const InvalidArgument& e) {
    throw ParseError(path, 0, e.what());
  }
}

void write_transform(const std::string& path, const Isometry3& T) {
  write_output(path, [&](std::ostream& out) {
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) out << (c ? " " : "") << shortest(T.matrix()(r, c));
      out << "\n";
    }
  });
}

}  // namespace lmalign
