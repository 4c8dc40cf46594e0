// A CLI test's pair of map files: a synthetic room (synthetic_scene.hpp) and the same map seen
// from another frame, written as target.txt and source.txt in the test's folder.
#pragma once

#include <cstdint>
#include <string>

#include "lmalign/map/map_io.hpp"
#include "lmalign/map/transform.hpp"
#include "support/run_cli.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign::test {

class CliRoomPair : public CliTest {
 protected:
  /// Writes target.txt, a room of `landmarks` landmarks (room_points(landmarks, seed), its
  /// frames and covariances from seed + 1), and source.txt, the same map in the frame `source`,
  /// so that p_target = T_target_source * p_source. Sets target_ and source_ to their paths.
  void write_room_pair(std::size_t landmarks, std::uint32_t seed,
                       const Isometry3& T_target_source) {
    target_ = path("target.txt");
    source_ = path("source.txt");
    const Map target = map_from_points(room_points(landmarks, seed), seed + 1);
    write_map(target_, target);
    write_map(source_, transform_map(target, T_target_source.inverse()));
  }
  std::string source_, target_;
};

}  // namespace lmalign::test
