// Unit tests of the map model, the strict map reader/writer and atomic file output.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <gtest/gtest.h>

#include "lmalign/core/error.hpp"
#include "lmalign/io/output_file.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/map/map_io.hpp"
#include "support/map_compare.hpp"

namespace lmalign {
namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// Helpers

Map read_text(const std::string& text, const MapReadOptions& options = {}) {
  std::istringstream in(text);
  return read_map(in, "test.txt", options);
}

MapReadOptions keep_all() {
  MapReadOptions options;
  options.min_observations = 0;
  return options;
}

/// Reads `text` expecting a ParseError on `line` whose detail contains every one of `words`.
void expect_parse_error(const std::string& text, std::size_t line,
                        std::initializer_list<std::string_view> words,
                        const MapReadOptions& options = keep_all()) {
  SCOPED_TRACE("input:\n" + text);
  try {
    read_text(text, options);
    ADD_FAILURE() << "expected a ParseError, but the text was accepted";
  } catch (const ParseError& e) {
    EXPECT_EQ(e.file(), "test.txt");
    EXPECT_EQ(e.line(), line) << e.what();
    for (const std::string_view word : words) {
      EXPECT_NE(e.detail().find(word), std::string::npos)
          << "detail '" << e.detail() << "' lacks '" << word << "'";
    }
    EXPECT_EQ(std::string(e.what()), "test.txt:" + std::to_string(line) + ": " + e.detail());
  }
}

/// A unique scratch directory, removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    static int counter = 0;
    path_ = fs::temp_directory_path() /
            ("lmalign_test_map_io_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::vector<std::string> entries() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(path_)) {
      names.push_back(entry.path().filename().string());
    }
    return names;
  }

 private:
  fs::path path_;
};

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream out;
  out << in.rdbuf();
  return out.str();
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// Valid records used to build malformed inputs.
const std::string kFrame0 = "FRAME 0 0 0 0 1 0 0 0\n";
const std::string kCovIdentity = "0.01 0 0 0 0.01 0 0 0 0.01";

std::string landmark_line(const std::string& id, const std::string& cov,
                          const std::string& tail = "2 0 10 20 0 11 21") {
  return "LANDMARK " + id + " 1 2 3 " + cov + " " + tail + "\n";
}

// ---------------------------------------------------------------------------------------------
// Round trip

Map awkward_map() {
  Map map;
  Frame f1;
  f1.id = std::numeric_limits<Id>::max();
  f1.p_world_camera = Vec3(0.1, -3.3333333333333335, 1e-17);
  f1.q_world_camera = Quat(Eigen::AngleAxisd(0.3, Vec3(1.0, 2.0, 3.0).normalized()));
  Frame f2;
  f2.id = 0;
  f2.p_world_camera = Vec3(-0.0, 5e-324, 1.7976931348623157e308);
  // w < 0 is kept as written (the writer does not canonicalise).
  f2.q_world_camera = Quat(-0.7071067811865476, 0.0, 0.7071067811865475, -0.0);
  Frame f3;
  f3.id = 42;
  f3.p_world_camera = Vec3(2.0 / 3.0, 1e21, -123456.789);
  f3.q_world_camera = Quat(Eigen::AngleAxisd(2.9, Vec3(-0.2, 0.9, 0.1).normalized()));
  map.frames = {f1, f2, f3};

  Landmark l1;
  l1.id = 1000000007;
  l1.p_world = Vec3(0.1, 0.2, 0.30000000000000004);
  Eigen::Matrix3d A;
  A << 0.1, 0.2, 0.3, -1e-3, 0.7, 1.0 / 3.0, 0.0, 1e-9, 0.05;
  l1.cov_world_m2 = A * A.transpose();
  l1.observations = {{f1.id, 318.6, 255.3}, {0, -0.0, 1e-300}, {42, 639.9999999999999, 0.1}};
  Landmark l2;
  l2.id = 3;  // ids need not be sorted or contiguous
  l2.p_world = Vec3(-3.3333333333333335, 1e-17, 9007199254740993.0);
  l2.cov_world_m2 = Mat3::Zero();  // PSD (all zero)
  Landmark l3;
  l3.id = 0;
  l3.p_world = Vec3(1.0, 2.0, 3.0);
  l3.cov_world_m2 = Vec3(1e-17, 0.1, 4.9e-324).asDiagonal();
  l3.observations = {{0, 1.0, 2.0}};
  map.landmarks = {l1, l2, l3};
  return map;
}

