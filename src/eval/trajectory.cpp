// Trajectory I/O and the TUM benchmark's ATE and RPE (include/lmalign/eval/trajectory.hpp).
#include "lmalign/eval/trajectory.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <unordered_map>

#include <Eigen/SVD>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/text.hpp"
#include "lmalign/io/output_file.hpp"

namespace lmalign {

namespace {

double parse_double(const std::string& path, std::size_t line, const std::string& field,
                    const std::string& token) {
  double v = 0.0;
  const auto r = std::from_chars(token.data(), token.data() + token.size(), v);
  if (r.ec == std::errc::result_out_of_range) {
    throw ParseError(path, line, "field '" + field + "' is out of range: '" + token + "'");
  }
  if (r.ec != std::errc() || r.ptr != token.data() + token.size()) {
    throw ParseError(path, line, "field '" + field + "' is not a number: '" + token + "'");
  }
  if (!std::isfinite(v)) {
    throw ParseError(path, line, "field '" + field + "' is not finite: '" + token + "'");
  }
  return v;
}

std::ifstream open_text(const std::string& path, const std::string& what) {
  std::ifstream in(path);
  if (!in) throw IoError("cannot open " + what + " '" + path + "': " + std::strerror(errno));
  return in;
}

// Reads the non-comment lines of a text file as (line number, tokens).
std::vector<std::pair<std::size_t, std::vector<std::string>>> read_records(
    const std::string& path, const std::string& what) {
  std::ifstream in = open_text(path, what);
  std::vector<std::pair<std::size_t, std::vector<std::string>>> records;
  std::string line;
  std::size_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    auto toks = split_whitespace(line);
    if (toks.empty() || toks[0][0] == '#') continue;
    records.emplace_back(line_no, std::move(toks));
  }
  if (in.bad()) throw IoError("cannot read " + what + " '" + path + "'");
  return records;
}

double angle_deg(const Mat3& R) { return rotation_angle_deg(R); }

}  // namespace

Trajectory read_tum_trajectory(const std::string& path) {
  static const char* kNames[8] = {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};
  Trajectory out;
  std::map<double, std::size_t> seen;
  for (const auto& [line, toks] : read_records(path, "trajectory file")) {
    if (toks.size() != 8) {
      throw ParseError(path, line,
                       "TUM trajectory line has " + std::to_string(toks.size()) +
                           " fields, expected 8 (timestamp tx ty tz qx qy qz qw)");
    }
    double v[8];
    for (int i = 0; i < 8; ++i) v[i] = parse_double(path, line, kNames[i], toks[i]);
    const Quat q(v[7], v[4], v[5], v[6]);
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      throw ParseError(path, line,
                       "quaternion norm is " + shortest(q.norm()) + ", expected 1 (qx qy qz qw)");
    }
    if (auto [it, inserted] = seen.emplace(v[0], line); !inserted) {
      throw ParseError(
          path, line,
          "duplicate timestamp " + toks[0] + " (first on line " + std::to_string(it->second) + ")");
    }
    StampedPose p;
    p.timestamp_s = v[0];
    p.T_world_camera.linear() = q.normalized().toRotationMatrix();
    p.T_world_camera.translation() = Vec3(v[1], v[2], v[3]);
    out.push_back(p);
  }
  std::stable_sort(out.begin(), out.end(), [](const StampedPose& a, const StampedPose& b) {
    return a.timestamp_s < b.timestamp_s;
  });
  return out;
}

void write_tum_trajectory(const std::string& path, const Trajectory& trajectory) {
  for (const auto& p : trajectory) {
    if (!std::isfinite(p.timestamp_s) || !is_finite(p.T_world_camera)) {
      throw InvalidArgument("cannot write trajectory '" + path + "': pose at time " +
                            shortest(p.timestamp_s) + " is not finite");
    }
  }
  write_output(path, [&](std::ostream& os) {
    os << "# timestamp tx ty tz qx qy qz qw (T_world_camera)\n";
    for (const auto& p : trajectory) {
      Quat q(p.T_world_camera.rotation());
      if (q.w() < 0) q.coeffs() = -q.coeffs();
      const Vec3 t = p.T_world_camera.translation();
      os << shortest(p.timestamp_s) << ' ' << shortest(t.x()) << ' ' << shortest(t.y()) << ' '
         << shortest(t.z()) << ' ' << shortest(q.x()) << ' ' << shortest(q.y()) << ' '
         << shortest(q.z()) << ' ' << shortest(q.w()) << '\n';
    }
  });
}

