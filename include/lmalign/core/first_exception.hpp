// Exceptions and OpenMP: an exception that leaves a parallel region (or skips a worksharing
// construct some threads of the team reach) ends the process with std::terminate, which would
// take a Python interpreter or a CLI down with it instead of a one-line error. Every OpenMP
// region of the library whose body can throw (a validation, an allocation, a callback) runs each
// iteration, and each allocation made outside the worksharing loop, through
// FirstException::capture(), and calls rethrow() after the region.
#pragma once

#include <atomic>
#include <exception>
#include <mutex>
#include <utility>

namespace lmalign {

/// Keeps the first exception thrown by the bodies it runs (first in time: with several threads
/// which one that is may vary; each is an error of the same input). Thread-safe.
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
      failed_.store(true, std::memory_order_relaxed);
    }
  }
  /// True once a body has thrown: loops may skip their remaining iterations.
  bool failed() const noexcept { return failed_.load(std::memory_order_relaxed); }
  /// Throws the kept exception, if any. Call outside the parallel region.
  void rethrow() const {
    if (first_) std::rethrow_exception(first_);
  }

 private:
  std::mutex mutex_;
  std::exception_ptr first_;
  std::atomic<bool> failed_{false};
};

}  // namespace lmalign
