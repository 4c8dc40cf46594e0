// Windows of a real map cut as `lmalign split --retriangulate` cuts them: the real-data tests'
// pairs of mini-maps with a known relative pose (both in the full map's frame).
#pragma once

#include <functional>

#include "lmalign/map/map.hpp"
#include "lmalign/map/split.hpp"

namespace lmalign::test {

/// The frames [first, last] of `full` and the landmarks they observe, re-triangulated from those
/// frames alone, in full's frame. `tune` may change the other split options (parallax,
/// intrinsics). Throws what split_map() throws.
inline Map retriangulated_window(const Map& full, Id first, Id last,
                                 const std::function<void(SplitOptions&)>& tune = {}) {
  SplitOptions o;
  o.first_frame_id = first;
  o.last_frame_id = last;
  o.retriangulate = true;
  if (tune) tune(o);
  return split_map(full, o);
}

}  // namespace lmalign::test
