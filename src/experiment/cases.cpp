// Config -> cases (docs/experiments.md, "Cases"). Every random draw happens here, serially, from
// a std::mt19937_64 per basin level seeded from the config's seed; the draws are mapped to numbers
// with explicit formulas (not std::uniform_*_distribution, whose output differs between standard
// libraries).
#include "lmalign/experiment/cases.hpp"

#include <charconv>
#include <cmath>
#include <cstring>
#include <random>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "text_format.hpp"

namespace lmalign {

namespace {

using detail::shortest;
using detail::shortest_rounded;

/// Uniform in [0, 1) with 53 random bits.
double uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

Case make_case(const ExperimentSpec& e, std::size_t experiment_index, std::string label,
               std::string group, std::string variable, double value, const Pose6& pose, int k) {
  Case c;
  c.experiment_index = experiment_index;
  c.experiment = e.name;
  c.label = std::move(label);
  c.group = std::move(group);
  c.variable = std::move(variable);
  c.value = value;
  c.displacement = pose;
  c.D = pose.transform();
  c.k = k;
  c.strategies = e.strategies;
  return c;
}

Case make_drawn_case(const ExperimentSpec& e, std::size_t experiment_index, std::string label,
                     std::string group, std::string variable, double value, const Isometry3& D) {
  const Eigen::Matrix<double, 6, 1> v = xyz_rpy_deg_from_pose(D);
  Pose6 p{v[0], v[1], v[2], v[3], v[4], v[5]};
  Case c = make_case(e, experiment_index, std::move(label), std::move(group), std::move(variable),
                     value, p, e.k);
  c.D = D;
  return c;
}

/// Mean of the points (zero if none).
Vec3 centroid_of(const Points3& points) {
  Vec3 c = Vec3::Zero();
  for (const Vec3& p : points) c += p;
  return points.empty() ? c : Vec3(c / static_cast<double>(points.size()));
}

/// The generator of one level of one axis: seeded from (seed, axis, level) through
/// std::seed_seq (whose output the standard specifies), so that a level's draws do not depend
/// on which other levels the config lists.
std::mt19937_64 level_rng(std::uint64_t seed, std::uint32_t axis, double level) {
  std::uint64_t bits = 0;
  static_assert(sizeof bits == sizeof level, "double is 64 bits");
  std::memcpy(&bits, &level, sizeof bits);
  std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32), axis,
                    static_cast<std::uint32_t>(bits), static_cast<std::uint32_t>(bits >> 32)};
  return std::mt19937_64(seq);
}

void expand_basin(const ExperimentSpec& e, std::size_t ei, const Points3& source_points,
                  std::vector<Case>& out) {
  const BasinSpec& b = e.basin;
  const Vec3 centroid = centroid_of(source_points);

  // A level of 0 is the identity whatever is drawn: one case stands for all its draws.
  const auto draws = [&](double level) { return level == 0.0 ? 1 : b.samples; };
  for (double level : b.yaw_levels_deg) {
    std::mt19937_64 rng = level_rng(b.seed, 0, level);
    for (int s = 0; s < draws(level); ++s) {
      // Two draws per case whatever the pivot, so the stream does not depend on it.
      const double sign = (rng() >> 63) != 0 ? -1.0 : 1.0;
      const double u = uniform01(rng);
      Vec3 pivot = Vec3::Zero();
      if (b.yaw_pivot == YawPivot::kCentroid) {
        pivot = centroid;
      } else if (b.yaw_pivot == YawPivot::kLandmark) {
        const std::size_t i =
            std::min(source_points.size() - 1,
                     static_cast<std::size_t>(u * static_cast<double>(source_points.size())));
        pivot = source_points[i];
      }
      pivot.z() = 0.0;  // a vertical axis: only its x, y matter
      const Isometry3 R = pose_from_xyz_rpy_deg(0, 0, 0, 0, 0, sign * level);
      Isometry3 D = Isometry3::Identity();
      D.linear() = R.linear();
      D.translation() = pivot - R.linear() * pivot;
      out.push_back(make_drawn_case(e, ei, "yaw=" + shortest(level) + " #" + std::to_string(s),
                                    "yaw", "yaw_deg", level, D));
    }
  }
  for (double level : b.translation_levels_m) {
    std::mt19937_64 rng = level_rng(b.seed, 1, level);
    for (int s = 0; s < draws(level); ++s) {
      const double u1 = uniform01(rng);
      const double u2 = uniform01(rng);
      Vec3 dir;
      if (b.translation_directions == TranslationDirections::kXy) {
        const double phi = 2.0 * M_PI * u1;
        dir = Vec3(std::cos(phi), std::sin(phi), 0.0);
      } else {
        const double z = 2.0 * u1 - 1.0;
        const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
        const double phi = 2.0 * M_PI * u2;
        dir = Vec3(r * std::cos(phi), r * std::sin(phi), z);
      }
      Isometry3 D = Isometry3::Identity();
      D.translation() = level * dir;
      out.push_back(make_drawn_case(e, ei, "t=" + shortest(level) + " #" + std::to_string(s),
                                    "translation", "translation_m", level, D));
    }
  }
}

