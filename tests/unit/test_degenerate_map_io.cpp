// Hostile map files and paths (issue 5, docs/robustness.md): endless and over-long lines,
// truncated files, Windows line endings, non-UTF-8 paths, unreadable streams and unwritable
// outputs. Each has a defined outcome: a clear error naming the file and line, or a valid map.
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <ios>
#include <limits>
#include <sstream>
#include <streambuf>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lmalign/core/error.hpp"
#include "lmalign/io/output_file.hpp"
#include "lmalign/map/map_io.hpp"

namespace lmalign {
namespace {

namespace fs = std::filesystem;

const std::string kFrames = "FRAME 0 0 0 0 1 0 0 0\nFRAME 1 1 0 0 1 0 0 0\n";
const std::string kLandmarks =
    "LANDMARK 5 0.1 0.2 1.5 1e-4 0 0 0 1e-4 0 0 0 1e-4 2 0 100.5 200.25 1 300 400\n"
    "LANDMARK 6 -0.4 0.3 2.5 2e-4 1e-5 0 1e-5 2e-4 0 0 0 3e-4 2 1 10 20 0 30 40\n";

class TempDir {
 public:
  TempDir() {
    path_ = fs::temp_directory_path() /
            ("lmalign_degenerate_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::size_t count() const {
    return static_cast<std::size_t>(
        std::distance(fs::directory_iterator(path_), fs::directory_iterator()));
  }

 private:
  fs::path path_;
};

void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out << bytes;
}

Map read_text(const std::string& text, const MapReadOptions& options = {}) {
  std::istringstream in(text);
  return read_map(in, "test.txt", options);
}

/// A stream of `total` bytes of 'x' with no line ending (an "endless" line), generated on the
/// fly; counts how many bytes the reader pulled.
class EndlessLine : public std::streambuf {
 public:
  explicit EndlessLine(std::size_t total) : left_(total) {}
  std::size_t consumed() const { return consumed_; }

 protected:
  int_type underflow() override {
    if (left_ == 0) return traits_type::eof();
    const std::size_t n = std::min(left_, sizeof(buffer_));
    std::fill(buffer_, buffer_ + n, 'x');
    left_ -= n;
    consumed_ += n;
    setg(buffer_, buffer_, buffer_ + n);
    return traits_type::to_int_type(buffer_[0]);
  }

 private:
  char buffer_[4096];
  std::size_t left_;
  std::size_t consumed_ = 0;
};

/// A map of `total` bytes generated on the fly: two frames and two landmarks, then 64 KiB comment
/// lines up to `total`; counts how many bytes the reader pulled.
class HugeMapStream : public std::streambuf {
 public:
  explicit HugeMapStream(std::size_t total) : left_(total) {
    const std::string head = kFrames + kLandmarks;
    comment_ = "#" + std::string(kLine - 2, 'c') + "\n";
    std::copy(head.begin(), head.end(), buffer_.begin());
    first_ = head.size();
  }
  std::size_t consumed() const { return consumed_; }

 protected:
  int_type underflow() override {
    if (left_ == 0) return traits_type::eof();
    std::size_t n = first_;
    if (n == 0) {
      std::copy(comment_.begin(), comment_.end(), buffer_.begin());
      n = comment_.size();
    }
    first_ = 0;
    n = std::min(n, left_);
    if (n < comment_.size() && n == left_) buffer_[n - 1] = '\n';  // end on a line ending
    left_ -= n;
    consumed_ += n;
    setg(buffer_.data(), buffer_.data(), buffer_.data() + n);
    return traits_type::to_int_type(buffer_[0]);
  }

 private:
  static constexpr std::size_t kLine = std::size_t{64} << 10;
  std::vector<char> buffer_ = std::vector<char>(kLine);
  std::string comment_;
  std::size_t first_ = 0;
  std::size_t left_;
  std::size_t consumed_ = 0;
};

/// Peak resident memory of this process so far, bytes.
std::size_t peak_rss_bytes() {
  rusage u{};
  ::getrusage(RUSAGE_SELF, &u);
  return static_cast<std::size_t>(u.ru_maxrss) * 1024;
}

/// A stream that fails with an I/O error after its first bytes, as std::filebuf does on EIO.
class FailingStream : public std::streambuf {
 protected:
  int_type underflow() override {
    if (!served_) {
      served_ = true;
      setg(text_, text_, text_ + sizeof(text_) - 1);
      return traits_type::to_int_type(text_[0]);
    }
    throw std::ios_base::failure("read failed", std::make_error_code(std::errc::io_error));
  }

