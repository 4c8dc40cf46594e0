// The one output writer (io/output_file.hpp): what each kind of path gets, and that nothing it
// points at is destroyed. Nodes are made in a scratch folder; device nodes need root (mknod),
// and those cases are skipped otherwise.
#include <fcntl.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "lmalign/core/error.hpp"
#include "lmalign/io/output_file.hpp"
#include "support/socket_listener.hpp"
#include "support/temp_dir.hpp"

namespace lmalign {
namespace {

namespace fs = std::filesystem;

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

void write_text(const std::string& path, const std::string& text) {
  write_output(path, [&](std::ostream& out) { out << text; });
}

// The IoError's message, or "" when write_text succeeds.
std::string write_error(const std::string& path, const std::string& text) {
  try {
    write_text(path, text);
  } catch (const IoError& e) {
    return e.what();
  }
  return "";
}

std::size_t entries(const std::string& dir) {
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++n;
  return n;
}

// Standard output pointed at `fd` for the scope (the writer's "-" is file descriptor 1).
class StdoutTo {
 public:
  explicit StdoutTo(int fd) : saved_(::dup(STDOUT_FILENO)) {
    std::fflush(stdout);
    ::dup2(fd, STDOUT_FILENO);
  }
  ~StdoutTo() {
    std::fflush(stdout);
    ::dup2(saved_, STDOUT_FILENO);
    ::close(saved_);
  }