TEST(MapIoRoundTrip, WriteThenReadIsBitExact) {
  TempDir dir;
  const Map original = awkward_map();
  const std::string path = dir.file("map.txt");
  write_map(path, original);
  const Map read_back = read_map(path, keep_all());
  EXPECT_TRUE(test::maps_identical(original, read_back));

  // Writing what was read gives the same bytes.
  const std::string path2 = dir.file("map2.txt");
  write_map(path2, read_back);
  EXPECT_EQ(slurp(path), slurp(path2));
}

TEST(MapIoRoundTrip, StreamWriterUsesScalarFirstQuaternionsAndShortestNumbers) {
  Map map;
  Frame frame;
  frame.id = 7;
  frame.p_world_camera = Vec3(0.1, 2.0, -3.5);
  frame.q_world_camera = Quat(0.5, -0.5, 0.5, -0.5);  // w x y z
  map.frames = {frame};
  Landmark landmark;
  landmark.id = 9;
  landmark.p_world = Vec3(1.0, 1e-17, 0.25);
  landmark.cov_world_m2 = Mat3::Identity();
  landmark.observations = {{7, 318.5, 0.1}};
  map.landmarks = {landmark};
  std::ostringstream out;
  write_map(out, map);
  EXPECT_EQ(out.str(),
            "FRAME 7 0.1 2 -3.5 0.5 -0.5 0.5 -0.5\n"
            "LANDMARK 9 1 1e-17 0.25 1 0 0 0 1 0 0 0 1 1 7 318.5 0.1\n");
}

TEST(MapIoRoundTrip, ReadsFramesAfterLandmarksAndKeepsFileOrder) {
  const std::string text = "LANDMARK 20 1 2 3 " + kCovIdentity + " 2 9 10 20 4 11 21\n" +
                           "LANDMARK 10 4 5 6 " + kCovIdentity + " 2 4 1 2 9 3 4\n" +
                           "FRAME 9 1 2 3 1 0 0 0\n" + "FRAME 4 0 0 0 0 1 0 0\n";
  const Map map = read_text(text);
  ASSERT_EQ(map.frames.size(), 2u);
  EXPECT_EQ(map.frames[0].id, 9);
  EXPECT_EQ(map.frames[1].id, 4);
  EXPECT_EQ(map.frames[1].q_world_camera.x(), 1.0);  // scalar first: "0 1 0 0" is x = 1
  EXPECT_EQ(map.frames[1].q_world_camera.w(), 0.0);
  ASSERT_EQ(map.landmarks.size(), 2u);
  EXPECT_EQ(map.landmarks[0].id, 20);
  EXPECT_EQ(map.landmarks[1].id, 10);
  EXPECT_EQ(map.landmarks[0].p_world, Vec3(1, 2, 3));
  ASSERT_EQ(map.landmarks[0].observations.size(), 2u);
  EXPECT_EQ(map.landmarks[0].observations[1].frame_id, 4);
  EXPECT_EQ(map.landmarks[0].observations[1].u_px, 11.0);
  EXPECT_EQ(map.landmarks[0].observations[1].v_px, 21.0);
}

TEST(MapIoRoundTrip, CovarianceIsRowMajor) {
  // Asymmetric within tolerance is impossible to tell apart, so check placement by a symmetric
  // matrix with distinct entries.
  const std::string text = kFrame0 + "LANDMARK 1 0 0 0 4 1 2 1 5 3 2 3 6 2 0 1 1 0 2 2\n";
  const Map map = read_text(text);
  Mat3 expected;
  expected << 4, 1, 2, 1, 5, 3, 2, 3, 6;
  EXPECT_EQ(map.landmarks.at(0).cov_world_m2, expected);
}

