// The settings of a registration pipeline, as one table: each setting is one row (key, member,
// default, bound, unit, doc). Every stage of the pipeline (pipeline.hpp) declares its rows; a
// pipeline's table is the engine's rows plus those of its stages. The same rows drive the
// validation (the key, the value and the bound named), the experiment configs' `settings:`, the
// CLI's `--set KEY=VALUE`, Python's `settings=`, `lmalign options PRESET` and the merge's edge
// cache key.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace lmalign {

/// A setting's value: a flag, an integer, a real, a name from a list, or a list of reals.
using SettingValue = std::variant<bool, long long, double, std::string, std::vector<double>>;

enum class SettingType { kBool, kInt, kReal, kChoice, kReals };

/// Where a value may lie. Numbers (and each element of a list) in the interval [lo, hi] with
/// either end open; +inf accepted only with `allow_inf`. A choice among `choices`. A list of
/// `min_size`..`max_size` elements, non-increasing when `non_increasing`.
struct SettingBound {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;
  bool hi_open = false;
  bool allow_inf = false;
  std::vector<std::string> choices;
  std::size_t min_size = 0;
  std::size_t max_size = std::numeric_limits<std::size_t>::max();
  bool non_increasing = false;

  static SettingBound closed(double lo, double hi);       ///< [lo, hi]
  static SettingBound open_closed(double lo, double hi);  ///< (lo, hi]
  static SettingBound closed_open(double lo, double hi);  ///< [lo, hi)
  static SettingBound open(double lo, double hi);         ///< (lo, hi)
  static SettingBound at_least(double lo);                ///< >= lo, finite
  static SettingBound above(double lo);                   ///< > lo, finite
  static SettingBound above_or_inf(double lo);            ///< > lo, or inf
  static SettingBound one_of(std::vector<std::string> names);
  /// The text of the bound, as error messages and `lmalign options` print it: "(0, 1]",
  /// ">= 1", "> 0 or inf", "one of none, huber, cauchy".
  std::string text(SettingType type) const;
};

/// One row of the table.
struct SettingRow {
  std::string key;  ///< "seam.name", e.g. "match.k", "schedule.max_iterations"
  SettingType type = SettingType::kReal;
  std::string member;  ///< the C++ member it sets (docs), e.g. "MahalanobisGateOptions::k"
  SettingValue value;  ///< the default
  SettingBound bound;
  std::string unit;  ///< "m", "deg", "rad", "m^2", "1" (dimensionless), "count", "flag"
  std::string doc;   ///< one sentence

  /// True when `v` has this row's type and lies within the bound; else *why names the key, the
  /// value and the bound: "match.k = 0 is outside [1, 4096]".
  bool check(const SettingValue& v, std::string* why = nullptr) const;
  /// The value as text: "true", "5", "0.05", "inf", "cauchy", "[inf, 1, 0.5]".
  std::string text(const SettingValue& v) const;
  /// Reads a value of this row's type from text (the CLI's --set): numbers, inf, true/false,
  /// a name, or reals separated by commas (brackets optional). Throws InvalidArgument naming
  /// the key when the text is not of the type or not within the bound.
  SettingValue parse(const std::string& text) const;
};

/// The Levenshtein distance between two names (insertions, deletions, substitutions), for the
/// nearest known key or preset named in refusals.
std::size_t edit_distance(const std::string& a, const std::string& b);
/// The name of `known` closest to `name` by edit_distance, when it is close (at most a third of
/// the name, and at least 2 edits, away); else empty.
std::string nearest_name(const std::string& name, const std::vector<std::string>& known);

/// Row helpers (the stages' tables are lists of these).
SettingRow bool_setting(std::string key, std::string member, bool value, std::string doc);
SettingRow int_setting(std::string key, std::string member, long long value, SettingBound bound,
                       std::string unit, std::string doc);
SettingRow real_setting(std::string key, std::string member, double value, SettingBound bound,
                        std::string unit, std::string doc);
SettingRow choice_setting(std::string key, std::string member, std::string value,
                          std::vector<std::string> choices, std::string doc);
SettingRow reals_setting(std::string key, std::string member, std::vector<double> value,
                         SettingBound bound, std::string unit, std::string doc);

/// The values of one pipeline: a table and its current values (the defaults until set).
class Settings {
 public:
  Settings() = default;
  /// Throws InvalidArgument if two rows share a key.
  explicit Settings(std::vector<SettingRow> table);

  const std::vector<SettingRow>& table() const { return rows_; }
  bool has(const std::string& key) const;
  /// The row of `key`; throws InvalidArgument "unknown setting 'KEY' (nearest: 'OTHER')".
  const SettingRow& row(const std::string& key) const;

  /// Sets a value; throws InvalidArgument for an unknown key (naming the nearest known key), a
  /// value of another type, or one outside its bound (naming the key, the value, the bound). An
  /// integer value is accepted for a real setting.
  void set(const std::string& key, SettingValue value);
  /// Sets a value from text (`--set KEY=VALUE`): SettingRow::parse, then set().
  void set_text(const std::string& key, const std::string& text);
  /// "KEY=VALUE" (the first '=' splits). Throws InvalidArgument for text without '='.
  void set_assignment(const std::string& assignment);

  const SettingValue& value(const std::string& key) const;
  bool boolean(const std::string& key) const;
  long long integer(const std::string& key) const;
  double real(const std::string& key) const;
  const std::string& choice(const std::string& key) const;
  const std::vector<double>& reals(const std::string& key) const;
  /// True when the key's value differs from its row's default.
  bool is_set(const std::string& key) const;

  /// Every value within its bound (always true after set(); kept for the Ceres-style check).
  bool is_valid(std::string* why = nullptr) const;
  /// The known key closest to `key` (edit distance over the key, then over its last part); empty
  /// when nothing is close.
  std::string nearest_key(const std::string& key) const;
  /// "key=value" for every row, in table order: the canonical text of the settings (the merge's
  /// edge cache key hashes it).
  std::string canonical_text() const;

 private:
  std::size_t index_of(const std::string& key) const;
  std::vector<SettingRow> rows_;
  std::vector<SettingValue> values_;
};

}  // namespace lmalign
