// Map model: frame index, positions, validation and rigid transformation (method.md §1).
#include "lmalign/map/map.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <unordered_map>

#include "lmalign/core/error.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

std::string map_scale_name(MapScale scale) { return name_of(kMapScaleNames, scale); }

std::optional<MapScale> map_scale_from_name(const std::string& name) {
  return find_enum(kMapScaleNames, name);
}

Isometry3 Frame::T_world_camera() const {
  Isometry3 T = Isometry3::Identity();
  T.linear() = q_world_camera.normalized().toRotationMatrix();
  T.translation() = p_world_camera;
  return T;
}

std::optional<std::size_t> Map::frame_index(Id id) const {
  if (frame_index_.size() != frames.size()) {
    frame_index_.clear();
    frame_index_.reserve(frames.size());
    // On duplicate ids the first occurrence wins (validate() reports duplicates).
    for (std::size_t i = 0; i < frames.size(); ++i) frame_index_.emplace(frames[i].id, i);
    // With duplicates the index is smaller than `frames`; it is then rebuilt on every call,
    // which is correct, only slower, for an invalid map.
  }
  const auto it = frame_index_.find(id);
  if (it == frame_index_.end() || it->second >= frames.size() || frames[it->second].id != id) {
    return std::nullopt;
  }
  return it->second;
}

const Frame* Map::find_frame(Id id) const {
  const auto index = frame_index(id);
  return index ? &frames[*index] : nullptr;
}

Points3 Map::positions() const {
  Points3 points;
  points.reserve(landmarks.size());
  for (const Landmark& landmark : landmarks) points.push_back(landmark.p_world);
  return points;
}

std::vector<Mat3> Map::covariances_m2() const {
  std::vector<Mat3> covariances;
  covariances.reserve(landmarks.size());
  for (const Landmark& landmark : landmarks) covariances.push_back(landmark.cov_world_m2);
  return covariances;
}

std::vector<Vec3> Map::view_directions() const {
  std::vector<Vec3> directions;
  directions.reserve(landmarks.size());
  for (const Landmark& landmark : landmarks) {
    Vec3 sum = Vec3::Zero();
    std::size_t rays = 0;
    for (const Observation& o : landmark.observations) {
      const Frame* frame = find_frame(o.frame_id);
      if (frame == nullptr) continue;
      const Vec3 ray = landmark.p_world - frame->p_world_camera;
      const double length = ray.norm();
      if (!(length > 0.0) || !std::isfinite(length)) continue;
      sum += ray / length;
      ++rays;
    }
    const double mean_length = rays > 0 ? sum.norm() / static_cast<double>(rays) : 0.0;
    directions.push_back(mean_length >= kMinViewConcentration ? Vec3(sum.normalized())
                                                              : Vec3::Zero());
  }
  return directions;
}

void Map::validate() const {
  std::unordered_map<Id, std::size_t> frame_ids;
  frame_ids.reserve(frames.size());
  for (const Frame& frame : frames) {
    if (frame.id < 0) {
      throw InvalidArgument("FRAME id " + std::to_string(frame.id) + " is negative");
    }
    if (!frame_ids.emplace(frame.id, 0).second) {
      throw InvalidArgument("duplicate FRAME id " + std::to_string(frame.id));
    }
    if (!frame.p_world_camera.allFinite() || !frame.q_world_camera.coeffs().allFinite()) {
      throw InvalidArgument("FRAME " + std::to_string(frame.id) + " has a non-finite pose value");
    }
    if (frame.q_world_camera.norm() == 0.0) {
      throw InvalidArgument("FRAME " + std::to_string(frame.id) + " has a zero quaternion");
    }
  }
  std::unordered_map<Id, std::size_t> landmark_ids;
  landmark_ids.reserve(landmarks.size());
  for (const Landmark& landmark : landmarks) {
    const std::string name = "LANDMARK " + std::to_string(landmark.id);
    if (landmark.id < 0) throw InvalidArgument(name + ": id is negative");
    if (!landmark_ids.emplace(landmark.id, 0).second) {
      throw InvalidArgument("duplicate LANDMARK id " + std::to_string(landmark.id));
    }
    if (!landmark.p_world.allFinite()) throw InvalidArgument(name + " has a non-finite position");
    if (!landmark.cov_world_m2.allFinite()) {
      throw InvalidArgument(name + " has a non-finite covariance");
    }
    for (const Observation& obs : landmark.observations) {
      if (frame_ids.count(obs.frame_id) == 0) {
        throw InvalidArgument(name + " observes unknown frame " + std::to_string(obs.frame_id));
      }
      if (!std::isfinite(obs.u_px) || !std::isfinite(obs.v_px)) {
        throw InvalidArgument(name + " has a non-finite pixel observation in frame " +
                              std::to_string(obs.frame_id));
      }
    }
  }
}

