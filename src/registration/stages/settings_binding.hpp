// A stage's settings rows bound to the members of its options struct, so that each setting is
// written once: its key, the member it sets (named for the docs, its default read from the
// struct's own initialiser), its bound, unit and doc. The same binding reads a Settings back
// into the struct. Internal to the library (the stages, the scale search and the engine).
#pragma once

#include <functional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "lmalign/registration/settings.hpp"

namespace lmalign {

/// The member argument of SettingsBinding: its path for the table's docs and an accessor of it
/// (a member, or a member of a member: `search.pool`).
#define LMALIGN_FIELD(path) #path, [](auto& o) -> decltype(auto) { return (o.path); }

/// Rows of settings bound to members of `Options`. Integer members (int, std::size_t) are
/// integer settings, double members real ones, bool members flags, std::string members choices
/// and std::vector<double> members lists of reals; the default is the member's value in a
/// default-constructed `Options`. Each row's member is named "STRUCT::path" (SettingRow::member),
/// with STRUCT the name given to the constructor.
template <class Options>
class SettingsBinding {
 public:
  explicit SettingsBinding(std::string struct_name) : struct_name_(std::move(struct_name)) {}

  /// A number or a list of reals: `bound` and `unit` as in SettingRow.
  template <class Access>
  SettingsBinding& add(std::string key, const char* path, Access access, SettingBound bound,
                       std::string unit, std::string doc) {
    using T = std::remove_reference_t<decltype(access(std::declval<Options&>()))>;
    Options defaults;
    const T& value = access(defaults);
    if constexpr (std::is_same_v<T, double>) {
      rows_.push_back(real_setting(key, member(path), value, std::move(bound), std::move(unit),
                                   std::move(doc)));
      readers_.push_back([key, access](const Settings& s, Options& o) { access(o) = s.real(key); });
    } else if constexpr (std::is_same_v<T, std::vector<double>>) {
      rows_.push_back(reals_setting(key, member(path), value, std::move(bound), std::move(unit),
                                    std::move(doc)));
      readers_.push_back(
          [key, access](const Settings& s, Options& o) { access(o) = s.reals(key); });
    } else {
      static_assert(std::is_integral_v<T> && !std::is_same_v<T, bool>,
                    "add() binds numbers and lists of reals; flag() and choice() the others");
      rows_.push_back(int_setting(key, member(path), static_cast<long long>(value),
                                  std::move(bound), std::move(unit), std::move(doc)));
      readers_.push_back([key, access](const Settings& s, Options& o) {
        access(o) = static_cast<T>(s.integer(key));
      });
    }
    return *this;
  }

  /// A bool member.
  template <class Access>
  SettingsBinding& flag(std::string key, const char* path, Access access, std::string doc) {
    Options defaults;
    rows_.push_back(bool_setting(key, member(path), access(defaults), std::move(doc)));
    readers_.push_back(
        [key, access](const Settings& s, Options& o) { access(o) = s.boolean(key); });
    return *this;
  }

  /// A std::string member that names one of `choices`.
  template <class Access>
  SettingsBinding& choice(std::string key, const char* path, Access access,
                          std::vector<std::string> choices, std::string doc) {
    Options defaults;
    rows_.push_back(
        choice_setting(key, member(path), access(defaults), std::move(choices), std::move(doc)));
    readers_.push_back([key, access](const Settings& s, Options& o) { access(o) = s.choice(key); });
    return *this;
  }

  /// The rows, in the order they were bound.
  const std::vector<SettingRow>& rows() const { return rows_; }

  /// Every bound member of `*options` set from `settings` (which holds these rows' keys).
  void read(const Settings& settings, Options* options) const {
    for (const auto& reader : readers_) reader(settings, *options);
  }
  /// A default-constructed Options, read().
  Options read(const Settings& settings) const {
    Options o;
    read(settings, &o);
    return o;
  }

 private:
  std::string member(const char* path) const { return struct_name_ + "::" + path; }

  std::string struct_name_;
  std::vector<SettingRow> rows_;
  std::vector<std::function<void(const Settings&, Options&)>> readers_;
};

}  // namespace lmalign
