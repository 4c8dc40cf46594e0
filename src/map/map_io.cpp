// Strict reader and exact writer of the map text file (method.md §1, docs/map-format.md).
#include "lmalign/map/map_io.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <ios>
#include <istream>
#include <limits>
#include <optional>
#include <ostream>
#include <streambuf>
#include <string>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>

#include "lmalign/core/error.hpp"
#include "lmalign/core/text.hpp"
#include "lmalign/io/output_file.hpp"

namespace lmalign {
namespace {

constexpr std::string_view kFrameSyntax = "FRAME id tx ty tz qw qx qy qz";
constexpr std::string_view kLandmarkSyntax =
    "LANDMARK id x y z c00 c01 c02 c10 c11 c12 c20 c21 c22 n f_1 u_1 v_1 ... f_n u_n v_n";
constexpr std::string_view kHeaderSyntax =
    "MAP [scale metric|arbitrary|unknown] [covariance estimated|assumed]";
constexpr std::size_t kFrameTokens = 9;
constexpr std::size_t kLandmarkFixedTokens = 15;  // LANDMARK id x y z c00..c22 n
constexpr const char* kCovNames[3][3] = {
    {"c00", "c01", "c02"}, {"c10", "c11", "c12"}, {"c20", "c21", "c22"}};

void append_double(std::string& out, double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out.append(buffer, result.ptr);
}

void append_id(std::string& out, Id value) {
  char buffer[24];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out.append(buffer, result.ptr);
}

/// A 6-significant-digit rendering for human-facing numbers (norms, eigenvalues).
std::string format_short(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.6g", value);
  return buffer;
}

/// Appends `text` with control bytes (and DEL) written as \xHH, so that an error message stays
/// one printable line whatever the file holds (NUL, CR, escape sequences).
void append_printable(std::string& out, std::string_view text) {
  static constexpr char kHex[] = "0123456789abcdef";
  for (const char ch : text) {
    const auto byte = static_cast<unsigned char>(ch);
    if (byte < 0x20 || byte == 0x7f) {
      out.append("\\x");
      out.push_back(kHex[byte >> 4]);
      out.push_back(kHex[byte & 0xf]);
    } else {
      out.push_back(ch);
    }
  }
}

/// Quotes a token for an error message, shortening very long ones.
std::string quote(std::string_view token) {
  constexpr std::size_t kMax = 64;
  std::string text = "'";
  if (token.size() > kMax) {
    append_printable(text, token.substr(0, kMax));
    text.append("...");
  } else {
    append_printable(text, token);
  }
  text.push_back('\'');
  return text;
}

enum class LineStatus { kLine, kEnd, kTooLong };

/// Reads one line (without its '\n') into `line`, reading at most max_bytes + 1 bytes of it:
/// memory stays bounded however long the line is. kTooLong leaves the rest of the line unread.
LineStatus next_line(std::streambuf& in, std::string& line, std::size_t max_bytes) {
  using Traits = std::char_traits<char>;
  line.clear();
  bool any = false;
  for (;;) {
    const Traits::int_type c = in.sbumpc();
    if (Traits::eq_int_type(c, Traits::eof())) return any ? LineStatus::kLine : LineStatus::kEnd;
    any = true;
    if (c == '\n') return LineStatus::kLine;
    // The limit excludes the line ending: a '\r' just before '\n' does not count.
    if (line.size() >= max_bytes && !(c == '\r' && in.sgetc() == '\n')) {
      return LineStatus::kTooLong;
    }
    line.push_back(Traits::to_char_type(c));
  }
}

bool is_separator(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f'; }

/// Splits `line` on runs of spaces/tabs into `tokens` (views into `line`).
void split(std::string_view line, std::vector<std::string_view>& tokens) {
  tokens.clear();
  std::size_t i = 0;
  const std::size_t size = line.size();
  while (i < size) {
    while (i < size && is_separator(line[i])) ++i;
    if (i == size) break;
    const std::size_t start = i;
    while (i < size && !is_separator(line[i])) ++i;
    tokens.push_back(line.substr(start, i - start));
  }
}

/// Name of a field in error messages: "tx", "c01", or "u_3" for observation 3.
struct FieldName {
  std::string_view base;
  std::size_t index = 0;  ///< 1-based observation index, 0 for none
  std::string str() const {
    std::string name(base);
    if (index > 0) name += "_" + std::to_string(index);
    return name;
  }
};

/// Covariance check shared by the reader (ParseError) and the writer (InvalidArgument).
/// Returns an empty string if `cov` is symmetric PSD within the tolerances, else the problem.
std::string covariance_problem(const Mat3& cov, double symmetry_tolerance, double psd_tolerance) {
  const double scale = std::max(1e-12, cov.cwiseAbs().maxCoeff());
  for (int i = 0; i < 3; ++i) {
    for (int j = i + 1; j < 3; ++j) {
      if (std::abs(cov(i, j) - cov(j, i)) > symmetry_tolerance * scale) {
        return std::string("covariance is not symmetric: ") + kCovNames[i][j] + "=" +
               shortest(cov(i, j)) + " but " + kCovNames[j][i] + "=" + shortest(cov(j, i)) +
               " (row-major c00 c01 c02 c10 c11 c12 c20 c21 c22)";
      }
    }
  }
  // 0.5 * a + 0.5 * b, not 0.5 * (a + b): no overflow for entries near the largest double.
  const Mat3 symmetric = 0.5 * cov + 0.5 * cov.transpose();
  const Eigen::SelfAdjointEigenSolver<Mat3> solver(symmetric, Eigen::EigenvaluesOnly);
  const Vec3 eigenvalues = solver.eigenvalues();  // ascending
  if (!eigenvalues.allFinite()) {
    return "covariance eigenvalues overflow a double (entries too large to check)";
  }
  const double largest = std::max(1e-12, eigenvalues.cwiseAbs().maxCoeff());
  if (eigenvalues(0) < -psd_tolerance * largest) {
    return "covariance is not positive semi-definite: smallest eigenvalue is " +
           format_short(eigenvalues(0)) + " (largest " + format_short(eigenvalues(2)) + ")";
  }
  return {};
}

std::string quaternion_problem(const Quat& q, double tolerance) {
  const double norm = q.norm();
  if (!(std::abs(norm - 1.0) <= tolerance)) {
    return "quaternion norm is " + format_short(norm) + ", expected 1 (w x y z, scalar first)";
  }
  return {};
}

/// Parses the records of one file. Holds the current line number for error messages.
class Reader {
 public:
  Reader(const std::string& name, const MapReadOptions& options) : name_(name), options_(options) {}

  Map read(std::istream& in) {
    if (in.bad() || in.rdbuf() == nullptr) {
      throw IoError("cannot read map file '" + name_ + "': read error");
    }
    std::streambuf& buffer = *in.rdbuf();
    std::string line;
    try {
      for (;;) {
        const LineStatus status = next_line(buffer, line, options_.max_line_bytes);
        if (status == LineStatus::kEnd) break;
        ++line_number_;
        if (status == LineStatus::kTooLong) {
          std::string start;
          append_printable(start, std::string_view(line).substr(0, 32));
          fail("line is longer than " + std::to_string(options_.max_line_bytes) +
               " bytes (MapReadOptions::max_line_bytes), not a map record; it starts '" + start +
               "...'");
        }
        parse_line(line);
      }
    } catch (const std::ios_base::failure& e) {
      // std::filebuf reports a failed read(2) by throwing.
      in.setstate(std::ios::badbit);
      throw IoError("cannot read map file '" + name_ + "': " + e.code().message());
    }
    check_observed_frames();
    return std::move(map_);
  }

 private:
  [[noreturn]] void fail(std::string detail) const {
    throw ParseError(name_, line_number_, std::move(detail));
  }

  void parse_line(std::string_view line) {
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    split(line, tokens_);
    if (tokens_.empty() || tokens_[0].front() == '#') return;
    const std::string_view type = tokens_[0];
    if (type == "FRAME") {
      parse_frame();
    } else if (type == "LANDMARK") {
      parse_landmark();
    } else if (type == "MAP") {
      parse_header();
    } else {
      fail("unknown record type " + quote(type) + " (expected FRAME, LANDMARK or MAP)");
    }
  }

  double parse_double(std::string_view token, FieldName field) const {
    double value = 0.0;
    const char* end = token.data() + token.size();
    const auto [ptr, ec] = std::from_chars(token.data(), end, value);
    if (ec == std::errc::result_out_of_range && ptr == end) {
      fail("field '" + field.str() + "' is out of the range of a double: " + quote(token));
    }
    if (ec != std::errc() || ptr != end) {
      fail("field '" + field.str() + "' is not a number: " + quote(token));
    }
    if (!std::isfinite(value)) {
      fail("field '" + field.str() + "' is not finite: " + quote(token));
    }
    return value;
  }

  Id parse_id(std::string_view token, FieldName field) const {
    Id value = 0;
    const char* end = token.data() + token.size();
    // from_chars accepts a leading '-', which an id may not have; it never accepts '+'.
    const auto [ptr, ec] = token.front() == '-'
                               ? std::from_chars_result{token.data(), std::errc::invalid_argument}
                               : std::from_chars(token.data(), end, value);
    if (ec != std::errc() || ptr != end || value < 0) {
      fail("field '" + field.str() + "' is not a non-negative integer: " + quote(token));
    }
    return value;
  }

  /// MAP key value ...: what the map says about itself (MapHeader). At most one per file.
  void parse_header() {
    if (header_line_ != 0) {
      fail("duplicate MAP record (first on line " + std::to_string(header_line_) + ")");
    }
    header_line_ = line_number_;
    if (tokens_.size() % 2 != 1) {
      fail("MAP record has " + std::to_string(tokens_.size()) + " fields, expected " +
           std::string(kHeaderSyntax));
    }
    bool seen_scale = false;
    bool seen_covariance = false;
    for (std::size_t i = 1; i + 1 < tokens_.size(); i += 2) {
      const std::string_view key = tokens_[i];
      const std::string value(tokens_[i + 1]);
      if (key == "scale") {
        if (seen_scale) fail("MAP record: duplicate key 'scale'");
        seen_scale = true;
        const std::optional<MapScale> scale = map_scale_from_name(value);
        if (!scale) {
          fail("MAP record: scale " + quote(value) + " is not one of metric, arbitrary, unknown");
        }
        map_.header.scale = *scale;
      } else if (key == "covariance") {
        if (seen_covariance) fail("MAP record: duplicate key 'covariance'");
        seen_covariance = true;
        if (value != "estimated" && value != "assumed") {
          fail("MAP record: covariance " + quote(value) + " is not one of estimated, assumed");
        }
        map_.header.covariance_assumed = value == "assumed";
      } else {
        fail("MAP record: unknown key " + quote(key) + " (known: scale, covariance; " +
             std::string(kHeaderSyntax) + ")");
      }
    }
  }

  void parse_frame() {
    if (tokens_.size() != kFrameTokens) {
      fail("FRAME record has " + std::to_string(tokens_.size()) + " fields, expected " +
           std::to_string(kFrameTokens) + " (" + std::string(kFrameSyntax) + ")");
    }
    Frame frame;
    frame.id = parse_id(tokens_[1], {"id"});
    const double tx = parse_double(tokens_[2], {"tx"});
    const double ty = parse_double(tokens_[3], {"ty"});
    const double tz = parse_double(tokens_[4], {"tz"});
    const double qw = parse_double(tokens_[5], {"qw"});
    const double qx = parse_double(tokens_[6], {"qx"});
    const double qy = parse_double(tokens_[7], {"qy"});
    const double qz = parse_double(tokens_[8], {"qz"});
    frame.p_world_camera = Vec3(tx, ty, tz);
    frame.q_world_camera = Quat(qw, qx, qy, qz);  // Eigen's constructor is scalar first too
    if (std::string problem =
            quaternion_problem(frame.q_world_camera, options_.quaternion_norm_tolerance);
        !problem.empty()) {
      fail(std::move(problem));
    }
    if (const auto [it, inserted] = frame_lines_.emplace(frame.id, line_number_); !inserted) {
      fail("duplicate FRAME id " + std::to_string(frame.id) + " (first defined on line " +
           std::to_string(it->second) + ")");
    }
    map_.frames.push_back(frame);
  }

  void parse_landmark() {
    if (tokens_.size() < kLandmarkFixedTokens) {
      fail("LANDMARK record has " + std::to_string(tokens_.size()) + " fields, expected at least " +
           std::to_string(kLandmarkFixedTokens) + " (" + std::string(kLandmarkSyntax) + ")");
    }
    Landmark landmark;
    landmark.id = parse_id(tokens_[1], {"id"});
    static constexpr std::string_view kPositionNames[3] = {"x", "y", "z"};
    for (int i = 0; i < 3; ++i) {
      landmark.p_world(i) = parse_double(tokens_[2 + i], {kPositionNames[i]});
    }
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        landmark.cov_world_m2(r, c) = parse_double(tokens_[5 + 3 * r + c], {kCovNames[r][c]});
      }
    }
    const Id n = parse_id(tokens_[14], {"n"});
    const std::size_t values_after_n = tokens_.size() - kLandmarkFixedTokens;
    const auto declared = static_cast<std::uint64_t>(n);
    if (values_after_n % 3 != 0 || values_after_n / 3 != declared) {
      const std::string expected_values = declared <= std::numeric_limits<std::uint64_t>::max() / 3
                                              ? std::to_string(3 * declared)
                                              : "3n";
      fail("LANDMARK " + std::to_string(landmark.id) + " declares n=" + std::to_string(n) +
           " observations (" + expected_values + " values) but has " +
           std::to_string(values_after_n) + " values after n");
    }
    if (std::string problem =
            covariance_problem(landmark.cov_world_m2, options_.covariance_symmetry_tolerance,
                               options_.covariance_psd_tolerance);
        !problem.empty()) {
      fail("LANDMARK " + std::to_string(landmark.id) + ": " + problem);
    }
    landmark.observations.resize(declared);
    for (std::size_t k = 0; k < declared; ++k) {
      const std::size_t base = kLandmarkFixedTokens + 3 * k;
      Observation& obs = landmark.observations[k];
      obs.frame_id = parse_id(tokens_[base], {"f", k + 1});
      obs.u_px = parse_double(tokens_[base + 1], {"u", k + 1});
      obs.v_px = parse_double(tokens_[base + 2], {"v", k + 1});
    }
    if (const auto [it, inserted] = landmark_lines_.emplace(landmark.id, line_number_); !inserted) {
      fail("duplicate LANDMARK id " + std::to_string(landmark.id) + " (first defined on line " +
           std::to_string(it->second) + ")");
    }
    // Frames may follow the landmarks that observe them: remember the references to frames not
    // seen yet, and resolve them at the end of the file.
    for (const Observation& obs : landmark.observations) {
      if (frame_lines_.count(obs.frame_id) == 0) {
        pending_frames_.push_back({obs.frame_id, landmark.id, line_number_});
      }
    }
    // Landmarks below the min_observations filter are validated, then dropped at once, so memory
    // follows the kept map rather than the file.
    if (landmark.num_observations() >= options_.min_observations) {
      map_.landmarks.push_back(std::move(landmark));
    } else {
      ++num_dropped_;
    }
  }

