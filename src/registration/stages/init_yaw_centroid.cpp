// Initialiser "yaw_centroid": the initial guess, and init.yaw_hypotheses yaws about the maps'
// vertical init.up (evenly spaced from 0), each turning the moved source about its centroid and
// moving that onto the target's centroid. Meant with a scorer that refines and scores each.
#include <cmath>

#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/estimation_4dof.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(init_yaw_centroid)

namespace lmalign::stages {

namespace {

struct YawCentroidOptions {
  int hypotheses = 12;
  Vec3 up = Vec3::UnitZ();
};

class YawCentroid : public Initialiser {
 public:
  YawCentroid(int count, const Vec3& up) : count_(count), up_(up) {}

  std::vector<Hypothesis> propose(const InitialiserContext& c,
                                  InitialiserReport* report) const override {
    const Isometry3 T_init = c.initial_guess.value_or(Isometry3::Identity());
    const Points3& sp = *c.source.positions;
    Vec3 cs = Vec3::Zero();
    for (const Vec3& p : sp) cs += T_init * p;
    cs /= static_cast<double>(sp.size());
    Vec3 ct = Vec3::Zero();
    for (const Vec3& p : c.target->points()) ct += p;
    ct /= static_cast<double>(c.target->size());
    report->initialisation = "yaw_centroid";
    report->resolution_rad = 2.0 * kPi / count_;
    std::vector<Hypothesis> out;
    Hypothesis guess;
    guess.T_target_source = T_init;
    guess.origin = "guess";
    out.push_back(guess);
    for (int h = 0; h < count_; ++h) {
      const double yaw = 2.0 * M_PI * h / count_;
      Isometry3 H = Isometry3::Identity();
      H.linear() = rotation_about_up(up_, yaw);
      H.translation() = ct - H.linear() * cs;
      Hypothesis y;
      y.T_target_source = H * T_init;
      y.origin = "search";
      out.push_back(y);
    }
    return out;
  }

 private:
  int count_;
  Vec3 up_;
};

}  // namespace

std::vector<SettingRow> init_yaw_centroid_settings() {
  const YawCentroidOptions d;
  return {int_setting("init.yaw_hypotheses", "YawCentroidOptions::hypotheses", d.hypotheses,
                      SettingBound::closed(1, 3600), "count",
                      "yaws tried about the up axis, evenly spaced from 0, besides the guess"),
          reals_setting("init.up", "YawCentroidOptions::up", {d.up.x(), d.up.y(), d.up.z()},
                        vector3_bound(), "1",
                        "the maps' shared vertical the yaws turn about (normalised)")};
}

std::unique_ptr<Stage> make_init_yaw_centroid(const Settings& s) {
  return std::make_unique<YawCentroid>(static_cast<int>(s.integer("init.yaw_hypotheses")),
                                       unit_vector(s, "init.up"));
}

}  // namespace lmalign::stages
