// What every stage file includes: the seams, the settings (bound to its options struct by
// settings_binding.hpp), and the declaration of its two registry functions (registry.cpp lists
// the rows).
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/error.hpp"
#include "lmalign/core/types.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "lmalign/registration/seams.hpp"
#include "lmalign/registration/settings.hpp"
#include "settings_binding.hpp"

namespace lmalign::stages {

/// The landmark confidences a setting may name (weights.hpp): "uniform", "covariance",
/// "observations", "distance".
std::vector<std::string> confidence_names();

/// Refuses a user's limits that are not limits: a budget < 1, a distance that is not > 0.
void check_limits(std::optional<int> max_iterations, std::optional<double> max_distance_m);

/// The bound of a direction: a list of 3 reals (the up axis of a map: one type, a unit Vec3).
SettingBound vector3_bound();
/// The normalised direction of a 3-real setting. Throws InvalidArgument "KEY = [...] must be
/// finite and non-zero".
Vec3 unit_vector(const Settings& settings, const std::string& key);

}  // namespace lmalign::stages

/// Declares a stage's registry functions: `IDENT_settings()` (its rows) and `make_IDENT()`.
#define LMALIGN_STAGE_FUNCTIONS(IDENT)                           \
  namespace lmalign::stages {                                    \
  std::vector<SettingRow> IDENT##_settings();                    \
  std::unique_ptr<Stage> make_##IDENT(const Settings& settings); \
  }

/// Defines a stage's registry functions when the stage is built from its options alone, bound to
/// its rows by the file's `binding()` (settings_binding.hpp): `IDENT_settings()` returns the
/// rows, `make_IDENT()` reads them into the options and constructs `CLASS` from them.
#define LMALIGN_BOUND_STAGE(IDENT, CLASS)                                 \
  namespace lmalign::stages {                                             \
  std::vector<SettingRow> IDENT##_settings() { return binding().rows(); } \
  std::unique_ptr<Stage> make_##IDENT(const Settings& settings) {         \
    return std::make_unique<CLASS>(binding().read(settings));             \
  }                                                                       \
  }
