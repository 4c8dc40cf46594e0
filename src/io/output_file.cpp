// The one output writer (include/lmalign/io/output_file.hpp).
#include "lmalign/io/output_file.hpp"

#include <fcntl.h>
#include <limits.h>
#include <pthread.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <ostream>
#include <streambuf>
#include <string>

#include "lmalign/core/error.hpp"

namespace lmalign {
namespace {

std::atomic<unsigned long> temp_counter{0};

// Symlinks followed before a chain counts as a loop (Linux's own limit).
constexpr int kMaxSymlinkHops = 40;

[[noreturn]] void fail(const std::string& path, const std::string& why) {
  throw IoError((path == "-" ? std::string("cannot write the standard output ('-')")
                             : "cannot write '" + path + "'") +
                ": " + why);
}

[[noreturn]] void fail_errno(const std::string& path, int err) {
  fail(path, std::strerror(err != 0 ? err : EIO));
}

std::string directory_of(const std::string& path) {
  const auto slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  if (slash == 0) return "/";
  return path.substr(0, slash);
}

// Refuses a new file's path whose directory is missing or not a directory (naming it).
void require_directory(const std::string& path, const std::string& file) {
  const std::string dir = directory_of(file);
  struct stat st {};
  if (::stat(dir.c_str(), &st) != 0) {
    if (errno == ENOENT || errno == ENOTDIR)
      fail(path, "the directory '" + dir + "' does not exist");
    fail(path, "cannot reach the directory '" + dir + "': " + std::strerror(errno));
  }
  if (!S_ISDIR(st.st_mode)) fail(path, "'" + dir + "' is not a directory");
}

// Writes through a file descriptor, keeping the first error (errno) instead of throwing, so
// that std::ostream code above it needs nothing special. SIGPIPE is blocked in this thread
// while it writes and a SIGPIPE it caused is consumed: a closed pipe is EPIPE, never the end
// of the process.
class FdBuffer : public std::streambuf {
 public:
  explicit FdBuffer(int fd) : fd_(fd) { setp(buffer_, buffer_ + sizeof(buffer_)); }
  int error() const { return error_; }

 protected:
  int_type overflow(int_type ch) override {
    if (!drain()) return traits_type::eof();
    if (!traits_type::eq_int_type(ch, traits_type::eof())) {
      *pptr() = traits_type::to_char_type(ch);
      pbump(1);
    }
    return traits_type::not_eof(ch);
  }
  int sync() override { return drain() ? 0 : -1; }

 private:
  bool drain() {
    const char* p = pbase();
    std::size_t n = static_cast<std::size_t>(pptr() - pbase());
    setp(buffer_, buffer_ + sizeof(buffer_));
    if (error_ != 0) return false;
    if (n == 0) return true;
    sigset_t pipe_only, old;
    sigemptyset(&pipe_only);
    sigaddset(&pipe_only, SIGPIPE);
    sigset_t pending;
    sigemptyset(&pending);
    ::sigpending(&pending);
    const bool was_pending = sigismember(&pending, SIGPIPE) == 1;
    ::pthread_sigmask(SIG_BLOCK, &pipe_only, &old);
    while (n > 0) {
      const ssize_t w = ::write(fd_, p, n);
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) {
        error_ = w < 0 ? errno : EIO;
        break;
      }
      p += w;
      n -= static_cast<std::size_t>(w);
    }
    if (error_ == EPIPE && !was_pending) {
      const struct timespec zero {};
      while (::sigtimedwait(&pipe_only, nullptr, &zero) < 0 && errno == EINTR) {
      }
    }
    ::pthread_sigmask(SIG_SETMASK, &old, nullptr);
    return error_ == 0;
  }