TEST(MapIoRoundTrip, QuaternionIsNotNormalisedOnLoad) {
  const Map map = read_text("FRAME 1 0 0 0 1.0005 0 0 0\n");
  EXPECT_EQ(map.frames.at(0).q_world_camera.w(), 1.0005);
  // ...but the pose uses a proper rotation.
  EXPECT_TRUE(map.frames.at(0).T_world_camera().linear().isApprox(Mat3::Identity(), 1e-15));
}

// ---------------------------------------------------------------------------------------------
// Malformed input: every error names the line and says what was expected.

TEST(MapIoParseErrors, UnknownRecordType) {
  expect_parse_error(kFrame0 + "FOO 1 2 3\n", 2,
                     {"unknown record type 'FOO'", "(expected FRAME, LANDMARK or MAP)"});
  // Record types are case sensitive.
  expect_parse_error("frame 0 0 0 0 1 0 0 0\n", 1, {"unknown record type 'frame'"});
}

TEST(MapIoParseErrors, FrameFieldCount) {
  expect_parse_error("FRAME 1 0 0 1 0 0\n", 1,
                     {"FRAME record has 7 fields, expected 9", "(FRAME id tx ty tz qw qx qy qz)"});
  expect_parse_error(kFrame0 + "FRAME 1 0 0 0 1 0 0 0 5\n", 2,
                     {"FRAME record has 10 fields, expected 9"});
  // A trailing comment is not allowed on a record line.
  expect_parse_error("FRAME 1 0 0 0 1 0 0 0 # note\n", 1, {"has 11 fields, expected 9"});
}

TEST(MapIoParseErrors, LandmarkTooFewFieldsBeforeN) {
  expect_parse_error(kFrame0 + "LANDMARK 3 1 2 3 " + kCovIdentity + "\n", 2,
                     {"LANDMARK record has 14 fields, expected at least 15", "c22 n"});
}

TEST(MapIoParseErrors, LandmarkObservationCountMismatch) {
  expect_parse_error(kFrame0 + landmark_line("12", kCovIdentity, "3 0 1 2 0 1 2 0 1"), 2,
                     {"LANDMARK 12 declares n=3 observations (9 values) but has 8 values after n"});
  expect_parse_error(kFrame0 + landmark_line("12", kCovIdentity, "1 0 1 2 0"), 2,
                     {"declares n=1 observations (3 values) but has 4 values after n"});
  expect_parse_error(kFrame0 + landmark_line("5", kCovIdentity, "0 0 1 2"), 2,
                     {"declares n=0 observations (0 values) but has 3 values after n"});
}

TEST(MapIoParseErrors, NonNumericValue) {
  expect_parse_error("FRAME 1 abc 0 0 1 0 0 0\n", 1, {"field 'tx' is not a number: 'abc'"});
  // The whole token must be a number.
  expect_parse_error("FRAME 1 0 0 1.5x 1 0 0 0\n", 1, {"field 'tz' is not a number: '1.5x'"});
  expect_parse_error("FRAME 1 0 0 0 1 0 0 +0\n", 1, {"field 'qz' is not a number: '+0'"});
  expect_parse_error("FRAME 1 0 0 0 1 0 0 0x0\n", 1, {"field 'qz' is not a number: '0x0'"});
  expect_parse_error(kFrame0 + landmark_line("4", "0.01 0 0 0 0.01 0 0 zero 0.01"), 2,
                     {"field 'c21' is not a number: 'zero'"});
  expect_parse_error(kFrame0 + landmark_line("4", kCovIdentity, "2 0 10 20 0 1,5 21"), 2,
                     {"field 'u_2' is not a number: '1,5'"});
  expect_parse_error("LANDMARK 4 1 y 3 " + kCovIdentity + " 0\n", 1,
                     {"field 'y' is not a number: 'y'"});
}