/// Random starts (RandomStartSpec): draw i from its own generator seeded from (seed, i); six
/// uniforms per draw in a fixed order whatever the pivot: yaw, roll, pitch, offset direction,
/// offset length, pivot landmark.
void expand_random(const ExperimentSpec& e, std::size_t ei, const Points3& source_points,
                   std::vector<Case>& out) {
  const RandomStartSpec& r = e.random;
  const Vec3 centroid = centroid_of(source_points);
  // A: from a frame whose z is up to the maps' frame (Rx(90 deg) takes z to -y, Ry(90 deg) to x;
  // the sign of the up axis does not matter, every angle is drawn symmetrically).
  Mat3 A = Mat3::Identity();
  if (r.up_axis == CoordinateAxis::kY) {
    A = Eigen::AngleAxisd(M_PI / 2.0, Vec3::UnitX()).toRotationMatrix();
  }
  if (r.up_axis == CoordinateAxis::kX) {
    A = Eigen::AngleAxisd(M_PI / 2.0, Vec3::UnitY()).toRotationMatrix();
  }
  for (int s = 0; s < r.samples; ++s) {
    std::seed_seq seq{static_cast<std::uint32_t>(r.seed), static_cast<std::uint32_t>(r.seed >> 32),
                      2u, static_cast<std::uint32_t>(s)};
    std::mt19937_64 rng(seq);
    const double yaw = r.yaw_deg * (2.0 * uniform01(rng) - 1.0);
    const double roll = r.roll_pitch_deg * (2.0 * uniform01(rng) - 1.0);
    const double pitch = r.roll_pitch_deg * (2.0 * uniform01(rng) - 1.0);
    const double phi = 2.0 * M_PI * uniform01(rng);
    const double length = r.translation_m * uniform01(rng);
    const double u = uniform01(rng);
    Vec3 pivot = Vec3::Zero();
    if (r.pivot == YawPivot::kCentroid) {
      pivot = centroid;
    } else if (r.pivot == YawPivot::kLandmark) {
      const std::size_t i =
          std::min(source_points.size() - 1,
                   static_cast<std::size_t>(u * static_cast<double>(source_points.size())));
      pivot = source_points[i];
    }
    const Mat3 R_up = pose_from_xyz_rpy_deg(0, 0, 0, roll, pitch, yaw).linear();
    const Mat3 R = A * R_up * A.transpose();
    const Vec3 offset = A * Vec3(length * std::cos(phi), length * std::sin(phi), 0.0);
    Isometry3 D = Isometry3::Identity();
    D.linear() = R;
    D.translation() = pivot - R * pivot + offset;
    out.push_back(
        make_drawn_case(e, ei, "start #" + std::to_string(s), "random", "offset_m", length, D));
  }
}

}  // namespace

bool cases_need_source_points(const ExperimentConfig& config) {
  for (const ExperimentSpec& e : config.experiments) {
    if (e.type == ExperimentType::kBasin && !e.basin.yaw_levels_deg.empty() &&
        e.basin.yaw_pivot != YawPivot::kOrigin) {
      return true;
    }
    if (e.type == ExperimentType::kRandom && e.random.pivot != YawPivot::kOrigin) return true;
  }
  return false;
}

