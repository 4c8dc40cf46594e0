// TUM sequence input of the map builder: lists, association, camera presets and YAML, and the
// bad-input errors (each names the file, and the line for text files).
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "lmalign/core/error.hpp"
#include "lmalign/vo/map_builder.hpp"
#include "lmalign/vo/tum_sequence.hpp"

namespace lmalign {
namespace {

namespace fs = std::filesystem;

class VoInput : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("lmalign_vo_input_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "rgb");
    fs::create_directories(dir_ / "depth");
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text) {
    const std::string p = (dir_ / name).string();
    std::ofstream(p) << text;
    return p;
  }
  // A valid two-frame sequence with textured 640x480 images.
  void make_sequence() {
    write("rgb.txt", "# rgb\n1.000 rgb/a.png\n1.100 rgb/b.png\n");
    write("depth.txt", "# depth\n1.010 depth/a.png\n1.105 depth/b.png\n");
    cv::Mat rgb(480, 640, CV_8UC3), depth(480, 640, CV_16UC1, cv::Scalar(10000));
    cv::randu(rgb, 0, 255);
    for (const char* n : {"a.png", "b.png"}) {
      cv::imwrite((dir_ / "rgb" / n).string(), rgb);
      cv::imwrite((dir_ / "depth" / n).string(), depth);
    }
  }
  template <typename E>
  std::string expect_build_error() {
    const auto seq = vo::load_tum_sequence(dir_.string());
    try {
      vo::build_map(seq, vo::MapBuilderOptions{});
    } catch (const E& e) {
      return e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << "wrong exception type: " << e.what();
      return "";
    }
    ADD_FAILURE() << "no error";
    return "";
  }
  fs::path dir_;
};

TEST_F(VoInput, AssociatesByNearestTimestampWithinMaxDifference) {
  write("rgb.txt", "1.00 rgb/1.png\n1.03 rgb/2.png\n1.20 rgb/3.png\n");
  write("depth.txt", "1.01 depth/1.png\n1.035 depth/2.png\n1.25 depth/3.png\n");
  const auto seq = vo::load_tum_sequence(dir_.string());
  ASSERT_EQ(seq.frames.size(), 2u);
  EXPECT_EQ(seq.frames[0].rgb_timestamp_s, 1.00);
  EXPECT_EQ(seq.frames[0].depth_timestamp_s, 1.01);
  EXPECT_EQ(seq.frames[1].depth_path, (dir_ / "depth/2.png").string());
  EXPECT_FALSE(seq.ground_truth.has_value());
  vo::TumSequenceOptions wide;
  wide.max_difference_s = 0.06;
  EXPECT_EQ(vo::load_tum_sequence(dir_.string(), wide).frames.size(), 3u);
}

TEST_F(VoInput, BadListsNameFileAndLine) {
  write("depth.txt", "1.0 depth/1.png\n");
  auto expect_parse = [&](const std::string& rgb, std::size_t line, const std::string& part) {
    const std::string p = write("rgb.txt", rgb);
    try {
      vo::load_tum_sequence(dir_.string());
      FAIL() << "no error for " << rgb;
    } catch (const ParseError& e) {
      EXPECT_EQ(e.file(), p);
      EXPECT_EQ(e.line(), line);
      EXPECT_NE(e.detail().find(part), std::string::npos) << e.what();
    }
  };
  expect_parse("# c\n1.0 rgb/1.png\nabc rgb/2.png\n", 3, "bad timestamp 'abc'");
  expect_parse("1.0 rgb/1.png\n0.5 rgb/2.png\n", 2, "does not increase");
  expect_parse("-1.0 rgb/1.png\n", 1, "bad timestamp");
  expect_parse("1.0\n", 1, "expected 2");
  expect_parse("1.0 rgb/1.png\n2.0 rgb/2.png x\n", 2, "expected 2");
  fs::remove(dir_ / "rgb.txt");
  try {
    vo::load_tum_sequence(dir_.string());
    FAIL();
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("rgb.txt"), std::string::npos);
  }
  write("rgb.txt", "5.0 rgb/1.png\n");
  EXPECT_THROW(vo::load_tum_sequence(dir_.string()), InvalidArgument);  // nothing associates
}