TEST(MapIoParseErrors, IdsAndCountsMustBeNonNegativeIntegers) {
  expect_parse_error("FRAME 1.5 0 0 0 1 0 0 0\n", 1,
                     {"field 'id' is not a non-negative integer: '1.5'"});
  expect_parse_error("FRAME -1 0 0 0 1 0 0 0\n", 1,
                     {"field 'id' is not a non-negative integer: '-1'"});
  expect_parse_error("FRAME 99999999999999999999 0 0 0 1 0 0 0\n", 1,
                     {"field 'id' is not a non-negative integer"});
  expect_parse_error(kFrame0 + landmark_line("1e3", kCovIdentity), 2,
                     {"field 'id' is not a non-negative integer: '1e3'"});
  expect_parse_error(kFrame0 + landmark_line("8", kCovIdentity, "2.0 0 10 20 0 11 21"), 2,
                     {"field 'n' is not a non-negative integer: '2.0'"});
  expect_parse_error(kFrame0 + landmark_line("8", kCovIdentity, "2 0 10 20 -3 11 21"), 2,
                     {"field 'f_2' is not a non-negative integer: '-3'"});
}

TEST(MapIoParseErrors, NonFiniteValues) {
  expect_parse_error(kFrame0 + landmark_line("4", "0.01 nan 0 0 0.01 0 0 0 0.01"), 2,
                     {"field 'c01' is not finite: 'nan'"});
  expect_parse_error("FRAME 1 inf 0 0 1 0 0 0\n", 1, {"field 'tx' is not finite: 'inf'"});
  expect_parse_error("FRAME 1 0 -Infinity 0 1 0 0 0\n", 1,
                     {"field 'ty' is not finite: '-Infinity'"});
  expect_parse_error(kFrame0 + landmark_line("4", kCovIdentity, "1 0 10 NaN"), 2,
                     {"field 'v_1' is not finite: 'NaN'"});
  expect_parse_error("FRAME 1 0 0 1e999 1 0 0 0\n", 1,
                     {"field 'tz' is out of the range of a double: '1e999'"});
}

TEST(MapIoParseErrors, QuaternionNorm) {
  expect_parse_error("FRAME 0 0 0 0 0.5 0 0 0\n", 1,
                     {"quaternion norm is 0.5, expected 1 (w x y z, scalar first)"});
  expect_parse_error("FRAME 0 0 0 0 0 0 0 0\n", 1, {"quaternion norm is 0, expected 1"});
  // Within the default tolerance (1e-3) is accepted; a tighter tolerance rejects it.
  EXPECT_NO_THROW(read_text("FRAME 0 0 0 0 1.0005 0 0 0\n"));
  MapReadOptions strict = keep_all();
  strict.quaternion_norm_tolerance = 1e-4;
  expect_parse_error("FRAME 0 0 0 0 1.0005 0 0 0\n", 1, {"quaternion norm is 1.0005"}, strict);
}

TEST(MapIoParseErrors, CovarianceNotSymmetric) {
  expect_parse_error(kFrame0 + landmark_line("6", "0.01 0.001 0 0 0.01 0 0 0 0.01"), 2,
                     {"LANDMARK 6", "covariance is not symmetric", "c01=0.001", "c10=0"});
  expect_parse_error(kFrame0 + landmark_line("6", "0.01 0 0 0 0.01 0.002 0 0.001 0.01"), 2,
                     {"not symmetric", "c12=0.002", "c21=0.001"});
  // A difference within the relative tolerance is accepted and kept exactly as written.
  const Map map =
      read_text(kFrame0 + landmark_line("6", "0.01 0.001 0 0.001000000000001 0.01 0 0 0 0.01"));
  EXPECT_EQ(map.landmarks.at(0).cov_world_m2(1, 0), 0.001000000000001);
}

TEST(MapIoParseErrors, CovarianceNotPositiveSemiDefinite) {
  expect_parse_error(
      kFrame0 + landmark_line("6", "1 0 0 0 1 0 0 0 -0.5"), 2,
      {"LANDMARK 6", "covariance is not positive semi-definite", "smallest eigenvalue is -0.5"});
  // Symmetric with positive diagonal but indefinite (eigenvalues 3, -1, 1).
  expect_parse_error(kFrame0 + landmark_line("7", "1 2 0 2 1 0 0 0 1"), 2,
                     {"not positive semi-definite", "-1"});
  // Singular (rank 1) and all-zero covariances are PSD.
  EXPECT_NO_THROW(read_text(kFrame0 + landmark_line("8", "1 1 0 1 1 0 0 0 0")));
  EXPECT_NO_THROW(read_text(kFrame0 + landmark_line("9", "0 0 0 0 0 0 0 0 0")));
}

