// Consumer of the installed merge component (find_package(lmalign COMPONENTS merge)): solves a
// three-map pose graph with exact edges and checks that the poses are recovered. Exit 0 on
// success, 1 with a message otherwise.
#include <cstdio>

#include <lmalign/core/geometry.hpp>
#include <lmalign/merge/pose_graph.hpp>

int main() {
  const lmalign::Isometry3 T_w1 = lmalign::pose_from_xyz_rpy_deg(2, 0, 0, 0, 0, 30);
  const lmalign::Isometry3 T_w2 = lmalign::pose_from_xyz_rpy_deg(2, 3, 0, 0, 0, -50);
  std::vector<lmalign::Edge> edges(2);
  edges[0].source = 1;
  edges[0].target = 0;
  edges[0].T_target_source = T_w1;
  edges[1].source = 2;
  edges[1].target = 1;
  edges[1].T_target_source = T_w1.inverse() * T_w2;
  for (lmalign::Edge& e : edges) {
    e.trusted = true;
    e.covariance_valid = true;
    e.covariance = lmalign::Mat6::Identity() * 1e-4;
  }
  const std::vector<std::optional<lmalign::MapPrior>> none(3);
  const lmalign::MergeResult r = lmalign::solve_pose_graph(3, none, edges);
  const lmalign::TransformError e = lmalign::transform_error(r.maps[2].T_world_map, T_w2);
  std::printf("consumer_merge: %zu component(s); map 2 error %.3g deg, %.3g m\n", r.num_components,
              e.rotation_deg, e.translation_m);
  if (r.num_components != 1 || !(e.rotation_deg < 1e-6 && e.translation_m < 1e-6)) {
    std::printf("consumer_merge: FAILED to recover the poses\n");
    return 1;
  }
  return 0;
}