std::vector<std::pair<Id, double>> read_frame_times(const std::string& path) {
  std::vector<std::pair<Id, double>> out;
  std::unordered_map<Id, std::size_t> seen;
  for (const auto& [line, toks] : read_records(path, "frame-times file")) {
    if (toks.size() != 2) {
      throw ParseError(path, line,
                       "frame-times line has " + std::to_string(toks.size()) +
                           " fields, expected 2 (frame_id timestamp)");
    }
    Id id = 0;
    const auto r = std::from_chars(toks[0].data(), toks[0].data() + toks[0].size(), id);
    if (r.ec != std::errc() || r.ptr != toks[0].data() + toks[0].size() || id < 0) {
      throw ParseError(path, line,
                       "field 'frame_id' is not a non-negative integer: '" + toks[0] + "'");
    }
    const double t = parse_double(path, line, "timestamp", toks[1]);
    if (auto [it, inserted] = seen.emplace(id, line); !inserted) {
      throw ParseError(
          path, line,
          "duplicate frame id " + toks[0] + " (first on line " + std::to_string(it->second) + ")");
    }
    out.emplace_back(id, t);
  }
  return out;
}

Trajectory trajectory_from_map(const Map& map,
                               const std::vector<std::pair<Id, double>>& frame_times,
                               const std::string& frame_times_name) {
  std::unordered_map<Id, double> times(frame_times.begin(), frame_times.end());
  Trajectory out;
  out.reserve(map.frames.size());
  for (const auto& f : map.frames) {
    const auto it = times.find(f.id);
    if (it == times.end()) {
      throw InvalidArgument("map FRAME " + std::to_string(f.id) + " has no time stamp in " +
                            frame_times_name);
    }
    out.push_back({it->second, f.T_world_camera()});
  }
  std::stable_sort(out.begin(), out.end(), [](const StampedPose& a, const StampedPose& b) {
    return a.timestamp_s < b.timestamp_s;
  });
  return out;
}

std::vector<PoseAssociation> associate_trajectories(const Trajectory& estimate,
                                                    const Trajectory& ground_truth,
                                                    double max_difference_s, double offset_s) {
  struct Candidate {
    double diff;
    std::size_t e, g;
  };
  std::vector<Candidate> candidates;
  std::vector<double> gt_times(ground_truth.size());
  for (std::size_t j = 0; j < ground_truth.size(); ++j) {
    gt_times[j] = ground_truth[j].timestamp_s + offset_s;
  }
  std::vector<std::size_t> order(ground_truth.size());
  for (std::size_t j = 0; j < order.size(); ++j) order[j] = j;
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return gt_times[a] < gt_times[b]; });
  std::vector<double> sorted_times(order.size());
  for (std::size_t k = 0; k < order.size(); ++k) sorted_times[k] = gt_times[order[k]];
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    const double t = estimate[i].timestamp_s;
    auto lo = std::lower_bound(sorted_times.begin(), sorted_times.end(), t - max_difference_s);
    for (auto it = lo; it != sorted_times.end() && *it <= t + max_difference_s; ++it) {
      const std::size_t k = static_cast<std::size_t>(it - sorted_times.begin());
      candidates.push_back({std::abs(*it - t), i, order[k]});
    }
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const Candidate& a, const Candidate& b) {
                     if (a.diff != b.diff) return a.diff < b.diff;
                     if (a.e != b.e) return a.e < b.e;
                     return a.g < b.g;
                   });
  std::vector<char> used_e(estimate.size(), 0), used_g(ground_truth.size(), 0);
  std::vector<PoseAssociation> out;
  for (const auto& c : candidates) {
    if (used_e[c.e] || used_g[c.g]) continue;
    used_e[c.e] = used_g[c.g] = 1;
    out.push_back({c.e, c.g});
  }
  std::sort(out.begin(), out.end(), [&](const PoseAssociation& a, const PoseAssociation& b) {
    return estimate[a.estimate_index].timestamp_s < estimate[b.estimate_index].timestamp_s;
  });
  return out;
}

ErrorStats error_stats(const std::vector<double>& errors) {
  ErrorStats s;
  s.count = errors.size();
  if (errors.empty()) return s;
  double sum = 0.0, sum2 = 0.0;
  for (double e : errors) {
    sum += e;
    sum2 += e * e;
  }
  const double n = static_cast<double>(errors.size());
  s.mean = sum / n;
  s.rmse = std::sqrt(sum2 / n);
  s.std_dev = std::sqrt(std::max(0.0, sum2 / n - s.mean * s.mean));
  std::vector<double> sorted = errors;
  std::sort(sorted.begin(), sorted.end());
  s.min = sorted.front();
  s.max = sorted.back();
  const std::size_t m = sorted.size() / 2;
  s.median = sorted.size() % 2 == 1 ? sorted[m] : 0.5 * (sorted[m - 1] + sorted[m]);
  return s;
}