TEST(MapIoParseErrors, ObservationOfUnknownFrameReportsTheLandmarkLine) {
  // Frame 0 is defined after the landmark (allowed); frame 99 never is.
  const std::string text = "# header\n" + landmark_line("3", kCovIdentity) +
                           landmark_line("7", kCovIdentity, "2 0 1 2 99 3 4") + kFrame0;
  expect_parse_error(text, 3, {"LANDMARK 7 observes unknown frame 99"});
}

TEST(MapIoParseErrors, DuplicateIds) {
  expect_parse_error("FRAME 3 0 0 0 1 0 0 0\n# comment\n\nFRAME 3 1 1 1 1 0 0 0\n", 4,
                     {"duplicate FRAME id 3 (first defined on line 1)"});
  expect_parse_error(kFrame0 + landmark_line("5", kCovIdentity) + "FRAME 1 0 0 0 1 0 0 0\n" +
                         landmark_line("5", kCovIdentity),
                     4, {"duplicate LANDMARK id 5 (first defined on line 2)"});
  // Frame and landmark ids live in separate namespaces.
  EXPECT_NO_THROW(read_text(kFrame0 + landmark_line("0", kCovIdentity, "1 0 1 2")));
}

TEST(MapIoParseErrors, LineNumbersCountCommentsBlankLinesAndCrlf) {
  expect_parse_error("# c\r\n\r\n   # indented comment\r\n" + kFrame0 + "FRAME 1 x 0 0 1 0 0 0\r\n",
                     5, {"field 'tx' is not a number: 'x'"});
}

TEST(MapIoParseErrors, FileNameIsThePath) {
  TempDir dir;
  const std::string path = dir.file("bad map.txt");
  write_text(path, kFrame0 + "BOGUS\n");
  try {
    read_map(path);
    ADD_FAILURE() << "expected a ParseError";
  } catch (const ParseError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), 2u);
    EXPECT_EQ(std::string(e.what()).rfind(path + ":2: unknown record type 'BOGUS'", 0), 0u)
        << e.what();
  }
}

TEST(MapIoParseErrors, MissingFileIsAnIoError) {
  TempDir dir;
  const std::string path = dir.file("missing.txt");
  try {
    read_map(path);
    ADD_FAILURE() << "expected an IoError";
  } catch (const IoError& e) {
    EXPECT_EQ(std::string(e.what()),
              "cannot open map file '" + path + "': " + std::strerror(ENOENT));
  }
  EXPECT_THROW(read_map(dir.file("")), IoError);  // a directory
}

// ---------------------------------------------------------------------------------------------
// Load filter and accepted text forms

TEST(MapIoFilter, MinObservationsDropsLandmarksAfterValidation) {
  const std::string text = kFrame0 + landmark_line("10", kCovIdentity, "0") +
                           landmark_line("11", kCovIdentity, "1 0 1 2") +
                           landmark_line("12", kCovIdentity, "2 0 1 2 0 3 4") +
                           landmark_line("13", kCovIdentity, "3 0 1 2 0 3 4 0 5 6");
  const auto ids = [](const Map& map) {
    std::vector<Id> out;
    for (const Landmark& landmark : map.landmarks) out.push_back(landmark.id);
    return out;
  };
  EXPECT_EQ(ids(read_text(text)), (std::vector<Id>{12, 13}));  // default: n >= 2
  EXPECT_EQ(ids(read_text(text, keep_all())), (std::vector<Id>{10, 11, 12, 13}));
  MapReadOptions three;
  three.min_observations = 3;
  const Map map = read_text(text, three);
  EXPECT_EQ(ids(map), (std::vector<Id>{13}));
  EXPECT_EQ(map.frames.size(), 1u);  // frames are never filtered

  // A landmark that would be dropped is still validated.
  expect_parse_error(kFrame0 + landmark_line("14", kCovIdentity, "1 5 1 2"), 2,
                     {"LANDMARK 14 observes unknown frame 5"}, MapReadOptions{});
}

