// Moving a whole map by a similarity (core/similarity.hpp): what an alignment with a free scale
// writes (`lmalign align --aligned-out`).
#pragma once

#include "lmalign/core/similarity.hpp"
#include "lmalign/map/map.hpp"

namespace lmalign {

/// The map moved by S_new_old: landmarks p -> s R p + t with covariances C -> s^2 R C R^T, frames'
/// camera centres c -> s R c + t and orientations R_world_camera -> R R_world_camera. Everything
/// else (ids, observations, pixels) is kept. With scale 1 it equals transform_map(map, rigid).
Map transform_map(const Map& map, const Similarity3& S_new_old);

}  // namespace lmalign
