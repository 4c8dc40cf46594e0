// A seeded synthetic multi-robot scene for the merge (docs/merge.md
// "Synthetic fleet"): one large outdoor world cut into N mini-maps, each in its own random frame,
// with the true T_world_map known and some planted look-alike (aliased) map pairs.
//
// World frame: z up, metres. The world is a flat yard with a gentle terrain (ground landmarks,
// ground_density_per_m2) and boxes standing on it (object_density_per_m2 boxes per m^2, footprints
// 0.5-2.5 m, landmarks on their walls and tops at surface_density_per_m2). Box heights follow a
// smooth random field (0.5-6 m), so that regions differ in their height statistics the way real
// places do (the candidate pre-filter's descriptor, candidates.hpp, relies on such differences).
// Map centres lie on a jittered square grid with spacing spacing_factor * map_radius_m; map i sees
// the world landmarks within map_radius_m (horizontally) of its centre, each with probability
// detection_probability, with isotropic Gaussian position noise position_sigma_m (and that
// covariance), and has 8 keyframes on a circle of 0.3 map_radius_m around the centre, 1.5 m above
// the ground, looking outwards (camera axes x right, y down, z forward: estimate_up_axis() finds
// world z). Each landmark has 2 observations: pinhole pixels (f = 500 px, centre (320, 240)) of
// the true point in the 2 keyframes looking most directly at it. Landmark ids are the world ids
// (the same physical landmark has the same id in every map). That is `views` = kRing, the
// default. With kRoaming each map has 24 keyframes anywhere within 0.7 map_radius_m of its centre
// (uniform over the disc), 1.5 m above the ground, each with its own heading, and a keyframe sees
// a landmark only from the front of the surface it lies on: a box's wall is not seen through the
// box (kRing sees it from behind too, so two neighbouring maps see the landmarks between their
// centres from opposite sides; docs/merge.md, "Why the look-alikes win on the fleet").
//
// Planted false candidates: num_twins pairs of maps (a, b) far apart (centres more than
// 3.2 map_radius_m apart, twin regions disjoint from each other); the world around b (within 1.6
// map_radius_m) is replaced by a copy of the world around a, turned by a random yaw (new ids): maps
// a and b then look alike but share no landmark, and aligning them gives a confident wrong
// transform that the pose graph must reject.
//
// Each map is expressed in its own frame: T_world_map = [Rz(yaw), t], yaw uniform in
// [-180, 180) deg, t = centre + uniform offsets (+-5 m horizontally, +-0.5 m vertically);
// p_world = T_world_map * p_map. With prior_sigma_deg and prior_sigma_m > 0, each map also gets a
// noisy prior T_world_map * Exp(xi), xi = (rho, phi) ~ N(0, diag(sigma_m^2 I, sigma_rad^2 I)) in
// the map's own frame (a GPS-like heading error turns a map about itself, not about the world
// origin), and its covariance in the world-frame left convention of uncertainty.hpp,
// Ad(T_prior) diag(...) Ad(T_prior)^T.
// Deterministic for a given seed (std::mt19937_64, <random> distributions, as slam_sim.hpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/map/map.hpp"

namespace lmalign::sim {

/// How each map's keyframes see the world (see the file comment).
enum class FleetViews {
  kRing,     ///< 8 keyframes on a ring about the centre, looking out; walls seen from behind too
  kRoaming,  ///< 24 keyframes anywhere near the centre, any heading; surfaces seen from the front
};

struct FleetSimOptions {
  /// Mini-maps, in [2, 100000].
  std::size_t num_maps = 50;
  std::uint64_t seed = 1;
  /// Horizontal radius seen by a map, metres (> 0).
  double map_radius_m = 10.0;
  /// Grid spacing of the map centres, in map radii, in [0.3, 2] (1: 4-neighbours share ~40% of
  /// their area, diagonal ones ~18%).
  double spacing_factor = 1.0;
  double ground_density_per_m2 = 0.05;  ///< >= 0
  double object_density_per_m2 = 0.06;  ///< boxes per m^2, >= 0
  double surface_density_per_m2 = 1.5;  ///< landmarks per m^2 of box surface, >= 0
  double detection_probability = 0.8;   ///< in (0, 1]
  double position_sigma_m = 0.01;       ///< > 0
  /// Look-alike map pairs planted (see the file comment); fewer if the world is too small.
  std::size_t num_twins = 2;
  /// Noisy priors (both > 0), or none (both 0).
  double prior_sigma_deg = 0.0;
  double prior_sigma_m = 0.0;
  /// A pair of maps counts as truly overlapping when they share at least this fraction of the
  /// smaller map's landmarks, in (0, 1].
  double min_overlap = 0.05;
  /// The keyframes' layout and what they see. kRing draws the same scene as before the option.
  FleetViews views = FleetViews::kRing;
  /// Ceres-style check: false and the bad field named in *why.
  bool is_valid(std::string* why = nullptr) const;
};

/// A truly overlapping pair (i < j) and the fraction of the smaller map's landmarks it shares.
struct FleetOverlap {
  std::size_t i = 0;
  std::size_t j = 0;
  double shared_fraction = 0.0;
};

struct FleetScene {
  std::vector<std::string> names;  ///< "map_000", ...
  std::vector<Map> maps;           ///< each in its own frame
  std::vector<Isometry3> T_world_map;
  /// Per map when the options ask for priors (noisy T_world_map), else empty.
  std::vector<Isometry3> prior_T_world_map;
  /// Their 6x6 covariances (uncertainty.hpp's convention: left perturbation in the world frame).
  std::vector<Mat6> prior_covariance;
  /// Truly overlapping pairs (min_overlap), i < j, sorted.
  std::vector<FleetOverlap> overlaps;
  /// The planted look-alike pairs (a, b), a < b; they share no landmark.
  std::vector<std::pair<std::size_t, std::size_t>> twins;
};

/// Simulates the fleet. Throws InvalidArgument on invalid options.
FleetScene simulate_fleet(const FleetSimOptions& options);

}  // namespace lmalign::sim