TEST(MapIoTextForms, CrlfTabsCommentsAndBlankLinesReadLikePlainLf) {
  const std::string lf = "FRAME 2 0.5 -1 2 1 0 0 0\n" +
                         landmark_line("1", kCovIdentity, "1 2 3 4") +
                         landmark_line("4", "1 0.5 0 0.5 1 0 0 0 1", "2 2 1.25 2.5 2 3 4");
  const std::string messy = "# a comment\r\n\r\n  \t \r\n\tFRAME\t2  0.5 -1\t2 1 0 0 0  \r\n" +
                            std::string("   # indented comment, FRAME 9 x\r\n") +
                            "LANDMARK 1 1 2 3\t0.01 0 0 0 0.01 0 0 0 0.01 1 2 3 4\r\n" +
                            "LANDMARK 4 1 2 3 1 0.5 0 0.5 1 0 0 0 1 2 2 1.25 2.5 2 3 4";
  const Map a = read_text(lf, keep_all());
  ASSERT_EQ(a.landmarks.size(), 2u);
  EXPECT_TRUE(test::maps_identical(a, read_text(messy, keep_all())));
}

TEST(MapIoTextForms, EmptyOrCommentOnlyFileIsAnEmptyMap) {
  for (const std::string text : {"", "\n\n", "# only a comment\n", "  \r\n"}) {
    const Map map = read_text(text);
    EXPECT_TRUE(map.frames.empty());
    EXPECT_TRUE(map.landmarks.empty());
  }
}

// ---------------------------------------------------------------------------------------------
// Writer checks and atomic output

struct CallbackFailure {
  int code;
};

TEST(AtomicFile, CallbackExceptionLeavesTargetUnchangedAndNoTempFiles) {
  TempDir dir;
  const std::string path = dir.file("target.txt");
  write_text(path, "original\n");
  try {
    write_output(path, [](std::ostream& out) {
      out << "partial output that must never be seen\n";
      throw CallbackFailure{7};
    });
    ADD_FAILURE() << "the callback's exception was swallowed";
  } catch (const CallbackFailure& e) {
    EXPECT_EQ(e.code, 7);  // rethrown unchanged
  }
  EXPECT_EQ(slurp(path), "original\n");
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"target.txt"});

  // A std exception passes through with its own type and message.
  try {
    write_output(path, [](std::ostream&) { throw std::out_of_range("boom"); });
    ADD_FAILURE() << "the callback's exception was swallowed";
  } catch (const std::out_of_range& e) {
    EXPECT_STREQ(e.what(), "boom");
  }
  EXPECT_EQ(slurp(path), "original\n");
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"target.txt"});
}

TEST(AtomicFile, ReplacesTargetOnSuccess) {
  TempDir dir;
  const std::string path = dir.file("target.txt");
  write_text(path, "original\n");
  write_output(path, [](std::ostream& out) { out << "new content\n"; });
  EXPECT_EQ(slurp(path), "new content\n");
  write_output(dir.file("fresh.txt"), [](std::ostream& out) { out << "x"; });
  EXPECT_EQ(slurp(dir.file("fresh.txt")), "x");
  auto entries = dir.entries();
  std::sort(entries.begin(), entries.end());
  EXPECT_EQ(entries, (std::vector<std::string>{"fresh.txt", "target.txt"}));
}

TEST(AtomicFile, MissingDirectoryIsAnIoErrorNamingThePath) {
  TempDir dir;
  const std::string path = dir.file("no_such_dir/out.txt");
  try {
    write_output(path, [](std::ostream& out) { out << "x"; });
    ADD_FAILURE() << "expected an IoError";
  } catch (const IoError& e) {
    EXPECT_EQ(std::string(e.what()), "cannot write '" + path + "': the directory '" +
                                         dir.file("no_such_dir") + "' does not exist");
  }
  EXPECT_FALSE(fs::exists(path));
  EXPECT_THROW(write_map(path, awkward_map()), IoError);
}

TEST(AtomicFile, WriteMapRefusesAnInvalidMapAndWritesNothing) {
  TempDir dir;
  const std::string path = dir.file("map.txt");
  Map map = awkward_map();
  map.landmarks[0].observations.push_back({12345, 1.0, 2.0});  // unknown frame
  EXPECT_THROW(write_map(path, map), InvalidArgument);
  map = awkward_map();
  map.frames[1].q_world_camera = Quat(0.5, 0.0, 0.0, 0.0);  // the reader would reject it
  EXPECT_THROW(write_map(path, map), InvalidArgument);
  map = awkward_map();
  map.landmarks[1].cov_world_m2(0, 0) = -1.0;  // not PSD
  EXPECT_THROW(write_map(path, map), InvalidArgument);
  EXPECT_TRUE(dir.entries().empty());
}

