// Private to src/experiment/: the experiment config's schema as one table (config.cpp reads
// and writes configs with it; settings_page.cpp prints it as docs/settings.md).
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/enum_names.hpp"
#include "lmalign/experiment/config.hpp"

namespace lmalign::detail {

inline constexpr int kMaxK = 4096;
inline constexpr std::size_t kMaxCasesPerList = 100000;

inline constexpr EnumName<ExperimentType> kExperimentTypeNames[] = {
    {ExperimentType::kNeighbourhood, "k"}, {ExperimentType::kYaw, "yaw"},
    {ExperimentType::kXy, "xy"},           {ExperimentType::kXyYaw, "xy_yaw"},
    {ExperimentType::kPoses, "poses"},     {ExperimentType::kBasin, "basin"},
    {ExperimentType::kRandom, "random"}};
inline constexpr EnumName<YawPivot> kYawPivotNames[] = {{YawPivot::kLandmark, "landmark"},
                                                        {YawPivot::kCentroid, "centroid"},
                                                        {YawPivot::kOrigin, "origin"}};
inline constexpr EnumName<TranslationDirections> kDirectionNames[] = {
    {TranslationDirections::kXy, "xy"}, {TranslationDirections::kXyz, "xyz"}};
/// EscalationSpec::stop_when_all_fail.
inline constexpr EnumName<bool> kStopNames[] = {{false, "any"}, {true, "all"}};

/// How a row's value is read: one scalar of a type, or a structure read by code of its own.
enum class Kind { kInt, kReal, kBool, kChoice, kSeed, kText, kStructure };

/// The struct a row's member belongs to.
enum class Owner {
  kNone,
  kConfig,
  kMap,
  kSuccess,
  kExperiment,
  kEscalation,
  kBasin,
  kRandom,
  kPose
};

/// One key: where it is written, which experiment types take it, the member it fills (get and
/// set), its default (as text), bound, unit and doc.
struct Row {
  std::string section;
  std::string types;  ///< experiment types, space-separated ("" = every)
  std::string key;
  Kind kind = Kind::kStructure;
  Owner owner = Owner::kNone;
  std::string member;
  std::string value;  ///< the default, as text
  SettingBound bound;
  std::string bound_text;  ///< structures: what is expected
  std::string unit;
  std::string doc;
  /// Read by code of its own even though it is a scalar (its bound depends on other keys).
  bool custom = false;
  std::function<std::optional<SettingValue>(const void*)> get;
  std::function<void(void*, const SettingValue&)> set;

  bool applies_to(const std::string& type) const {
    if (types.empty() || type.empty()) return true;
    const std::string padded = " " + types + " ";
    return padded.find(" " + type + " ") != std::string::npos;
  }
};

/// The sections (ExperimentConfigKey::section).
inline constexpr const char* kTop = "";
inline constexpr const char* kMapSection = "source, target";
inline constexpr const char* kSuccessSection = "success";
inline constexpr const char* kExperiments = "experiments[]";
inline constexpr const char* kEscalate = "experiments[].escalate";
inline constexpr const char* kLevels = "experiments[].levels";
inline constexpr const char* kPoseSection = "pose";

/// The rows, in the order resolved_config_yaml() writes them.
const std::vector<Row>& schema();
/// The rows of a section (and an experiment type: "" = every row of the section).
std::vector<const Row*> rows_of(const std::string& section, const std::string& type = "");
std::vector<std::string> keys_of(const std::string& section, const std::string& type = "");
/// The row of a key; throws Error if the table has none (a bug).
const Row& row_of(const std::string& section, const std::string& type, const std::string& key);
/// A value as the docs and the resolved config write it ("true", "5", "0.05", "inf", "xy").
std::string value_text(const SettingValue& v);
/// " degrees" for "deg", " metres" for "m", else "" (error messages).
std::string unit_word(const std::string& unit);

}  // namespace lmalign::detail
