// Every output of the real `lmalign` binary goes through the one writer (io/output_file.hpp,
// docs/robustness.md "Outputs"): a device, a FIFO, a socket and a symlink stay what they were;
// "-" (and /dev/stdout) is the standard output, with the human summary then on standard error;
// a write error is a non-zero exit with one line naming the path and no "written" line; a
// missing directory is an error naming it. Small synthetic maps and the `base` preset: these
// tests exercise the plumbing, not the alignment.
#include <fcntl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "lmalign/core/geometry.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/map/transform.hpp"
#include "support/run_cli.hpp"
#include "support/socket_listener.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

namespace fs = std::filesystem;
using test::expect_one_line_error;
using test::shell_quote;

bool is_node(const std::string& path, mode_t type) {
  struct stat st {};
  return ::lstat(path.c_str(), &st) == 0 && (st.st_mode & S_IFMT) == type;
}

class CliOutputs : public test::CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    const Map target = test::map_from_points(test::room_points(200, 7), 8);
    write_map(path("target.txt"), target);
    write_map(path("source.txt"),
              transform_map(target, pose_from_xyz_rpy_deg(0.02, 0, 0, 0, 0, 2)));
    align_ = "align " + shell_quote(path("source.txt")) + " " + shell_quote(path("target.txt")) +
             " --strategy base ";
  }
  std::string align_;
};

TEST_F(CliOutputs, ACopyOfDevFullStaysADeviceAndTheWriteErrorIsOneLineWithoutAWrittenLine) {
  if (::geteuid() != 0) GTEST_SKIP() << "mknod needs root";
  const std::string full = path("full");
  ASSERT_EQ(::mknod(full.c_str(), S_IFCHR | 0666, makedev(1, 7)), 0);
  const test::CliRun r = run(align_ + "--json " + shell_quote(full));
  expect_one_line_error(r, "cannot write '" + full + "': No space left on device", "--json full");
  EXPECT_EQ(r.out.find("written"), std::string::npos) << r.out;
  EXPECT_TRUE(is_node(full, S_IFCHR)) << "the device node was replaced";
  // The same for a map output, and for a copy of /dev/null (written, and still a device).
  expect_one_line_error(run(align_ + "--aligned-out " + shell_quote(full)), "No space left",
                        "--aligned-out full");
  const std::string null = path("null");
  ASSERT_EQ(::mknod(null.c_str(), S_IFCHR | 0666, makedev(1, 3)), 0);
  const test::CliRun ok = run(align_ + "--json " + shell_quote(null));
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_NE(ok.out.find("JSON written to " + null), std::string::npos);
  EXPECT_TRUE(is_node(null, S_IFCHR));
  EXPECT_TRUE(is_node(full, S_IFCHR));
}

TEST_F(CliOutputs, AFifoGetsTheJsonInPlaceAndStaysAFifo) {
  const std::string fifo = path("f");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] { received = test::read_text(fifo); });
  const test::CliRun r = run(align_ + "--json " + shell_quote(fifo));
  reader.join();
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(received)["results"].size(), 1u);
  EXPECT_TRUE(is_node(fifo, S_IFIFO)) << "the FIFO was replaced";
}

TEST_F(CliOutputs, ASocketGetsTheJson) {
  const std::string sock = path("s");
  test::SocketListener listener(sock);
  const test::CliRun r = run(align_ + "--json " + shell_quote(sock));
  const std::string received = listener.received();
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(received)["results"].size(), 1u);
  EXPECT_TRUE(is_node(sock, S_IFSOCK));
}

TEST_F(CliOutputs, ASymlinkIsWrittenThroughAndStaysALink) {
  std::ofstream(path("real.json")) << "old\n";
  fs::create_symlink("real.json", path("link.json"));
  const test::CliRun r = run(align_ + "--json " + shell_quote(path("link.json")));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::is_symlink(path("link.json")));
  EXPECT_EQ(nlohmann::json::parse(test::read_text(path("real.json")))["results"].size(), 1u);
  // A map through a link: the map lands in the target, the link stays.
  fs::create_symlink("aligned_target.txt", path("aligned_link.txt"));
  ASSERT_EQ(run(align_ + "--aligned-out " + shell_quote(path("aligned_link.txt"))).exit_code, 0);
  EXPECT_TRUE(fs::is_symlink(path("aligned_link.txt")));
  EXPECT_EQ(read_map(path("aligned_target.txt")).landmarks.size(),
            read_map(path("source.txt")).landmarks.size());
}

