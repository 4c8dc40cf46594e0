// Atomic file output: write to a temporary file beside the target, then rename over it.
// A reader never sees a half-written file, and a failure leaves the target untouched.
#pragma once

#include <functional>
#include <iosfwd>
#include <string>

namespace lmalign {

/// Calls `write(stream)` on a temporary file in the directory of `path`, flushes and fsyncs it,
/// then renames it to `path`. If `write` throws, or any I/O step fails, the temporary file is
/// removed, `path` is left as it was, and the exception (IoError for I/O failures, naming the
/// path and the OS reason) propagates.
void write_file_atomically(const std::string& path,
                           const std::function<void(std::ostream&)>& write);

}  // namespace lmalign
