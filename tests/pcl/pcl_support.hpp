// Helpers for the PCL tests (built only when CMake finds PCL): the real pair as PCL clouds, and
// the duplicate landmarks of a map (identical positions, which PCL and lmalign may pick
// differently on an exact distance tie).
#pragma once

#include <map>
#include <string>
#include <tuple>
#include <vector>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "lmalign/core/types.hpp"
#include "lmalign/pcl.hpp"
#include "support/data_path.hpp"

namespace lmalign::test {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;

inline std::string pair_file(const char* name) {
  return data_file(std::string("tum_fr1_desk/ground_truth_pair/") + name);
}

/// The points as a PCL cloud (PointXYZ stores float: each coordinate is rounded).
inline Cloud::Ptr to_cloud(const Points3& points) { return to_pcl_cloud(points); }

/// The cloud's points back in double (exactly the float values).
inline Points3 from_cloud(const Cloud& cloud) {
  Points3 p;
  p.reserve(cloud.size());
  for (const pcl::PointXYZ& q : cloud) p.emplace_back(q.x, q.y, q.z);
  return p;
}

/// For each point, the lowest index of a point with exactly the same coordinates.
inline std::vector<int> canonical_indices(const Points3& points) {
  std::map<std::tuple<double, double, double>, int> first;
  std::vector<int> canon(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto key = std::make_tuple(points[i].x(), points[i].y(), points[i].z());
    const auto it = first.find(key);
    canon[i] = it == first.end() ? (first[key] = static_cast<int>(i)) : it->second;
  }
  return canon;
}

}  // namespace lmalign::test
