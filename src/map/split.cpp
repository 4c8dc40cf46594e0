// Mini-map extraction by frame window (method.md §6, `lmalign split`).
#include "lmalign/map/split.hpp"

#include <cmath>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include "lmalign/core/error.hpp"

namespace lmalign {

namespace {

template <typename T>
std::string str(const T& value) {
  std::ostringstream os;
  os << value;
  return os.str();
}

}  // namespace

bool SplitOptions::is_valid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (first_frame_id < 0) {
    return fail("first_frame_id (" + str(first_frame_id) + ") must be >= 0");
  }
  if (first_frame_id > last_frame_id) {
    return fail("first_frame_id (" + str(first_frame_id) + ") > last_frame_id (" +
                str(last_frame_id) + ")");
  }
  if (min_observations < 1) {
    return fail("min_observations (" + str(min_observations) + ") must be >= 1");
  }
  if (retriangulate && min_observations < 2) {
    return fail("min_observations (" + str(min_observations) +
                ") must be >= 2 with retriangulate (triangulation needs two views)");
  }
  if (!std::isfinite(min_parallax_deg) || min_parallax_deg < 0.0 || min_parallax_deg > 180.0) {
    return fail("min_parallax_deg (" + str(min_parallax_deg) + ") must be in [0, 180] degrees");
  }
  std::string intrinsics_why;
  if (!triangulation.intrinsics.is_valid(&intrinsics_why)) {
    return fail("triangulation.intrinsics: " + intrinsics_why);
  }
  if (!std::isfinite(triangulation.pixel_sigma_px) || triangulation.pixel_sigma_px <= 0.0) {
    return fail("triangulation.pixel_sigma_px (" + str(triangulation.pixel_sigma_px) +
                ") must be finite and > 0");
  }
  if (triangulation.max_iterations < 0) {
    return fail("triangulation.max_iterations (" + str(triangulation.max_iterations) +
                ") must be >= 0");
  }
  return true;
}

Map split_map(const Map& map, const SplitOptions& options, SplitStats* stats) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("split options: " + why);

  SplitStats local;
  Map out;
  out.header = map.header;

  // Window frames, in their original order; every frame id, to catch dangling observations.
  std::unordered_map<Id, std::size_t> all_frames;  // id -> index in map.frames
  std::unordered_map<Id, Isometry3, std::hash<Id>, std::equal_to<Id>,
                     Eigen::aligned_allocator<std::pair<const Id, Isometry3>>>
      window_poses;  // id -> T_world_camera (retriangulate only)
  all_frames.reserve(map.frames.size());
  for (std::size_t i = 0; i < map.frames.size(); ++i) {
    const Frame& frame = map.frames[i];
    if (!all_frames.emplace(frame.id, i).second) {
      throw InvalidArgument("split: duplicate frame id " + str(frame.id));
    }
    if (frame.id >= options.first_frame_id && frame.id <= options.last_frame_id) {
      out.frames.push_back(frame);
      if (options.retriangulate) window_poses.emplace(frame.id, frame.T_world_camera());
    }
  }
  local.frames_kept = out.frames.size();
  auto in_window = [&](Id frame_id) {
    return frame_id >= options.first_frame_id && frame_id <= options.last_frame_id;
  };

  std::vector<PixelView> views;
  for (const Landmark& landmark : map.landmarks) {
    Landmark kept;
    kept.id = landmark.id;
    for (const Observation& obs : landmark.observations) {
      if (!in_window(obs.frame_id)) continue;
      if (all_frames.find(obs.frame_id) == all_frames.end()) {
        throw InvalidArgument("split: landmark " + str(landmark.id) +
                              " has an observation of unknown frame " + str(obs.frame_id));
      }
      kept.observations.push_back(obs);
    }
    if (kept.observations.empty()) {
      ++local.landmarks_outside_window;
      continue;
    }
    if (kept.observations.size() < options.min_observations) {
      ++local.dropped_too_few_observations;
      continue;
    }
    if (!options.retriangulate) {
      kept.p_world = landmark.p_world;  // exact copies: stored estimate, not re-derived
      kept.cov_world_m2 = landmark.cov_world_m2;
    } else {
      views.clear();
      for (const Observation& obs : kept.observations) {
        // Frames read from COLMAP or Bundler carry their own (distorted) intrinsics.
        const std::optional<PixelView> view =
            make_pixel_view(window_poses.at(obs.frame_id),
                            map.frames[all_frames.at(obs.frame_id)].camera, obs.u_px, obs.v_px);
        if (view) views.push_back(*view);
      }
      const std::optional<TriangulatedPoint> point = triangulate(views, options.triangulation);
      if (!point) {
        ++local.dropped_triangulation_failed;
        continue;
      }
      if (point->max_parallax_deg < options.min_parallax_deg) {
        ++local.dropped_low_parallax;
        continue;
      }
      kept.p_world = point->p_world;
      kept.cov_world_m2 = point->cov_world_m2;
    }
    out.landmarks.push_back(std::move(kept));
  }
  local.landmarks_kept = out.landmarks.size();
  if (stats != nullptr) *stats = local;
  return out;
}

}  // namespace lmalign
