#include "lmalign/registration/settings.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <sstream>

#include "lmalign/core/error.hpp"
#include "lmalign/core/text.hpp"

namespace lmalign {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Exact, locale-independent: the shortest text that reads back to v.
std::string number_text(double v) { return shortest(v); }

std::string trim(std::string s) {
  const auto not_space = [](unsigned char c) { return !std::isspace(c); };
  s.erase(s.begin(), std::find_if(s.begin(), s.end(), not_space));
  s.erase(std::find_if(s.rbegin(), s.rend(), not_space).base(), s.end());
  return s;
}

bool parse_real(const std::string& text, double* out) {
  std::string s = trim(text);
  std::string lower = s;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (lower == "inf" || lower == "+inf" || lower == ".inf" || lower == "infinity") {
    *out = kInf;
    return true;
  }
  const char* b = s.data();
  const char* e = s.data() + s.size();
  if (b != e && *b == '+') ++b;
  const auto r = std::from_chars(b, e, *out);
  return !s.empty() && r.ec == std::errc() && r.ptr == e && !std::isnan(*out);
}

}  // namespace

std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      cur[j] =
          std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] != b[j - 1] ? 1 : 0)});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

namespace {

std::string last_part(const std::string& key) {
  const std::size_t dot = key.rfind('.');
  return dot == std::string::npos ? key : key.substr(dot + 1);
}

const char* type_name(SettingType t) {
  switch (t) {
    case SettingType::kBool:
      return "true or false";
    case SettingType::kInt:
      return "an integer";
    case SettingType::kReal:
      return "a number";
    case SettingType::kChoice:
      return "a name";
    case SettingType::kReals:
      return "a list of numbers";
  }
  return "?";
}

bool in_interval(const SettingBound& b, double v) {
  if (std::isnan(v)) return false;
  if (std::isinf(v)) return v > 0 && b.allow_inf;
  if (b.lo_open ? !(v > b.lo) : !(v >= b.lo)) return false;
  if (std::isfinite(b.hi) && (b.hi_open ? !(v < b.hi) : !(v <= b.hi))) return false;
  return true;
}

}  // namespace

// ----------------------------------------------------------------------------- bounds

SettingBound SettingBound::closed(double lo, double hi) {
  SettingBound b;
  b.lo = lo;
  b.hi = hi;
  return b;
}
SettingBound SettingBound::open_closed(double lo, double hi) {
  SettingBound b = closed(lo, hi);
  b.lo_open = true;
  return b;
}
SettingBound SettingBound::closed_open(double lo, double hi) {
  SettingBound b = closed(lo, hi);
  b.hi_open = true;
  return b;
}
SettingBound SettingBound::open(double lo, double hi) {
  SettingBound b = closed(lo, hi);
  b.lo_open = b.hi_open = true;
  return b;
}
SettingBound SettingBound::at_least(double lo) { return closed(lo, kInf); }
SettingBound SettingBound::above(double lo) {
  SettingBound b = closed(lo, kInf);
  b.lo_open = true;
  return b;
}
SettingBound SettingBound::above_or_inf(double lo) {
  SettingBound b = above(lo);
  b.allow_inf = true;
  return b;
}
SettingBound SettingBound::one_of(std::vector<std::string> names) {
  SettingBound b;
  b.choices = std::move(names);
  return b;
}

std::string SettingBound::text(SettingType type) const {
  if (type == SettingType::kBool) return "true or false";
  if (type == SettingType::kChoice) {
    std::string s = "one of ";
    for (std::size_t i = 0; i < choices.size(); ++i) s += (i ? ", " : "") + choices[i];
    return s;
  }
  std::string s;
  const bool low = std::isfinite(lo);
  const bool high = std::isfinite(hi);
  auto number_text = [type](double v) {
    return type == SettingType::kInt && std::abs(v) < 9.0e15
               ? std::to_string(static_cast<long long>(v))
               : lmalign::number_text(v);
  };
  if (low && high) {
    s = std::string(lo_open ? "(" : "[") + number_text(lo) + ", " + number_text(hi) +
        (hi_open ? ")" : "]");
  } else if (low) {
    s = std::string(lo_open ? "> " : ">= ") + number_text(lo) + (allow_inf ? " or inf" : "");
  } else if (high) {
    s = std::string(hi_open ? "< " : "<= ") + number_text(hi);
  } else {
    s = allow_inf ? "any number or inf" : "any finite number";
  }
  if (type == SettingType::kReals) {
    std::string list = "a list of";
    if (min_size > 0) list += " " + std::to_string(min_size) + (max_size == min_size ? "" : "+");
    list += " numbers, each " + s;
    if (non_increasing) list += ", non-increasing";
    return list;
  }
  return s;
}

// ----------------------------------------------------------------------------- rows

