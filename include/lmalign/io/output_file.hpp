// The one writer of every file lmalign writes (maps, JSON, CSV, YAML, PLY, reports, plots): it
// never destroys what an output path points at (docs/robustness.md, "Outputs").
//
//   "-"                         standard output, written in place
//   a path naming this process's standard output (/dev/stdout, /dev/fd/1, a file that fd 1 is)
//                               the same: standard output, in place
//   a regular file, a new path  a temporary file in the same directory, fsync, rename over it:
//                               a reader never sees half a file, a failure leaves it as it was
//   a symlink                   followed to its final target, which is then written as above
//                               (atomically there if it is a regular file or does not exist);
//                               the link stays a link
//   a FIFO, a character device, a socket
//                               written in place (opened for writing; a socket is connected to)
//   a directory, a block device, a path whose directory does not exist
//                               refused (IoError), nothing written or created
#pragma once

#include <functional>
#include <iosfwd>
#include <string>

namespace lmalign {

/// What an output path names, as write_output() treats it.
enum class OutputKind {
  kStandardOutput,  ///< "-", or a path that names this process's standard output
  kNewFile,         ///< nothing there yet (its directory exists): created atomically
  kRegularFile,     ///< an existing regular file: replaced atomically
  kInPlace,         ///< a FIFO, a character device or a socket: written in place
};

/// An output path checked: what it names and where the bytes go.
struct OutputTarget {
  std::string path;  ///< as given (what messages name)
  /// What is written: the final target of the symlinks `path` goes through (kNewFile,
  /// kRegularFile), else `path` itself.
  std::string resolved;
  OutputKind kind = OutputKind::kNewFile;
  bool through_symlink = false;
  bool is_socket = false;  ///< kInPlace: connected to rather than opened
};

/// True for "-" and for a path that names this process's standard output (the same device and
/// inode as file descriptor 1: /dev/stdout, /dev/fd/1, or the file that standard output was
/// redirected to).
bool names_standard_output(const std::string& path);

/// Checks an output path before any work, without writing anything. Throws IoError naming the
/// path and what is wrong: an empty path, a directory (or a path ending in '/'), a block device,
/// a path whose directory does not exist (naming the directory), a symlink loop, an existing
/// regular file that is not writable.
OutputTarget check_output_path(const std::string& path);

/// Writes `write(stream)` to `path` as the header says: standard output and FIFOs, character
/// devices and sockets in place; regular files and new paths (directly or through symlinks)
/// through a temporary file in the same directory, flushed, fsynced and renamed over the final
/// target (an existing file keeps its permission bits). Throws IoError naming `path` and the
/// OS reason for every failure of the check (check_output_path) or of a write (no space, a
/// broken pipe, an I/O error): then a regular file is left as it was and no temporary file
/// remains. An exception from `write` propagates unchanged after the same clean-up. Standard
/// output needs SIGPIPE ignored (the CLI does; Python does) for a closed pipe to be an error
/// rather than the end of the process.
void write_output(const std::string& path, const std::function<void(std::ostream&)>& write);

/// Creates an output folder and its missing parents (an output folder given with -o may be
/// new). Throws IoError naming `folder` when it is "-" or names the standard output, when it
/// exists as something other than a folder (or a symlink to one), or cannot be created.
void create_output_folder(const std::string& folder);

}  // namespace lmalign