 private:
  char text_[24] = "FRAME 0 0 0 0 1 0 0 0\nF";
  bool served_ = false;
};

// ---------------------------------------------------------------------------------------------
// Line length: bounded memory, clear refusal

TEST(DegenerateMapFile, LineLongerThanTheLimitIsAParseErrorNamingTheLine) {
  MapReadOptions options;
  options.max_line_bytes = 100;
  const std::string ok_line = "FRAME 2 0 0 0 1 0 0 0" + std::string(100 - 21, ' ');
  ASSERT_EQ(ok_line.size(), 100u);
  // Exactly the limit is fine, with LF or CRLF (the line ending does not count).
  EXPECT_EQ(read_text(kFrames + ok_line + "\n", options).frames.size(), 3u);
  EXPECT_EQ(read_text(kFrames + ok_line + "\r\n", options).frames.size(), 3u);
  EXPECT_EQ(read_text(kFrames + ok_line, options).frames.size(), 3u);
  try {
    read_text(kFrames + ok_line + " \n", options);
    FAIL() << "a 101-byte line was accepted";
  } catch (const ParseError& e) {
    EXPECT_EQ(e.line(), 3u);
    EXPECT_NE(e.detail().find("longer than 100 bytes"), std::string::npos) << e.what();
    EXPECT_NE(e.detail().find("starts 'FRAME 2"), std::string::npos) << e.what();
  }
}

TEST(DegenerateMapFile, AnEndlessLineIsRefusedAfterReadingOnlyTheLimit) {
  // 64 GiB of one line, generated on the fly: the reader must stop at the limit.
  EndlessLine endless(std::size_t{64} << 30);
  std::istream in(&endless);
  MapReadOptions options;
  options.max_line_bytes = 1 << 16;
  try {
    read_map(in, "endless.txt", options);
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_EQ(e.line(), 1u);
    EXPECT_NE(e.detail().find("longer than 65536 bytes"), std::string::npos) << e.what();
  }
  EXPECT_LE(endless.consumed(), (std::size_t{1} << 16) + 4096);
}

TEST(DegenerateMapFile, TenMegabyteLineIsRefusedWithTheDefaultLimit) {
  TempDir dir;
  const std::string path = dir.file("long_line.txt");
  {
    std::ofstream out(path, std::ios::binary);
    out << kFrames << "LANDMARK 9 0 0 0 1 0 0 0 1 0 0 0 1 800000";
    for (int i = 0; i < 800000; ++i) out << " 0 10.5 20.25";  // 10.4 MB
    out << "\n" << kLandmarks;
  }
  ASSERT_GT(fs::file_size(path), 10'000'000u);
  try {
    read_map(path);
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), 3u);
    EXPECT_NE(e.detail().find("longer than 1048576 bytes"), std::string::npos) << e.what();
  }
}

TEST(DegenerateMapFile, AOneGigabyteMapIsReadInBoundedMemory) {
  // 1 GiB of map text (streamed, never stored by the test): the reader keeps only what it needs.
  const std::size_t total = std::size_t{1} << 30;
  HugeMapStream huge(total);
  std::istream in(&huge);
  const std::size_t rss_before = peak_rss_bytes();
  const Map map = read_map(in, "huge.txt");
  EXPECT_EQ(huge.consumed(), total);
  EXPECT_EQ(map.frames.size(), 2u);
  ASSERT_EQ(map.landmarks.size(), 2u);
  EXPECT_EQ(map.landmarks[1].id, 6);
  // Far below the file's size: the text is streamed line by line. (The bound leaves room for
  // AddressSanitizer, whose quarantine alone may keep 256 MB of freed line buffers resident.)
  EXPECT_LT(peak_rss_bytes() - rss_before, total / 2);
}

TEST(DegenerateMapFile, TheDefaultLimitHoldsTensOfThousandsOfObservations) {
  std::string line = "LANDMARK 9 0 0 1 1e-4 0 0 0 1e-4 0 0 0 1e-4 30000";
  for (int i = 0; i < 30000; ++i)
    line += i % 2 ? " 1 493.722198 281.207306" : " 0 505.653381 269.800049";
  ASSERT_LT(line.size(), std::size_t{1} << 20);
  ASSERT_GT(line.size(), std::size_t{700} << 10);
  const Map map = read_text(kFrames + line + "\n");
  ASSERT_EQ(map.landmarks.size(), 1u);
  EXPECT_EQ(map.landmarks[0].num_observations(), 30000u);
}