  /// Runs after the whole file: reports the first (in file order) observation of a frame that
  /// the file never defines.
  void check_observed_frames() const {
    for (const PendingFrame& pending : pending_frames_) {
      if (frame_lines_.count(pending.frame_id) == 0) {
        throw ParseError(name_, pending.line,
                         "LANDMARK " + std::to_string(pending.landmark_id) +
                             " observes unknown frame " + std::to_string(pending.frame_id));
      }
    }
  }

  const std::string& name_;
  const MapReadOptions& options_;
  std::size_t line_number_ = 0;
  std::size_t header_line_ = 0;
  std::vector<std::string_view> tokens_;
  std::unordered_map<Id, std::size_t> frame_lines_;
  std::unordered_map<Id, std::size_t> landmark_lines_;
  struct PendingFrame {
    Id frame_id;
    Id landmark_id;
    std::size_t line;
  };
  std::vector<PendingFrame> pending_frames_;
  Map map_;

 public:
  /// Landmarks dropped by the min_observations filter.
  std::size_t num_dropped_ = 0;
};

}  // namespace

bool MapReadOptions::is_valid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  const std::pair<const char*, double> tolerances[] = {
      {"quaternion_norm_tolerance", quaternion_norm_tolerance},
      {"covariance_symmetry_tolerance", covariance_symmetry_tolerance},
      {"covariance_psd_tolerance", covariance_psd_tolerance}};
  for (const auto& [field, value] : tolerances) {
    if (!std::isfinite(value) || value < 0.0) {
      return fail(std::string(field) + " must be finite and >= 0, got " + format_short(value));
    }
  }
  if (max_line_bytes < 64) {
    return fail("max_line_bytes must be >= 64, got " + std::to_string(max_line_bytes));
  }
  return true;
}

