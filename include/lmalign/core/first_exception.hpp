// Exceptions and OpenMP: an exception that leaves a parallel region ends the process
// (std::terminate), which would take a Python interpreter or a CLI down with it instead of a
// one-line error. Loops whose body can throw (a validation, an allocation) run it through
// FirstException::capture() and call rethrow() after the region.
#pragma once

#include <exception>
#include <mutex>
#include <utility>

namespace lmalign {

/// Keeps the first exception thrown by the bodies it runs (first in time: with several threads
/// which one that is may vary; each is an error of the same input).
class FirstException {
 public:
  /// Runs body(); an exception it throws is kept (if it is the first) instead of propagating.
  template <typename Body>
  void capture(Body&& body) noexcept {
    try {
      std::forward<Body>(body)();
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!first_) first_ = std::current_exception();
    }
  }
  /// Throws the kept exception, if any. Call outside the parallel region.
  void rethrow() const {
    if (first_) std::rethrow_exception(first_);
  }

 private:
  std::mutex mutex_;
  std::exception_ptr first_;
};

}  // namespace lmalign