// ---------------------------------------------------------------------------------------------
// Map model

TEST(MapModel, FrameIndexFindsFramesAndFollowsGrowth) {
  Map map;
  map.frames.resize(3);
  map.frames[0].id = 30;
  map.frames[1].id = 10;
  map.frames[2].id = 20;
  EXPECT_EQ(map.frame_index(10), std::optional<std::size_t>(1));
  EXPECT_EQ(map.frame_index(20), std::optional<std::size_t>(2));
  EXPECT_FALSE(map.frame_index(40).has_value());
  EXPECT_EQ(map.find_frame(99), nullptr);
  Frame extra;
  extra.id = 40;
  map.frames.push_back(extra);  // size change: the index is rebuilt
  ASSERT_NE(map.find_frame(40), nullptr);
  EXPECT_EQ(map.find_frame(40), &map.frames[3]);
  map.frames[0].id = 31;  // same size: invalidate explicitly
  map.invalidate_index();
  EXPECT_EQ(map.frame_index(31), std::optional<std::size_t>(0));
  EXPECT_FALSE(map.frame_index(30).has_value());
}

TEST(MapModel, PositionsAndPoseAccessor) {
  const Map map = awkward_map();
  const Points3 points = map.positions();
  ASSERT_EQ(points.size(), 3u);
  EXPECT_EQ(points[1], map.landmarks[1].p_world);
  Frame frame;
  frame.q_world_camera = Quat(2.0, 0.0, 0.0, 2.0);  // not unit: 90 degrees about z once normalised
  frame.p_world_camera = Vec3(1, 2, 3);
  const Isometry3 T = frame.T_world_camera();
  EXPECT_TRUE((T * Vec3(1, 0, 0)).isApprox(Vec3(1, 3, 3), 1e-14));
}

TEST(MapModel, ValidateNamesTheOffendingId) {
  Map map = awkward_map();
  EXPECT_NO_THROW(map.validate());
  map.frames.push_back(map.frames[2]);
  try {
    map.validate();
    ADD_FAILURE() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("duplicate FRAME id 42"), std::string::npos) << e.what();
  }
  map = awkward_map();
  map.landmarks[2].observations[0].frame_id = 77;
  try {
    map.validate();
    ADD_FAILURE() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("LANDMARK 0 observes unknown frame 77"), std::string::npos)
        << e.what();
  }
  map = awkward_map();
  map.landmarks.push_back(map.landmarks[0]);
  EXPECT_THROW(map.validate(), InvalidArgument);
  map = awkward_map();
  map.landmarks[0].p_world.x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(map.validate(), InvalidArgument);
}