Map read_map(std::istream& in, const std::string& name, const MapReadOptions& options,
             std::size_t* num_dropped) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("map read options: " + why);
  Reader reader(name, options);
  Map map = reader.read(in);
  if (num_dropped != nullptr) *num_dropped = reader.num_dropped_;
  return map;
}

Map read_map(const std::string& path, const MapReadOptions& options, std::size_t* num_dropped) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    throw IoError("cannot open map file '" + path + "': " + std::strerror(EISDIR));
  }
  errno = 0;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    const int err = errno != 0 ? errno : ENOENT;
    throw IoError("cannot open map file '" + path + "': " + std::strerror(err));
  }
  return read_map(in, path, options, num_dropped);
}

void write_map(std::ostream& out, const Map& map) {
  std::string line;
  line.reserve(256);
  if (map.header != MapHeader{}) {
    line.assign("MAP scale ");
    line.append(map_scale_name(map.header.scale));
    line.append(map.header.covariance_assumed ? " covariance assumed\n"
                                              : " covariance estimated\n");
    out.write(line.data(), static_cast<std::streamsize>(line.size()));
  }
  for (const Frame& frame : map.frames) {
    line.assign("FRAME ");
    append_id(line, frame.id);
    for (const double value :
         {frame.p_world_camera.x(), frame.p_world_camera.y(), frame.p_world_camera.z()}) {
      line.push_back(' ');
      append_double(line, value);
    }
    const Quat& q = frame.q_world_camera;
    for (const double value : {q.w(), q.x(), q.y(), q.z()}) {  // scalar first
      line.push_back(' ');
      append_double(line, value);
    }
    line.push_back('\n');
    out.write(line.data(), static_cast<std::streamsize>(line.size()));
  }
  for (const Landmark& landmark : map.landmarks) {
    line.assign("LANDMARK ");
    append_id(line, landmark.id);
    for (int i = 0; i < 3; ++i) {
      line.push_back(' ');
      append_double(line, landmark.p_world(i));
    }
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {  // row-major
        line.push_back(' ');
        append_double(line, landmark.cov_world_m2(r, c));
      }
    }
    line.push_back(' ');
    line.append(std::to_string(landmark.observations.size()));
    for (const Observation& obs : landmark.observations) {
      line.push_back(' ');
      append_id(line, obs.frame_id);
      line.push_back(' ');
      append_double(line, obs.u_px);
      line.push_back(' ');
      append_double(line, obs.v_px);
    }
    line.push_back('\n');
    out.write(line.data(), static_cast<std::streamsize>(line.size()));
  }
}