std::string SettingRow::text(const SettingValue& v) const {
  if (const bool* b = std::get_if<bool>(&v)) return *b ? "true" : "false";
  if (const long long* i = std::get_if<long long>(&v)) return std::to_string(*i);
  if (const double* d = std::get_if<double>(&v)) return number_text(*d);
  if (const std::string* s = std::get_if<std::string>(&v)) return *s;
  const auto& list = std::get<std::vector<double>>(v);
  std::string s = "[";
  for (std::size_t i = 0; i < list.size(); ++i) s += (i ? ", " : "") + number_text(list[i]);
  return s + "]";
}

bool SettingRow::check(const SettingValue& v, std::string* why) const {
  auto fail = [&](const std::string& what) {
    if (why != nullptr) *why = what;
    return false;
  };
  const std::string bound_text = bound.text(type);
  switch (type) {
    case SettingType::kBool:
      if (!std::holds_alternative<bool>(v)) return fail(key + ": expected true or false");
      return true;
    case SettingType::kInt: {
      if (!std::holds_alternative<long long>(v)) return fail(key + ": expected an integer");
      const double d = static_cast<double>(std::get<long long>(v));
      if (!in_interval(bound, d)) {
        return fail(key + " = " + text(v) + " is outside its bound " + bound_text);
      }
      return true;
    }
    case SettingType::kReal: {
      if (!std::holds_alternative<double>(v)) return fail(key + ": expected a number");
      if (!in_interval(bound, std::get<double>(v))) {
        return fail(key + " = " + text(v) + " is outside its bound " + bound_text);
      }
      return true;
    }
    case SettingType::kChoice: {
      if (!std::holds_alternative<std::string>(v)) return fail(key + ": expected a name");
      const std::string& s = std::get<std::string>(v);
      if (std::find(bound.choices.begin(), bound.choices.end(), s) == bound.choices.end()) {
        return fail(key + " = '" + s + "' is not " + bound_text);
      }
      return true;
    }
    case SettingType::kReals: {
      if (!std::holds_alternative<std::vector<double>>(v)) {
        return fail(key + ": expected a list of numbers");
      }
      const auto& list = std::get<std::vector<double>>(v);
      bool ok = list.size() >= bound.min_size && list.size() <= bound.max_size;
      for (std::size_t i = 0; ok && i < list.size(); ++i) {
        ok = in_interval(bound, list[i]) &&
             !(bound.non_increasing && i > 0 && list[i] > list[i - 1]);
      }
      if (!ok) return fail(key + " = " + text(v) + " is outside its bound " + bound_text);
      return true;
    }
  }
  return fail(key + ": unknown type");
}

SettingValue SettingRow::parse(const std::string& raw) const {
  const std::string t = trim(raw);
  auto bad = [&]() -> InvalidArgument {
    return InvalidArgument(key + " = '" + raw + "': expected " + type_name(type) + ", " +
                           bound.text(type));
  };
  SettingValue v;
  switch (type) {
    case SettingType::kBool:
      if (t == "true" || t == "1" || t == "yes" || t == "on") {
        v = true;
      } else if (t == "false" || t == "0" || t == "no" || t == "off") {
        v = false;
      } else {
        throw bad();
      }
      break;
    case SettingType::kInt: {
      long long i = 0;
      const char* b = t.data();
      const char* e = t.data() + t.size();
      if (b != e && *b == '+') ++b;
      const auto r = std::from_chars(b, e, i);
      if (t.empty() || r.ec != std::errc() || r.ptr != e) throw bad();
      v = i;
      break;
    }
    case SettingType::kReal: {
      double d = 0.0;
      if (!parse_real(t, &d)) throw bad();
      v = d;
      break;
    }
    case SettingType::kChoice:
      v = t;
      break;
    case SettingType::kReals: {
      std::string s = t;
      if (!s.empty() && s.front() == '[' && s.back() == ']') s = s.substr(1, s.size() - 2);
      std::vector<double> list;
      std::stringstream in(s);
      std::string item;
      while (std::getline(in, item, ',')) {
        double d = 0.0;
        if (!parse_real(item, &d)) throw bad();
        list.push_back(d);
      }
      v = list;
      break;
    }
  }
  std::string why;
  if (!check(v, &why)) throw InvalidArgument(why);
  return v;
}