TEST_F(VoInput, MissingImageNamesFile) {
  make_sequence();
  fs::remove(dir_ / "rgb" / "b.png");
  const std::string m = expect_build_error<IoError>();
  EXPECT_NE(m.find((dir_ / "rgb/b.png").string()), std::string::npos) << m;
  EXPECT_NE(m.find("does not exist"), std::string::npos) << m;
}

TEST_F(VoInput, UnreadableImageNamesFile) {
  make_sequence();
  write("depth/a.png", "not a png");
  const std::string m = expect_build_error<IoError>();
  EXPECT_NE(m.find((dir_ / "depth/a.png").string()), std::string::npos) << m;
  EXPECT_NE(m.find("not a readable image"), std::string::npos) << m;
}

TEST_F(VoInput, DepthOfWrongTypeNamesFile) {
  make_sequence();
  cv::imwrite((dir_ / "depth" / "a.png").string(), cv::Mat(480, 640, CV_8UC1, cv::Scalar(3)));
  const std::string m = expect_build_error<ParseError>();
  EXPECT_NE(m.find((dir_ / "depth/a.png").string()), std::string::npos) << m;
  EXPECT_NE(m.find("expected 16-bit single-channel"), std::string::npos) << m;
}

TEST_F(VoInput, DepthOfWrongSizeNamesFile) {
  make_sequence();
  cv::imwrite((dir_ / "depth" / "b.png").string(), cv::Mat(240, 320, CV_16UC1, cv::Scalar(3)));
  const std::string m = expect_build_error<ParseError>();
  EXPECT_NE(m.find((dir_ / "depth/b.png").string()), std::string::npos) << m;
  EXPECT_NE(m.find("320x240"), std::string::npos) << m;
}

TEST_F(VoInput, RgbOfWrongSizeNamesFile) {
  make_sequence();
  cv::imwrite((dir_ / "rgb" / "a.png").string(), cv::Mat(100, 100, CV_8UC3, cv::Scalar(3)));
  const std::string m = expect_build_error<ParseError>();
  EXPECT_NE(m.find((dir_ / "rgb/a.png").string()), std::string::npos) << m;
}

TEST_F(VoInput, InitFromGroundTruthNeedsGroundTruth) {
  make_sequence();
  const auto seq = vo::load_tum_sequence(dir_.string());
  vo::MapBuilderOptions o;
  o.init_from_ground_truth = true;
  EXPECT_THROW(vo::build_map(seq, o), InvalidArgument);
  write("groundtruth.txt", "1.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n");
  try {
    vo::load_tum_sequence(dir_.string());
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_EQ(e.line(), 2u);
  }
}

TEST(VoCamera, PresetsAndYaml) {
  EXPECT_EQ(vo::tum_camera_preset("fr1").pinhole.fx_px, 517.3);
  EXPECT_EQ(vo::tum_camera_preset("fr2").pinhole.cx_px, 325.1);
  EXPECT_EQ(vo::tum_camera_preset("fr3").pinhole.fy_px, 539.2);
  EXPECT_THROW(vo::tum_camera_preset("fr4"), InvalidArgument);

  const fs::path dir = fs::temp_directory_path() / ("lmalign_vo_cam_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string p = (dir / "cam.yaml").string();
  std::ofstream(p) << "%YAML:1.0\n# TUM fr3\nfx: 535.4\nfy: 539.2\ncx: 320.1\ncy: 247.6\n"
                      "width: 640\nheight: 480\ndepth_scale: 5000  # units per metre\n";
  const auto c = vo::read_camera_yaml(p);
  EXPECT_EQ(c.pinhole.fx_px, 535.4);
  EXPECT_EQ(c.pinhole.cy_px, 247.6);
  EXPECT_EQ(c.depth_units_per_m, 5000.0);
  auto expect_line = [&](const std::string& text, std::size_t line) {
    std::ofstream(p) << text;
    try {
      vo::read_camera_yaml(p);
      FAIL() << text;
    } catch (const ParseError& e) {
      EXPECT_EQ(e.file(), p);
      EXPECT_EQ(e.line(), line) << e.what();
    }
  };
  expect_line("fx: 1\nfy: abc\n", 2);
  expect_line("fx: 1\nfoo: 2\n", 2);
  expect_line("fx: 1\nfx: 2\n", 2);
  expect_line("fx: 1\nfy: 1\ncx: 1\n", 0);  // missing cy
  expect_line("fx: -1\nfy: 1\ncx: 1\ncy: 1\n", 0);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lmalign
