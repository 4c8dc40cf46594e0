// Initialiser "guess": the initial guess alone (identity if none).
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(init_guess)

namespace lmalign::stages {

namespace {

class GuessInitialiser : public Initialiser {
 public:
  std::vector<Hypothesis> propose(const InitialiserContext& c,
                                  InitialiserReport* report) const override {
    report->initialisation = "given";
    Hypothesis h;
    h.T_target_source = c.initial_guess.value_or(Isometry3::Identity());
    h.origin = "guess";
    return {h};
  }
};

}  // namespace

std::vector<SettingRow> init_guess_settings() { return {}; }

std::unique_ptr<Stage> make_init_guess(const Settings&) {
  return std::make_unique<GuessInitialiser>();
}

}  // namespace lmalign::stages
