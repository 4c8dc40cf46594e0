// Consumer of the installed lmalign package: moves a deterministic synthetic landmark set by a
// known T_target_source, aligns it back with the base strategy (the paper's nearest-neighbour
// ICP) and checks the recovered transform. Exit 0 on success, 1 with a message otherwise.
#include <cstdio>
#include <random>

#include <lmalign/core/geometry.hpp>
#include <lmalign/registration/presets.hpp>

int main() {
  std::mt19937_64 rng(20);
  std::uniform_real_distribution<double> coord(-2.0, 2.0);
  lmalign::Points3 target(500);
  for (lmalign::Vec3& p : target) p = lmalign::Vec3(coord(rng), coord(rng), coord(rng));
  // p_target = T_true * p_source, so p_source = T_true^-1 * p_target.
  const lmalign::Isometry3 T_true = lmalign::pose_from_xyz_rpy_deg(0.05, -0.03, 0.02, 2, -1, 4);
  const lmalign::Points3 source = lmalign::transform_points(T_true.inverse(), target);

  const lmalign::PreparedTarget prepared(target);
  lmalign::SourceView view;
  view.positions = &source;
  const lmalign::RegistrationResult r =
      lmalign::align(lmalign::find_preset("base"), view, prepared).registration;
  const lmalign::TransformError e = lmalign::transform_error(r.T_target_source, T_true);
  std::printf("consumer: %s; rotation error %.3g deg, translation error %.3g m\n",
              r.brief_report().c_str(), e.rotation_deg, e.translation_m);
  if (!(e.rotation_deg < 1e-6 && e.translation_m < 1e-8)) {
    std::printf("consumer: FAILED to recover the known transform\n");
    return 1;
  }
  return 0;
}