 private:
  int saved_;
};

TEST(OutputFile, ANewPathAndARegularFileAreWrittenAtomicallyKeepingThePermissionBits) {
  test::ScratchDir dir("output");
  const std::string file = dir.file("out.json");
  EXPECT_EQ(check_output_path(file).kind, OutputKind::kNewFile);
  write_text(file, "first\n");
  EXPECT_EQ(read_file(file), "first\n");
  ASSERT_EQ(::chmod(file.c_str(), 0640), 0);
  EXPECT_EQ(check_output_path(file).kind, OutputKind::kRegularFile);
  write_text(file, "second\n");
  EXPECT_EQ(read_file(file), "second\n");
  struct stat st {};
  ASSERT_EQ(::stat(file.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 07777, 0640u);
  EXPECT_EQ(entries(dir.path()), 1u) << "a temporary file was left behind";
  // A failing callback leaves the file as it was, and no temporary file.
  EXPECT_THROW(write_output(file,
                            [](std::ostream& out) {
                              out << "half";
                              throw InvalidArgument("stop");
                            }),
               InvalidArgument);
  EXPECT_EQ(read_file(file), "second\n");
  EXPECT_EQ(entries(dir.path()), 1u);
}

TEST(OutputFile, ASymlinkIsWrittenThroughToItsTargetAndStaysALink) {
  test::ScratchDir dir("output");
  write_text(dir.file("real.json"), "old\n");
  fs::create_symlink("real.json", dir.file("link.json"));
  fs::create_symlink("link.json", dir.file("link2.json"));  // a chain of links
  const OutputTarget t = check_output_path(dir.file("link2.json"));
  EXPECT_TRUE(t.through_symlink);
  EXPECT_EQ(t.kind, OutputKind::kRegularFile);
  EXPECT_EQ(fs::path(t.resolved).filename(), "real.json");
  write_text(dir.file("link2.json"), "new\n");
  EXPECT_TRUE(fs::is_symlink(dir.file("link.json")));
  EXPECT_TRUE(fs::is_symlink(dir.file("link2.json")));
  EXPECT_EQ(read_file(dir.file("real.json")), "new\n");
  EXPECT_EQ(entries(dir.path()), 3u);
  // A dangling link: the file it names is created, in the link's target folder.
  fs::create_directories(dir.file("sub"));
  fs::create_symlink("sub/made.json", dir.file("dangling.json"));
  write_text(dir.file("dangling.json"), "made\n");
  EXPECT_TRUE(fs::is_symlink(dir.file("dangling.json")));
  EXPECT_EQ(read_file(dir.file("sub/made.json")), "made\n");
  // ... unless that folder does not exist: an error naming it, nothing created.
  fs::create_symlink("missing/x.json", dir.file("nowhere.json"));
  EXPECT_NE(write_error(dir.file("nowhere.json"), "x").find("/missing' does not exist"),
            std::string::npos);
  EXPECT_FALSE(fs::exists(dir.file("missing")));
  // A loop of links is an error, not a hang.
  fs::create_symlink("loop_b", dir.file("loop_a"));
  fs::create_symlink("loop_a", dir.file("loop_b"));
  EXPECT_NE(write_error(dir.file("loop_a"), "x").find("symbolic links"), std::string::npos);
  EXPECT_TRUE(fs::is_symlink(dir.file("loop_a")));
}

TEST(OutputFile, AFifoIsWrittenInPlaceAndStaysAFifo) {
  test::ScratchDir dir("output");
  const std::string fifo = dir.file("f");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(check_output_path(fifo).kind, OutputKind::kInPlace);
  std::string received;
  std::thread reader([&] { received = read_file(fifo); });
  const std::string big(300000, 'x');  // more than a pipe holds: the writer waits for the reader
  write_text(fifo, big);
  reader.join();
  EXPECT_EQ(received, big);
  struct stat st {};
  ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
  EXPECT_EQ(entries(dir.path()), 1u);
}

TEST(OutputFile, AFifoWhoseReaderLeavesIsABrokenPipeErrorNotTheEndOfTheProcess) {
  test::ScratchDir dir("output");
  const std::string fifo = dir.file("f");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::thread reader([&] {
    const int fd = ::open(fifo.c_str(), O_RDONLY);
    char c = 0;
    (void)::read(fd, &c, 1);
    ::close(fd);
  });
  const std::string message = write_error(fifo, std::string(1 << 20, 'x'));
  reader.join();
  EXPECT_NE(message.find("cannot write '" + fifo + "': Broken pipe"), std::string::npos) << message;
  sigset_t pending;
  ::sigpending(&pending);
  EXPECT_FALSE(sigismember(&pending, SIGPIPE)) << "the writer left a SIGPIPE pending";
}

TEST(OutputFile, ASocketIsConnectedToAndWrittenInPlace) {
  test::ScratchDir dir("output");
  const std::string path = dir.file("sock");
  test::SocketListener listener(path);
  EXPECT_TRUE(check_output_path(path).is_socket);
  write_text(path, "over the socket\n");
  EXPECT_EQ(listener.received(), "over the socket\n");
  struct stat st {};
  ASSERT_EQ(::lstat(path.c_str(), &st), 0);
  EXPECT_TRUE(S_ISSOCK(st.st_mode));
}

TEST(OutputFile, DashAndPathsNamingTheStandardOutputWriteToFileDescriptorOne) {
  test::ScratchDir dir("output");
  const std::string captured = dir.file("captured.txt");
  const int fd = ::open(captured.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  ASSERT_GE(fd, 0);
  {
    StdoutTo redirect(fd);
    EXPECT_TRUE(names_standard_output("-"));
    EXPECT_TRUE(names_standard_output("/dev/stdout"));
    EXPECT_TRUE(names_standard_output(captured));  // the file standard output was sent to
    EXPECT_FALSE(names_standard_output(dir.file("other.txt")));
    write_text("-", "one\n");
    write_text("/dev/stdout", "two\n");
  }
  ::close(fd);
  EXPECT_EQ(read_file(captured), "one\ntwo\n");
  EXPECT_EQ(entries(dir.path()), 1u);
}

TEST(OutputFile, AClosedStandardOutputPipeIsAnErrorNamingIt) {
  int pipe_fds[2];
  ASSERT_EQ(::pipe(pipe_fds), 0);
  ::close(pipe_fds[0]);
  std::string message;
  {
    StdoutTo redirect(pipe_fds[1]);
    message = write_error("-", "lost\n");
  }
  ::close(pipe_fds[1]);
  EXPECT_NE(message.find("cannot write the standard output ('-'): Broken pipe"), std::string::npos)
      << message;
}

TEST(OutputFile, MissingDirectoriesDirectoriesAndEmptyPathsAreErrorsAndCreateNothing) {
  test::ScratchDir dir("output");
  write_text(dir.file("regular"), "a file\n");
  const std::size_t before = entries(dir.path());
  const std::string missing = dir.file("no/such/dir/x.json");
  EXPECT_NE(write_error(missing, "x")
                .find("the directory '" + dir.file("no/such/dir") + "' does not exist"),
            std::string::npos);
  EXPECT_FALSE(fs::exists(dir.file("no")));
  EXPECT_NE(write_error(dir.file("regular/x.json"), "x").find("is not a directory"),
            std::string::npos);
  EXPECT_NE(write_error(dir.path(), "x").find("it is a directory"), std::string::npos);
  EXPECT_NE(write_error(dir.path() + "/", "x").find("names a directory"), std::string::npos);
  EXPECT_NE(write_error("", "x").find("an empty path"), std::string::npos);
  EXPECT_EQ(entries(dir.path()), before);
  EXPECT_EQ(read_file(dir.file("regular")), "a file\n");
  // An output folder is created (with its parents); "-" is no folder.
  create_output_folder(dir.file("made/deeper"));
  EXPECT_TRUE(fs::is_directory(dir.file("made/deeper")));
  EXPECT_THROW(create_output_folder("-"), IoError);
  EXPECT_THROW(create_output_folder(dir.file("regular")), IoError);
}

TEST(OutputFile, DeviceNodesAreWrittenInPlaceAndAFullDeviceIsAnError) {
  if (::geteuid() != 0) GTEST_SKIP() << "mknod needs root";
  test::ScratchDir dir("output");
  // Copies of /dev/null (1, 3) and /dev/full (1, 7), and a block device (loop0: 7, 0).
  const std::string null = dir.file("null"), full = dir.file("full"), block = dir.file("block");
  ASSERT_EQ(::mknod(null.c_str(), S_IFCHR | 0666, makedev(1, 3)), 0);
  ASSERT_EQ(::mknod(full.c_str(), S_IFCHR | 0666, makedev(1, 7)), 0);
  ASSERT_EQ(::mknod(block.c_str(), S_IFBLK | 0600, makedev(7, 0)), 0);
  write_text(null, "discarded\n");
  const std::string message = write_error(full, "no room\n");
  EXPECT_NE(message.find("cannot write '" + full + "': No space left on device"), std::string::npos)
      << message;
  EXPECT_NE(write_error(block, "x").find("block device"), std::string::npos);
  for (const std::string& node : {null, full}) {
    struct stat st {};
    ASSERT_EQ(::lstat(node.c_str(), &st), 0);
    EXPECT_TRUE(S_ISCHR(st.st_mode)) << node << " was replaced";
  }
  struct stat st {};
  ASSERT_EQ(::lstat(block.c_str(), &st), 0);
  EXPECT_TRUE(S_ISBLK(st.st_mode));
  EXPECT_EQ(entries(dir.path()), 3u);
}

}  // namespace
}  // namespace lmalign