void write_map(const std::string& path, const Map& map) {
  map.validate();
  // Refuse what read_map (default options) would reject, so that write -> read always works.
  const MapReadOptions defaults;
  for (const Frame& frame : map.frames) {
    if (frame.camera && frame.camera->centred_pixels) {
      throw InvalidArgument("FRAME " + std::to_string(frame.id) +
                            ": its pixels are relative to the image centre (a Bundler map read "
                            "without an image size); the map text format stores pixels from the "
                            "top-left corner: give the image size (--image-size W,H)");
    }
    if (std::string problem =
            quaternion_problem(frame.q_world_camera, defaults.quaternion_norm_tolerance);
        !problem.empty()) {
      throw InvalidArgument("FRAME " + std::to_string(frame.id) + ": " + problem);
    }
  }
  for (const Landmark& landmark : map.landmarks) {
    if (landmark.covariance_unknown) {
      throw InvalidArgument("LANDMARK " + std::to_string(landmark.id) +
                            ": covariance unknown (Landmark::covariance_unknown); the map text "
                            "format needs one, so drop such landmarks before writing");
    }
    if (std::string problem =
            covariance_problem(landmark.cov_world_m2, defaults.covariance_symmetry_tolerance,
                               defaults.covariance_psd_tolerance);
        !problem.empty()) {
      throw InvalidArgument("LANDMARK " + std::to_string(landmark.id) + ": " + problem);
    }
  }
  write_output(path, [&map](std::ostream& out) { write_map(out, map); });
}

}  // namespace lmalign