// ---------------------------------------------------------------------------------------------
// Truncation, line endings

TEST(DegenerateMapFile, TruncatedFileNamesTheIncompleteLine) {
  const std::string text = kFrames + kLandmarks;
  // Cut the last record at each field boundary: an incomplete record, always an error on line 4.
  const std::size_t last_start = text.rfind("LANDMARK");
  std::size_t errors = 0;
  for (std::size_t cut = last_start + 1; cut < text.size() - 1; ++cut) {
    if (text[cut] != ' ') continue;  // cut just before a separator: whole fields missing
    try {
      read_text(text.substr(0, cut));
      ADD_FAILURE() << "truncation at byte " << cut << " accepted";
    } catch (const ParseError& e) {
      EXPECT_EQ(e.line(), 4u) << e.what();
      ++errors;
    }
  }
  EXPECT_GT(errors, 10u);
  // A cut at a line boundary leaves fewer, complete records: a valid, smaller map.
  EXPECT_EQ(read_text(text.substr(0, last_start), MapReadOptions{}).landmarks.size(), 1u);
}

TEST(DegenerateMapFile, WindowsAndMixedLineEndingsReadLikeLf) {
  TempDir dir;
  const std::string lf = kFrames + kLandmarks;
  std::string crlf;
  for (char c : lf) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  std::string mixed = crlf;
  mixed.replace(mixed.find("\r\n"), 2, "\n");
  write_bytes(dir.file("lf.txt"), lf);
  write_bytes(dir.file("crlf.txt"), crlf);
  write_bytes(dir.file("mixed.txt"), mixed);
  const Map a = read_map(dir.file("lf.txt"));
  for (const char* name : {"crlf.txt", "mixed.txt"}) {
    const Map b = read_map(dir.file(name));
    ASSERT_EQ(b.frames.size(), a.frames.size()) << name;
    ASSERT_EQ(b.landmarks.size(), a.landmarks.size()) << name;
    for (std::size_t i = 0; i < a.landmarks.size(); ++i) {
      EXPECT_TRUE(b.landmarks[i].p_world == a.landmarks[i].p_world) << name;
      EXPECT_EQ(b.landmarks[i].observations.back().v_px, a.landmarks[i].observations.back().v_px);
    }
  }
  // Old Mac CR-only endings are not line endings: a clear error on line 1.
  std::string cr = lf;
  for (char& c : cr) c = c == '\n' ? '\r' : c;
  try {
    read_text(cr);
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_EQ(e.line(), 1u);
    for (char c : std::string(e.what())) EXPECT_NE(c, '\r') << e.what();
  }
}

TEST(DegenerateMapFile, ControlBytesInErrorsAreEscapedToOnePrintableLine) {
  try {
    static const char kText[] = "FRAME 0 0 0 0 1 0 0 \x1b[31m\0\n";
    read_text(std::string(kText, sizeof(kText) - 1));
    FAIL();
  } catch (const ParseError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("\\x1b[31m\\x00"), std::string::npos) << what;
    for (char c : what) EXPECT_GE(static_cast<unsigned char>(c), 0x20) << what;
  }
}

// ---------------------------------------------------------------------------------------------
// Paths and streams

TEST(DegenerateMapFile, NonUtf8PathsWorkAndErrorsNameTheirBytes) {
  TempDir dir;
  const std::string path = dir.file("map_\xff\xfe_latin1_\xe9.txt");
  write_bytes(path, kFrames + kLandmarks);
  EXPECT_EQ(read_map(path).landmarks.size(), 2u);
  const std::string missing = dir.file("missing_\xff.txt");
  try {
    read_map(missing);
    FAIL();
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }
  // Errors inside such a file name it too.
  const std::string bad = dir.file("bad_\xfe.txt");
  write_bytes(bad, "FRAME 0 0 0 0 1 0 0\n");
  try {
    read_map(bad);
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_EQ(e.file(), bad);
    EXPECT_EQ(e.line(), 1u);
  }
}

TEST(DegenerateMapFile, AStreamReadErrorIsAnIoError) {
  FailingStream failing;
  std::istream in(&failing);
  try {
    read_map(in, "device.txt");
    FAIL();
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot read map file 'device.txt'"), std::string::npos)
        << e.what();
  }
  std::istringstream bad_stream("FRAME 0 0 0 0 1 0 0 0\n");
  bad_stream.setstate(std::ios::badbit);
  EXPECT_THROW(read_map(bad_stream, "bad.txt"), IoError);
}