Map transform_map(const Map& map, const Isometry3& T_new_old) {
  const Mat3 R = T_new_old.linear();
  Map out;
  out.header = map.header;
  out.frames.reserve(map.frames.size());
  for (const Frame& frame : map.frames) {
    Frame f = frame;
    const Isometry3 T_new_camera = T_new_old * frame.T_world_camera();
    Quat q(T_new_camera.linear());
    q.normalize();
    if (q.w() < 0.0) q.coeffs() = -q.coeffs();
    f.q_world_camera = q;
    f.p_world_camera = T_new_camera.translation();
    out.frames.push_back(f);
  }
  out.landmarks.reserve(map.landmarks.size());
  for (const Landmark& landmark : map.landmarks) {
    Landmark l = landmark;
    l.p_world = T_new_old * landmark.p_world;
    const Mat3 cov = R * landmark.cov_world_m2 * R.transpose();
    l.cov_world_m2 = 0.5 * (cov + cov.transpose());  // exact symmetry despite rounding
    out.landmarks.push_back(std::move(l));
  }
  return out;
}

void assume_covariances_from_spacing(Map& map, std::size_t k) {
  if (k == 0) throw InvalidArgument("assume_covariances_from_spacing: k must be >= 1");
  const std::size_t n = map.landmarks.size();
  if (n < 2) {
    throw InvalidArgument("cannot assume covariances from the spacing of " + std::to_string(n) +
                          " landmark(s): at least 2 are needed");
  }
  Points3 points = map.positions();
  for (std::size_t i = 0; i < n; ++i) {
    if (!points[i].allFinite()) {
      throw InvalidArgument("LANDMARK " + std::to_string(map.landmarks[i].id) +
                            " has a non-finite position");
    }
  }
  const KdTree tree(std::move(points));
  const std::size_t m = std::min(k, n - 1) + 1;  // the landmark itself comes first
  std::vector<PointIndex> indices(m);
  std::vector<double> distances_sq(m);
  std::vector<double> spacing(n, 0.0);
  std::vector<double> found;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t got = tree.knn(tree.points()[i], m, indices.data(), distances_sq.data());
    found.clear();
    for (std::size_t j = 0; j < got; ++j) {
      if (indices[j] != static_cast<PointIndex>(i)) found.push_back(std::sqrt(distances_sq[j]));
    }
    if (found.empty()) continue;
    std::nth_element(found.begin(), found.begin() + found.size() / 2, found.end());
    spacing[i] = found[found.size() / 2];
  }
  std::vector<double> positive;
  for (const double d : spacing) {
    if (d > 0.0) positive.push_back(d);
  }
  if (positive.empty()) {
    throw InvalidArgument("cannot assume covariances from the spacing: all " + std::to_string(n) +
                          " landmarks lie at one point");
  }
  std::nth_element(positive.begin(), positive.begin() + positive.size() / 2, positive.end());
  const double fallback = positive[positive.size() / 2];
  for (std::size_t i = 0; i < n; ++i) {
    const double sigma_m = 0.5 * (spacing[i] > 0.0 ? spacing[i] : fallback);
    Landmark& l = map.landmarks[i];
    l.cov_world_m2 = Mat3::Identity() * (sigma_m * sigma_m);
    l.covariance_unknown = false;
  }
  map.header.covariance_assumed = true;
}

}  // namespace lmalign