TEST_F(CliOutputs, DashIsTheStandardOutputAndTheSummaryMovesToStandardError) {
  const test::CliRun r = run(align_ + "--json -");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);  // nothing but the JSON
  EXPECT_EQ(j["results"].size(), 1u);
  EXPECT_NE(r.err.find("strategy"), std::string::npos) << "the table belongs on stderr";
  EXPECT_NE(r.err.find("JSON written to the standard output"), std::string::npos);
  // /dev/stdout is the same (the habit of `--json /dev/stdout | jq`), and stays a link.
  const test::CliRun dev = run(align_ + "--json /dev/stdout");
  ASSERT_EQ(dev.exit_code, 0) << dev.err;
  EXPECT_EQ(nlohmann::json::parse(dev.out)["results"].size(), 1u);
  EXPECT_TRUE(fs::is_symlink("/dev/stdout"));
  // A map to the standard output reads back; two outputs cannot share it.
  const test::CliRun map = run(align_ + "--aligned-out -");
  ASSERT_EQ(map.exit_code, 0) << map.err;
  std::ofstream(path("from_stdout.txt")) << map.out;
  EXPECT_EQ(read_map(path("from_stdout.txt")).landmarks.size(),
            read_map(path("source.txt")).landmarks.size());
  expect_one_line_error(run(align_ + "--json - --aligned-out -"), "at most one output",
                        "two outputs on stdout");
  expect_one_line_error(run(align_.substr(0, align_.find("--strategy")) +
                            "--strategy base,robust_obs --aligned-out -"),
                        "the standard output takes one", "several maps on stdout");
}

TEST_F(CliOutputs, AClosedPipeIsAnErrorNamingTheStandardOutput) {
  const std::string command = shell_quote(LMALIGN_CLI_PATH) + " " + align_ + "--aligned-out - 2>" +
                              shell_quote(path("err.txt")) +
                              " | head -c 1 >/dev/null; exit ${PIPESTATUS[0]}";
  const int status = std::system(("bash -c " + shell_quote(command)).c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 2);
  const std::string err = test::read_text(path("err.txt"));
  EXPECT_NE(err.find("lmalign: error: cannot write the standard output ('-'): Broken pipe"),
            std::string::npos)
      << err;
  EXPECT_EQ(err.find("written"), std::string::npos) << err;
}

TEST_F(CliOutputs, AMissingDirectoryIsAnErrorNamingItAndNothingIsCreated) {
  const std::string json = path("no/such/dir/x.json");
  const test::CliRun r = run(align_ + "--json " + shell_quote(json));
  expect_one_line_error(r, "the directory '" + path("no/such/dir") + "' does not exist",
                        "--json in a missing directory");
  EXPECT_FALSE(fs::exists(path("no")));
  EXPECT_EQ(r.out.find("strategy"), std::string::npos) << "checked before any work";
  // A directory, and a block device (as root), are refused.
  expect_one_line_error(run(align_ + "--json " + shell_quote(dir_.string())), "it is a directory",
                        "--json DIR");
  if (::geteuid() == 0) {
    ASSERT_EQ(::mknod(path("blk").c_str(), S_IFBLK | 0600, makedev(7, 0)), 0);
    expect_one_line_error(run(align_ + "--json " + shell_quote(path("blk"))), "block device",
                          "--json BLOCK");
  }
  // An output folder (-o) is still created, with its parents; "-" is no folder.
  const test::CliRun sim =
      run("simulate --scene road --landmarks 50 -o " + shell_quote(path("new/sim")));
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  EXPECT_TRUE(fs::exists(path("new/sim/source.txt")));
  expect_one_line_error(run("simulate --scene road --landmarks 50 -o -"),
                        "cannot be the standard output", "simulate -o -");
}

TEST_F(CliOutputs, EveryMapAndTextOutputTakesDash) {
  // convert: our text by default, PLY with --output-format.
  const test::CliRun text = run("convert " + shell_quote(path("target.txt")) + " -");
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.out.find("LANDMARK"), std::string::npos);
  EXPECT_NE(text.err.find("the standard output"), std::string::npos) << text.err;
  const test::CliRun ply =
      run("convert " + shell_quote(path("target.txt")) + " - --output-format ply");
  ASSERT_EQ(ply.exit_code, 0) << ply.err;
  EXPECT_EQ(ply.out.rfind("ply\nformat ascii 1.0\n", 0), 0u) << ply.out.substr(0, 40);
  expect_one_line_error(
      run("convert " + shell_quote(path("target.txt")) + " - --output-format bundler"),
      "does not write the format 'bundler'", "convert --output-format bundler");
  // split -o -: the window's map.
  const test::CliRun split =
      run("split " + shell_quote(path("target.txt")) + " --frames 100-106 -o -");
  ASSERT_EQ(split.exit_code, 0) << split.err;
  EXPECT_NE(split.out.find("LANDMARK"), std::string::npos);
  // eval-trajectory: the aligned trajectory and the SVG plot.
  std::ofstream traj(path("traj.txt"));
  for (int i = 0; i < 10; ++i) traj << i << " " << 0.1 * i << " 0 0 0 0 0 1\n";
  traj.close();
  const std::string eval =
      "eval-trajectory " + shell_quote(path("traj.txt")) + " " + shell_quote(path("traj.txt"));
  const test::CliRun svg = run(eval + " --plot -");
  ASSERT_EQ(svg.exit_code, 0) << svg.err;
  EXPECT_EQ(svg.out.rfind("<svg", 0), 0u) << svg.out.substr(0, 40);
  const test::CliRun aligned = run(eval + " --aligned-out -");
  ASSERT_EQ(aligned.exit_code, 0) << aligned.err;
  EXPECT_NE(aligned.out.find("0.9 0 0"), std::string::npos) << aligned.out;
  // Folder outputs refuse "-".
  expect_one_line_error(run("experiment " + shell_quote(path("none.yaml")) + " -o -"),
                        "cannot be the standard output", "experiment -o -");
}

}  // namespace
}  // namespace lmalign