TEST(DegenerateMapFile, DroppedLandmarksAreStillValidatedAgainstTheFrames) {
  // The min_observations filter drops as it reads; an unknown frame in a dropped landmark is still
  // an error, on that landmark's line, even when the frames come later.
  const std::string text = "LANDMARK 1 0 0 1 1e-4 0 0 0 1e-4 0 0 0 1e-4 1 42 1 2\n" + kFrames;
  try {
    read_text(text);
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_EQ(e.line(), 1u);
    EXPECT_NE(e.detail().find("observes unknown frame 42"), std::string::npos) << e.what();
  }
  // The frame defined later resolves it; the landmark is then dropped by the filter.
  const Map map = read_text("LANDMARK 1 0 0 1 1e-4 0 0 0 1e-4 0 0 0 1e-4 1 1 1 2\n" + kFrames);
  EXPECT_EQ(map.landmarks.size(), 0u);
  EXPECT_EQ(map.frames.size(), 2u);
}

TEST(DegenerateMapFile, InvalidReadOptionsAreRefusedNamingTheField) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  struct Case {
    const char* field;
    MapReadOptions options;
  };
  std::vector<Case> cases(5);
  cases[0] = {"quaternion_norm_tolerance", {}};
  cases[0].options.quaternion_norm_tolerance = nan;
  cases[1] = {"covariance_symmetry_tolerance", {}};
  cases[1].options.covariance_symmetry_tolerance = -1e-6;
  cases[2] = {"covariance_psd_tolerance", {}};
  cases[2].options.covariance_psd_tolerance = std::numeric_limits<double>::infinity();
  cases[3] = {"max_line_bytes", {}};
  cases[3].options.max_line_bytes = 0;
  cases[4] = {"max_line_bytes", {}};
  cases[4].options.max_line_bytes = 63;
  for (const Case& c : cases) {
    try {
      read_text(kFrames, c.options);
      ADD_FAILURE() << c.field << " accepted";
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find(c.field), std::string::npos) << e.what();
    }
  }
}

TEST(DegenerateMapFile, HugeCovarianceEntriesDoNotOverflowTheChecks) {
  MapReadOptions keep_all;
  keep_all.min_observations = 0;
  // 0.5 * (c + c^T) would overflow to inf for entries near the largest double; the reader
  // symmetrises without overflow and accepts this PSD covariance.
  const Map map =
      read_text(kFrames + "LANDMARK 1 0 0 1 1.7e308 0 0 0 1.7e308 0 0 0 1.7e308 0\n", keep_all);
  ASSERT_EQ(map.landmarks.size(), 1u);
  // Eigenvalues beyond the largest double cannot be checked: a clear refusal, not a silent pass.
  try {
    read_text(kFrames + "LANDMARK 1 0 0 1 1.7e308 1e308 0 1e308 1.7e308 0 0 0 1 0\n", keep_all);
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_EQ(e.line(), 3u);
    EXPECT_NE(e.detail().find("overflow"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------------------------
// Unwritable outputs: an IoError naming the path, and nothing left behind

TEST(DegenerateOutput, UnwritablePathsAreIoErrorsAndLeaveNoFile) {
  TempDir dir;
  write_bytes(dir.file("regular"), "not a directory");
  const std::size_t before = dir.count();
  Map map = read_text(kFrames + kLandmarks);
  for (const std::string& path :
       {dir.file("regular/out.txt"), dir.file("no/such/dir/out.txt"), dir.file("")}) {
    try {
      write_map(path, map);
      ADD_FAILURE() << path << " written";
    } catch (const IoError& e) {
      EXPECT_NE(std::string(e.what()).find("cannot write '" + path + "'"), std::string::npos)
          << e.what();
    }
    EXPECT_EQ(dir.count(), before) << path;
  }
  // A directory in the way: the rename fails, the temporary file is removed.
  fs::create_directories(dir.file("a_directory"));
  EXPECT_THROW(write_map(dir.file("a_directory"), map), IoError);
  EXPECT_EQ(dir.count(), before + 1);
  EXPECT_TRUE(fs::is_directory(dir.file("a_directory")));
  EXPECT_TRUE(fs::is_empty(dir.file("a_directory")));
}

}  // namespace
}  // namespace lmalign