TEST(TransformMap, TransformsPositionsCovariancesAndPosesByHand) {
  Map map;
  Frame f0;
  f0.id = 5;
  f0.p_world_camera = Vec3(0, 0, 1);
  f0.q_world_camera = Quat::Identity();
  Frame f1;
  f1.id = 6;
  f1.p_world_camera = Vec3(1, 0, 0);
  f1.q_world_camera = Quat(0, 0, 0, 1);  // 180 degrees about z
  map.frames = {f0, f1};
  Landmark l;
  l.id = 3;
  l.p_world = Vec3(1, 0, 0);
  l.cov_world_m2 << 1, 0.5, 0, 0.5, 4, 0, 0, 0, 9;
  l.observations = {{5, 100.5, 200.25}, {6, 1.0, 2.0}};
  map.landmarks = {l};

  // T_new_old: 90 degrees about z, then translate by (1, 2, 3). R maps (x, y, z) to (-y, x, z).
  Isometry3 T = Isometry3::Identity();
  T.linear() = Eigen::AngleAxisd(M_PI / 2, Vec3::UnitZ()).toRotationMatrix();
  T.translation() = Vec3(1, 2, 3);
  const Map out = transform_map(map, T);

  ASSERT_EQ(out.landmarks.size(), 1u);
  const Landmark& lo = out.landmarks[0];
  EXPECT_EQ(lo.id, 3);
  EXPECT_TRUE(lo.p_world.isApprox(Vec3(1, 3, 3), 1e-14)) << lo.p_world.transpose();
  Mat3 expected_cov;  // var(x') = var(y), cov(x', y') = -cov(y, x)
  expected_cov << 4, -0.5, 0, -0.5, 1, 0, 0, 0, 9;
  EXPECT_LT((lo.cov_world_m2 - expected_cov).cwiseAbs().maxCoeff(), 1e-14) << lo.cov_world_m2;
  EXPECT_EQ(lo.cov_world_m2, lo.cov_world_m2.transpose());
  ASSERT_EQ(lo.observations.size(), 2u);
  EXPECT_EQ(lo.observations[0].frame_id, 5);
  EXPECT_EQ(lo.observations[0].u_px, 100.5);
  EXPECT_EQ(lo.observations[0].v_px, 200.25);
  EXPECT_EQ(lo.observations[1].frame_id, 6);

  ASSERT_EQ(out.frames.size(), 2u);
  EXPECT_EQ(out.frames[0].id, 5);
  EXPECT_TRUE(out.frames[0].p_world_camera.isApprox(Vec3(1, 2, 4), 1e-14));
  const double h = std::sqrt(0.5);
  EXPECT_TRUE(out.frames[0].q_world_camera.coeffs().isApprox(Quat(h, 0, 0, h).coeffs(), 1e-14))
      << out.frames[0].q_world_camera.coeffs().transpose();
  // 90 + 180 = 270 degrees about z; stored with w >= 0 as -90 degrees.
  EXPECT_TRUE(out.frames[1].p_world_camera.isApprox(Vec3(1, 3, 3), 1e-14));
  EXPECT_GE(out.frames[1].q_world_camera.w(), 0.0);
  EXPECT_TRUE(out.frames[1].q_world_camera.coeffs().isApprox(Quat(h, 0, 0, -h).coeffs(), 1e-14))
      << out.frames[1].q_world_camera.coeffs().transpose();
  Mat3 R270;
  R270 << 0, 1, 0, -1, 0, 0, 0, 0, 1;
  EXPECT_TRUE(out.frames[1].T_world_camera().linear().isApprox(R270, 1e-14));

  // A landmark seen from a frame keeps its camera-frame coordinates.
  const Vec3 p_cam_before = map.frames[0].T_world_camera().inverse() * map.landmarks[0].p_world;
  const Vec3 p_cam_after = out.frames[0].T_world_camera().inverse() * lo.p_world;
  EXPECT_TRUE(p_cam_before.isApprox(Vec3(1, 0, -1), 1e-14));
  EXPECT_TRUE(p_cam_before.isApprox(p_cam_after, 1e-14)) << p_cam_after.transpose();
  // The input is untouched.
  EXPECT_EQ(map.landmarks[0].p_world, Vec3(1, 0, 0));
}

TEST(TransformMap, FrameQuaternionsAreKeptWithNonNegativeW) {
  // Rotations whose matrix has a negative trace are where a matrix-to-quaternion conversion can
  // return w < 0; the result must still be w >= 0 and the same rotation.
  Map map;
  Frame frame;
  frame.id = 1;
  map.frames = {frame};
  for (const double angle_deg : {-170.0, 170.0, -120.0, 179.0}) {
    for (const Vec3& axis : {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, -2, 0.5).normalized()}) {
      Isometry3 T = Isometry3::Identity();
      T.linear() = Eigen::AngleAxisd(angle_deg * M_PI / 180.0, axis).toRotationMatrix();
      const Map out = transform_map(map, T);
      const Quat& q = out.frames[0].q_world_camera;
      EXPECT_GE(q.w(), 0.0) << angle_deg << " deg about " << axis.transpose();
      EXPECT_NEAR(q.norm(), 1.0, 1e-15);
      EXPECT_TRUE(q.toRotationMatrix().isApprox(T.linear(), 1e-14));
    }
  }
}

}  // namespace
}  // namespace lmalign