  int fd_;
  int error_ = 0;
  char buffer_[1 << 16];
};

// Calls write(stream) on fd and flushes; throws IoError naming `path` on a write error.
void write_to_fd(const std::string& path, int fd, const std::function<void(std::ostream&)>& write) {
  FdBuffer buffer(fd);
  std::ostream out(&buffer);
  write(out);  // exceptions from the callback propagate unchanged
  out.flush();
  if (buffer.error() != 0) fail_errno(path, buffer.error());
  if (!out) fail_errno(path, EIO);
}

int connect_socket(const std::string& path, const std::string& resolved) {
  sockaddr_un address{};
  address.sun_family = AF_UNIX;
  if (resolved.size() >= sizeof(address.sun_path)) fail(path, "socket path too long");
  std::memcpy(address.sun_path, resolved.c_str(), resolved.size() + 1);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) fail_errno(path, errno);
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof(address)) != 0) {
    const int err = errno;
    ::close(fd);
    fail(path, std::string("cannot connect to the socket: ") + std::strerror(err));
  }
  return fd;
}

void write_in_place(const OutputTarget& t, const std::function<void(std::ostream&)>& write) {
  int fd = -1;
  if (t.is_socket) {
    fd = connect_socket(t.path, t.resolved);
  } else {
    do {
      fd = ::open(t.resolved.c_str(), O_WRONLY | O_NOCTTY | O_CLOEXEC);
    } while (fd < 0 && errno == EINTR);
    if (fd < 0) fail_errno(t.path, errno);
  }
  try {
    write_to_fd(t.path, fd, write);
  } catch (...) {
    ::close(fd);
    throw;
  }
  if (::close(fd) != 0 && errno != EINTR) fail_errno(t.path, errno);
}

// A temporary name in the directory of `file` (short enough for any file name).
std::string temporary_name(const std::string& file) {
  const std::string tag =
      ".tmp." + std::to_string(::getpid()) + "." + std::to_string(temp_counter.fetch_add(1));
  const std::string base = file.substr(file.find_last_of('/') + 1);
  if (base.size() + tag.size() <= NAME_MAX) return file + tag;
  const std::string dir = directory_of(file);
  return (dir == "/" ? dir : dir + "/") + ".lmalign" + tag;
}

void write_atomically(const OutputTarget& t, const std::function<void(std::ostream&)>& write) {
  const std::string& file = t.resolved;
  struct stat before {};
  const bool existed = t.kind == OutputKind::kRegularFile && ::stat(file.c_str(), &before) == 0;
  const std::string temp = temporary_name(file);
  // Exclusive creation: never clobber a file that happens to have the temporary name.
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) fail_errno(t.path, errno);
  bool open = true;
  try {
    write_to_fd(t.path, fd, write);
    // The file it replaces keeps its permission bits (best effort: not every file system has
    // them).
    if (existed) (void)::fchmod(fd, before.st_mode & 07777);
    if (::fsync(fd) != 0 && errno != EINVAL) fail_errno(t.path, errno);
    open = false;
    if (::close(fd) != 0) fail_errno(t.path, errno);
    if (::rename(temp.c_str(), file.c_str()) != 0) fail_errno(t.path, errno);
  } catch (...) {
    if (open) ::close(fd);
    ::unlink(temp.c_str());
    throw;
  }
  // Best effort: fsync the directory, so that the rename itself is durable.
  const int dir = ::open(directory_of(file).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir >= 0) {
    ::fsync(dir);
    ::close(dir);
  }
}

// What a node that exists is, for an output (`path` names it in messages).
void classify_existing(const std::string& path, const struct stat& st, OutputTarget* t) {
  if (S_ISREG(st.st_mode)) {
    if (::access(t->resolved.c_str(), W_OK) != 0) fail_errno(path, errno);
    t->kind = OutputKind::kRegularFile;
  } else if (S_ISFIFO(st.st_mode) || S_ISCHR(st.st_mode)) {
    t->kind = OutputKind::kInPlace;
  } else if (S_ISSOCK(st.st_mode)) {
    t->kind = OutputKind::kInPlace;
    t->is_socket = true;
  } else if (S_ISDIR(st.st_mode)) {
    fail(path, "it is a directory");
  } else if (S_ISBLK(st.st_mode)) {
    fail(path, "it is a block device (lmalign writes no block device)");
  } else {
    fail(path, "it is neither a file, a FIFO, a character device nor a socket");
  }
}

