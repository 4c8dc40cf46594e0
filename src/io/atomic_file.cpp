// Atomic file output: temporary file beside the target, fsync, rename(2).
#include "lmalign/io/atomic_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

#include "lmalign/core/error.hpp"

namespace lmalign {
namespace {

std::atomic<unsigned long> temp_counter{0};

[[noreturn]] void throw_io(const std::string& path, int err) {
  throw IoError("cannot write '" + path + "': " + std::strerror(err));
}

/// fsyncs an already written file (by path). Returns 0 or an errno value.
int fsync_path(const std::string& file) {
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return errno;
  int err = 0;
  if (::fsync(fd) != 0) err = errno;
  if (::close(fd) != 0 && err == 0) err = errno;
  return err;
}

/// Best-effort fsync of the directory holding `path`, so the rename itself is durable.
void fsync_parent_directory(const std::string& path) {
  const auto slash = path.find_last_of('/');
  const std::string dir =
      slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

}  // namespace

void write_file_atomically(const std::string& path,
                           const std::function<void(std::ostream&)>& write) {
  const std::string temp =
      path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(temp_counter.fetch_add(1));
  // Exclusive creation: never clobber a file that happens to have the temporary name.
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) throw_io(path, errno);
  ::close(fd);

  const auto remove_temp = [&temp] { std::remove(temp.c_str()); };
  try {
    {
      errno = 0;
      std::ofstream out(temp, std::ios::binary | std::ios::trunc);
      if (!out) throw_io(path, errno != 0 ? errno : EIO);
      write(out);  // exceptions from the callback propagate unchanged
      errno = 0;
      out.flush();
      if (!out) throw_io(path, errno != 0 ? errno : EIO);
      errno = 0;
      out.close();
      if (out.fail()) throw_io(path, errno != 0 ? errno : EIO);
    }
    if (const int err = fsync_path(temp); err != 0) throw_io(path, err);
    if (std::rename(temp.c_str(), path.c_str()) != 0) throw_io(path, errno);
  } catch (...) {
    remove_temp();
    throw;
  }
  fsync_parent_directory(path);
}

}  // namespace lmalign