Isometry3 align_rigid(const Points3& source, const Points3& target) {
  if (source.size() != target.size() || source.empty()) {
    throw InvalidArgument("align_rigid: need equally many source and target points (got " +
                          std::to_string(source.size()) + " and " + std::to_string(target.size()) +
                          "), at least 1");
  }
  Vec3 cs = Vec3::Zero(), ct = Vec3::Zero();
  for (std::size_t i = 0; i < source.size(); ++i) {
    cs += source[i];
    ct += target[i];
  }
  cs /= static_cast<double>(source.size());
  ct /= static_cast<double>(source.size());
  Mat3 H = Mat3::Zero();  // sum (t - ct)(s - cs)^T
  for (std::size_t i = 0; i < source.size(); ++i) {
    H += (target[i] - ct) * (source[i] - cs).transpose();
  }
  Eigen::JacobiSVD<Mat3> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 S = Mat3::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) S(2, 2) = -1.0;
  Isometry3 T = Isometry3::Identity();
  T.linear() = svd.matrixU() * S * svd.matrixV().transpose();
  T.translation() = ct - T.linear() * cs;
  return T;
}

AteResult absolute_trajectory_error(const Trajectory& estimate, const Trajectory& ground_truth,
                                    const AteOptions& options) {
  AteResult r;
  r.pairs =
      associate_trajectories(estimate, ground_truth, options.max_difference_s, options.offset_s);
  if (r.pairs.size() < 3) {
    auto range = [](const Trajectory& t) {
      if (t.empty()) return std::string("no poses");
      return std::to_string(t.size()) + " poses, " + shortest(t.front().timestamp_s) + " to " +
             shortest(t.back().timestamp_s) + " s";
    };
    throw InvalidArgument("only " + std::to_string(r.pairs.size()) + " poses associate within " +
                          shortest(options.max_difference_s) + " s (need 3): estimate " +
                          range(estimate) + ", ground truth " + range(ground_truth));
  }
  Points3 est, gt;
  for (const auto& p : r.pairs) {
    est.push_back(estimate[p.estimate_index].T_world_camera.translation());
    gt.push_back(ground_truth[p.ground_truth_index].T_world_camera.translation());
  }
  r.T_gt_est = options.align ? align_rigid(est, gt) : Isometry3::Identity();
  for (const auto& p : r.pairs) {
    const Isometry3 aligned = r.T_gt_est * estimate[p.estimate_index].T_world_camera;
    const Isometry3& g = ground_truth[p.ground_truth_index].T_world_camera;
    r.translation_errors_m.push_back((aligned.translation() - g.translation()).norm());
    r.rotation_errors_deg.push_back(angle_deg(g.linear().transpose() * aligned.linear()));
  }
  r.translation_m = error_stats(r.translation_errors_m);
  r.rotation_deg = error_stats(r.rotation_errors_deg);
  return r;
}

RpeResult relative_pose_error(const Trajectory& estimate, const Trajectory& ground_truth,
                              const RpeOptions& options) {
  RpeResult r;
  const auto pairs =
      associate_trajectories(estimate, ground_truth, options.max_difference_s, options.offset_s);
  std::vector<double> times;
  for (const auto& p : pairs) times.push_back(estimate[p.estimate_index].timestamp_s);
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const double target = times[i] + options.delta_s;
    auto it = std::lower_bound(times.begin(), times.end(), target);
    std::size_t j = static_cast<std::size_t>(it - times.begin());
    if (j == times.size() || (j > 0 && std::abs(times[j - 1] - target) < std::abs(*it - target))) {
      if (j == 0) continue;
      --j;
    }
    if (j <= i || std::abs(times[j] - target) > options.delta_tolerance_s) continue;
    const Isometry3& Pi = estimate[pairs[i].estimate_index].T_world_camera;
    const Isometry3& Pj = estimate[pairs[j].estimate_index].T_world_camera;
    const Isometry3& Qi = ground_truth[pairs[i].ground_truth_index].T_world_camera;
    const Isometry3& Qj = ground_truth[pairs[j].ground_truth_index].T_world_camera;
    const Isometry3 E = (Qi.inverse() * Qj).inverse() * (Pi.inverse() * Pj);
    r.translation_errors_m.push_back(E.translation().norm());
    r.rotation_errors_deg.push_back(angle_deg(E.linear()));
  }
  r.translation_m = error_stats(r.translation_errors_m);
  r.rotation_deg = error_stats(r.rotation_errors_deg);
  return r;
}

}  // namespace lmalign