std::vector<Case> expand_cases(const ExperimentConfig& config, const Points3& source_points) {
  if (cases_need_source_points(config) && source_points.empty()) {
    throw InvalidArgument(
        "expand_cases: a basin or random experiment turns about source landmarks, but no "
        "source points were given");
  }
  std::vector<Case> out;
  int escalation_groups = 0;
  for (std::size_t ei = 0; ei < config.experiments.size(); ++ei) {
    const ExperimentSpec& e = config.experiments[ei];
    switch (e.type) {
      case ExperimentType::kNeighbourhood:
        for (int k : e.k_values) {
          out.push_back(make_case(e, ei, "k=" + std::to_string(k), "", "k", k, e.pose, k));
        }
        break;
      case ExperimentType::kYaw:
        for (double yaw : e.yaw_deg) {
          Pose6 p = e.pose;
          p.yaw_deg = yaw;
          out.push_back(make_case(e, ei, "yaw=" + shortest(yaw), "", "yaw_deg", yaw, p, e.k));
        }
        break;
      case ExperimentType::kXy:
        if (!e.escalate) {
          for (const auto& [q, offsets] : e.offsets_m) {
            for (double d : offsets) {
              Pose6 p = e.pose;
              p.x_m = q.sign_x * d;
              p.y_m = q.sign_y * d;
              out.push_back(
                  make_case(e, ei, q.name() + " " + shortest(d), q.name(), "offset_m", d, p, e.k));
            }
          }
        } else {
          const EscalationSpec& s = e.escalation;
          const int levels =
              static_cast<int>(std::floor((s.max_m - s.start_m) / s.step_m + 1e-9)) + 1;
          for (const Quadrant& q : e.quadrants) {
            const int group = escalation_groups++;
            for (int l = 0; l < levels; ++l) {
              const double d = std::round((s.start_m + l * s.step_m) * 1e9) / 1e9;
              Pose6 p = e.pose;
              p.x_m = q.sign_x * d;
              p.y_m = q.sign_y * d;
              Case c = make_case(e, ei, q.name() + " " + shortest_rounded(d), q.name(), "offset_m",
                                 d, p, e.k);
              c.escalation_group = group;
              c.escalation_level = l;
              out.push_back(std::move(c));
            }
          }
        }
        break;
      case ExperimentType::kXyYaw:
        for (const Quadrant& q : e.quadrants) {
          for (double yaw : e.yaw_deg) {
            Pose6 p = e.pose;
            p.x_m = q.sign_x * e.offset_m;
            p.y_m = q.sign_y * e.offset_m;
            p.yaw_deg = yaw;
            out.push_back(make_case(e, ei, q.name() + " yaw=" + shortest(yaw), q.name(), "yaw_deg",
                                    yaw, p, e.k));
          }
        }
        break;
      case ExperimentType::kPoses:
        for (std::size_t i = 0; i < e.poses.size(); ++i) {
          out.push_back(make_case(e, ei, "pose " + std::to_string(i), "", "pose",
                                  static_cast<double>(i), e.poses[i], e.k));
        }
        break;
      case ExperimentType::kBasin:
        expand_basin(e, ei, source_points, out);
        break;
      case ExperimentType::kRandom:
        expand_random(e, ei, source_points, out);
        break;
    }
  }
  for (std::size_t i = 0; i < out.size(); ++i) out[i].index = i;
  return out;
}

std::optional<std::size_t> find_case(const std::vector<Case>& cases, const std::string& id) {
  std::size_t index = 0;
  const auto r = std::from_chars(id.data(), id.data() + id.size(), index);
  if (!id.empty() && r.ec == std::errc() && r.ptr == id.data() + id.size()) {
    if (index < cases.size()) return index;
    return std::nullopt;
  }
  for (const Case& c : cases) {
    if (c.id() == id) return c.index;
  }
  return std::nullopt;
}

std::optional<std::size_t> default_plot_case(const ExperimentConfig& config,
                                             const std::vector<Case>& cases) {
  if (!config.plot_case.empty()) {
    const auto found = find_case(cases, config.plot_case);
    if (!found) {
      throw InvalidArgument("plot_case '" + config.plot_case +
                            "' names no case (give a case index, or <experiment>/<label> such "
                            "as " +
                            (cases.empty() ? std::string("table1_k/k=5") : cases.front().id()) +
                            ")");
    }
    return found;
  }
  if (cases.empty()) return std::nullopt;
  for (const Case& c : cases) {
    if (config.experiments[c.experiment_index].type == ExperimentType::kNeighbourhood && c.k == 5) {
      return c.index;
    }
  }
  return 0;
}

}  // namespace lmalign