SettingRow bool_setting(std::string key, std::string member, bool value, std::string doc) {
  return {std::move(key), SettingType::kBool, std::move(member), value, SettingBound{},
          "flag",         std::move(doc)};
}
SettingRow int_setting(std::string key, std::string member, long long value, SettingBound bound,
                       std::string unit, std::string doc) {
  return {std::move(key),   SettingType::kInt, std::move(member), value,
          std::move(bound), std::move(unit),   std::move(doc)};
}
SettingRow real_setting(std::string key, std::string member, double value, SettingBound bound,
                        std::string unit, std::string doc) {
  return {std::move(key),   SettingType::kReal, std::move(member), value,
          std::move(bound), std::move(unit),    std::move(doc)};
}
SettingRow choice_setting(std::string key, std::string member, std::string value,
                          std::vector<std::string> choices, std::string doc) {
  return {std::move(key),
          SettingType::kChoice,
          std::move(member),
          std::move(value),
          SettingBound::one_of(std::move(choices)),
          "name",
          std::move(doc)};
}
SettingRow reals_setting(std::string key, std::string member, std::vector<double> value,
                         SettingBound bound, std::string unit, std::string doc) {
  return {std::move(key),   SettingType::kReals, std::move(member), std::move(value),
          std::move(bound), std::move(unit),     std::move(doc)};
}

// ----------------------------------------------------------------------------- settings

Settings::Settings(std::vector<SettingRow> table) : rows_(std::move(table)) {
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (rows_[i].key == rows_[j].key) {
        throw InvalidArgument("settings: the key '" + rows_[i].key + "' is declared twice");
      }
    }
    std::string why;
    if (!rows_[i].check(rows_[i].value, &why)) {
      throw InvalidArgument("settings: the default of " + why);
    }
    values_.push_back(rows_[i].value);
  }
}

std::size_t Settings::index_of(const std::string& key) const {
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    if (rows_[i].key == key) return i;
  }
  return rows_.size();
}

bool Settings::has(const std::string& key) const { return index_of(key) < rows_.size(); }

const SettingRow& Settings::row(const std::string& key) const {
  const std::size_t i = index_of(key);
  if (i == rows_.size()) {
    const std::string near = nearest_key(key);
    throw InvalidArgument("unknown setting '" + key + "'" +
                          (near.empty() ? std::string() : " (nearest: '" + near + "')"));
  }
  return rows_[i];
}

void Settings::set(const std::string& key, SettingValue value) {
  const SettingRow& r = row(key);
  if (r.type == SettingType::kReal && std::holds_alternative<long long>(value)) {
    value = static_cast<double>(std::get<long long>(value));
  }
  std::string why;
  if (!r.check(value, &why)) throw InvalidArgument(why);
  values_[index_of(key)] = std::move(value);
}

void Settings::set_text(const std::string& key, const std::string& text) {
  set(key, row(key).parse(text));
}

void Settings::set_assignment(const std::string& assignment) {
  const std::size_t eq = assignment.find('=');
  if (eq == std::string::npos) {
    throw InvalidArgument("setting '" + assignment + "': expected KEY=VALUE");
  }
  set_text(trim(assignment.substr(0, eq)), assignment.substr(eq + 1));
}

const SettingValue& Settings::value(const std::string& key) const {
  (void)row(key);
  return values_[index_of(key)];
}

bool Settings::boolean(const std::string& key) const { return std::get<bool>(value(key)); }
long long Settings::integer(const std::string& key) const {
  return std::get<long long>(value(key));
}
double Settings::real(const std::string& key) const { return std::get<double>(value(key)); }
const std::string& Settings::choice(const std::string& key) const {
  return std::get<std::string>(value(key));
}
const std::vector<double>& Settings::reals(const std::string& key) const {
  return std::get<std::vector<double>>(value(key));
}

bool Settings::is_set(const std::string& key) const { return !(value(key) == row(key).value); }

bool Settings::is_valid(std::string* why) const {
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    if (!rows_[i].check(values_[i], why)) return false;
  }
  return true;
}

std::string nearest_name(const std::string& name, const std::vector<std::string>& known) {
  std::string best;
  std::size_t best_d = std::numeric_limits<std::size_t>::max();
  for (const std::string& k : known) {
    const std::size_t d = edit_distance(name, k);
    if (d < best_d) {
      best_d = d;
      best = k;
    }
  }
  return best_d <= std::max<std::size_t>(2, name.size() / 3 + 1) ? best : std::string();
}

std::string Settings::nearest_key(const std::string& key) const {
  std::string best;
  std::size_t best_d = std::numeric_limits<std::size_t>::max();
  for (const SettingRow& r : rows_) {
    // The whole key, or its last part against the given text's last part (so "k" finds
    // "match.k" and "search.yaw_stepdeg" finds "search.yaw_step_deg").
    const std::size_t d =
        std::min(edit_distance(key, r.key), edit_distance(last_part(key), last_part(r.key)) + 1);
    if (d < best_d) {
      best_d = d;
      best = r.key;
    }
  }
  // Close: at most a third of the text (and at least 2 edits) away.
  const std::size_t limit = std::max<std::size_t>(2, last_part(key).size() / 3 + 1);
  return best_d <= limit ? best : std::string();
}

std::string Settings::canonical_text() const {
  std::string s;
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    s += rows_[i].key + "=" + rows_[i].text(values_[i]) + "\n";
  }
  return s;
}

}  // namespace lmalign
