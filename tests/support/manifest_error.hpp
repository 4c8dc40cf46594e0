// The message of parse_manifest() on a manifest text (file "m.yaml", base "/base"), or "" when
// it parses: the merge tests' check of one-line errors.
#pragma once

#include <string>

#include "lmalign/core/error.hpp"
#include "lmalign/merge/manifest.hpp"

namespace lmalign::test {

inline std::string manifest_error(const std::string& yaml) {
  try {
    parse_manifest(yaml, "m.yaml", "/base");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace lmalign::test