// The final name a dangling symlink chain leads to (which does not exist yet).
std::string dangling_target(const std::string& path) {
  std::string current = path;
  for (int hop = 0; hop < kMaxSymlinkHops; ++hop) {
    struct stat st {};
    if (::lstat(current.c_str(), &st) != 0) {
      if (errno == ENOENT) return current;
      fail_errno(path, errno);
    }
    if (!S_ISLNK(st.st_mode)) return current;
    std::string target(static_cast<std::size_t>(PATH_MAX), '\0');
    const ssize_t n = ::readlink(current.c_str(), target.data(), target.size());
    if (n < 0) fail_errno(path, errno);
    target.resize(static_cast<std::size_t>(n));
    current = (!target.empty() && target[0] == '/') ? target : directory_of(current) + "/" + target;
  }
  fail(path, "too many levels of symbolic links");
}

}  // namespace

bool names_standard_output(const std::string& path) {
  if (path == "-") return true;
  struct stat a {
  }, b{};
  return !path.empty() && ::stat(path.c_str(), &a) == 0 && ::fstat(STDOUT_FILENO, &b) == 0 &&
         a.st_dev == b.st_dev && a.st_ino == b.st_ino;
}

OutputTarget check_output_path(const std::string& path) {
  OutputTarget t;
  t.path = path;
  t.resolved = path;
  if (path.empty()) fail(path, "an empty path");
  if (names_standard_output(path)) {
    t.kind = OutputKind::kStandardOutput;
    return t;
  }
  if (path.back() == '/') fail(path, "it names a directory");
  struct stat ls {};
  if (::lstat(path.c_str(), &ls) != 0) {
    if (errno != ENOENT && errno != ENOTDIR) fail_errno(path, errno);
    require_directory(path, path);
    t.kind = OutputKind::kNewFile;
    return t;
  }
  if (!S_ISLNK(ls.st_mode)) {
    classify_existing(path, ls, &t);
    return t;
  }
  t.through_symlink = true;
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    if (S_ISREG(st.st_mode)) {
      char* real = ::realpath(path.c_str(), nullptr);
      if (real == nullptr) fail_errno(path, errno);
      t.resolved = real;
      std::free(real);
    }
    classify_existing(path, st, &t);
    return t;
  }
  if (errno == ELOOP) fail(path, "too many levels of symbolic links");
  if (errno != ENOENT) fail_errno(path, errno);
  // A dangling link: the file it names is created there, and the link then leads to it.
  t.resolved = dangling_target(path);
  require_directory(path, t.resolved);
  t.kind = OutputKind::kNewFile;
  return t;
}

void write_output(const std::string& path, const std::function<void(std::ostream&)>& write) {
  const OutputTarget t = check_output_path(path);
  switch (t.kind) {
    case OutputKind::kStandardOutput:
      // Whatever this process buffered for standard output goes first.
      std::cout.flush();
      std::fflush(stdout);
      write_to_fd(path, STDOUT_FILENO, write);
      return;
    case OutputKind::kInPlace:
      write_in_place(t, write);
      return;
    case OutputKind::kNewFile:
    case OutputKind::kRegularFile:
      write_atomically(t, write);
      return;
  }
}

void create_output_folder(const std::string& folder) {
  if (folder.empty()) throw IoError("cannot create the output folder '': an empty path");
  if (names_standard_output(folder)) {
    throw IoError("cannot create the output folder '" + folder +
                  "': an output folder cannot be the standard output");
  }
  std::error_code ec;
  std::filesystem::create_directories(folder, ec);
  if (ec) throw IoError("cannot create the output folder '" + folder + "': " + ec.message());
  if (!std::filesystem::is_directory(folder, ec)) {
    throw IoError("cannot create the output folder '" + folder +
                  "': it exists and is not a folder");
  }
}

}  // namespace lmalign
