// The check of an options struct's validation: each change of valid options, made alone, makes
// the call throw InvalidArgument with a message that names what was changed.
#pragma once

#include <gtest/gtest.h>

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "lmalign/core/error.hpp"

namespace lmalign::test {

template <typename Options>
struct OptionChange {
  std::function<void(Options&)> change;
  /// A fragment the error message must contain.
  std::string named;
};

/// For each change: a copy of `valid`, changed, given to `call`, must throw InvalidArgument
/// whose message contains the change's fragment (a test failure per change otherwise).
template <typename Options, typename Call>
void expect_each_change_named(const Options& valid, const Call& call,
                              const std::vector<OptionChange<Options>>& changes) {
  for (std::size_t i = 0; i < changes.size(); ++i) {
    Options o = valid;
    changes[i].change(o);
    std::string why = "no error";
    try {
      call(o);
    } catch (const InvalidArgument& e) {
      why = e.what();
    }
    EXPECT_NE(why.find(changes[i].named), std::string::npos)
        << "change " << i << " should name '" << changes[i].named << "': " << why;
  }
}

}  // namespace lmalign::test
