// Names of enum values, written once: a table of {value, name} pairs per enum and three small
// functions that read it both ways. Every enum of lmalign that has a name in a file, an option or
// a message (scale mode, up axis, robust kernel, confidence, map scale, ...) keeps its names in
// one such table beside its to_string and parse functions.
//
//   inline constexpr EnumName<UpAxis> kUpAxisNames[] = {
//       {UpAxis::kX, "x"}, {UpAxis::kY, "y"}, {UpAxis::kZ, "z"}};
//   name_of(kUpAxisNames, UpAxis::kY)            -> "y"
//   find_enum(kUpAxisNames, "z")                 -> UpAxis::kZ (nullopt for an unknown name)
//   parse_enum(kUpAxisNames, "up axis", "w")     -> throws InvalidArgument
//                                                   "unknown up axis 'w' (known: x, y, z)"
//
// A value may have several names (aliases): name_of gives the first, every one parses.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

#include "lmalign/core/error.hpp"

namespace lmalign {

template <typename E>
struct EnumName {
  E value;
  const char* name;
};

/// The name of `value`: the first row with it; "?" when no row has it.
template <typename E, std::size_t N>
constexpr const char* name_of(const EnumName<E> (&table)[N], E value) {
  for (const EnumName<E>& row : table) {
    if (row.value == value) return row.name;
  }
  return "?";
}

/// The value named `name`, or nullopt.
template <typename E, std::size_t N>
std::optional<E> find_enum(const EnumName<E> (&table)[N], std::string_view name) {
  for (const EnumName<E>& row : table) {
    if (name == row.name) return row.value;
  }
  return std::nullopt;
}

/// Every name of the table in order, separated by `separator`: "x, y, z".
template <typename E, std::size_t N>
std::string enum_names(const EnumName<E> (&table)[N], std::string_view separator = ", ") {
  std::string out;
  for (std::size_t i = 0; i < N; ++i) {
    if (i > 0) out += separator;
    out += table[i].name;
  }
  return out;
}

/// The value named `name`; throws InvalidArgument "unknown WHAT 'NAME' (known: a, b, c)".
template <typename E, std::size_t N>
E parse_enum(const EnumName<E> (&table)[N], std::string_view what, const std::string& name) {
  if (const std::optional<E> v = find_enum(table, name)) return *v;
  throw InvalidArgument("unknown " + std::string(what) + " '" + name +
                        "' (known: " + enum_names(table) + ")");
}

}  // namespace lmalign
