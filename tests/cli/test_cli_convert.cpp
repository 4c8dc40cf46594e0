// `lmalign convert` and the dispatching reader of align / split on real Bundler data
// (../shared/data/bundler_balbianello): Bundler -> ours and -> COLMAP text, then align and split
// reading the COLMAP folder by content.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "lmalign/io/transform_io.hpp"
#include "lmalign/map/formats/colmap.hpp"
#include "lmalign/map/formats/ply.hpp"
#include "lmalign/map/map_io.hpp"
#include "support/data_path.hpp"
#include "support/run_cli.hpp"
#include "support/stella_map_writer.hpp"

namespace lmalign {
namespace {

using test::shell_quote;

class CliConvert : public test::CliTest {};

TEST_F(CliConvert, BundlerToOursAndColmapThenAlignAndSplitReadThemByContent) {
  const std::string bundler = test::data_file("bundler_balbianello/Balbianello.out");
  LMALIGN_REQUIRE_FILE(bundler);
  const std::string ours = path("balbianello.txt");
  const std::string colmap = path("colmap") + "/";

  const test::CliRun no_size = run("convert " + shell_quote(bundler) + " " + shell_quote(ours));
  EXPECT_EQ(no_size.exit_code, 2);
  EXPECT_NE(no_size.err.find("image size"), std::string::npos) << no_size.err;
  EXPECT_FALSE(std::filesystem::exists(ours));

  const test::CliRun to_ours =
      run("convert " + shell_quote(bundler) + " " + shell_quote(ours) + " --image-size 640,427");
  ASSERT_EQ(to_ours.exit_code, 0) << to_ours.err;
  EXPECT_NE(to_ours.out.find("(bundler)"), std::string::npos) << to_ours.out;
  MapReadOptions keep_all;
  keep_all.min_observations = 0;
  const Map map = read_map(ours, keep_all);
  EXPECT_EQ(map.frames.size(), 5u);
  EXPECT_GT(map.landmarks.size(), 200u);

  const test::CliRun to_colmap =
      run("convert " + shell_quote(bundler) + " " + shell_quote(colmap) + " --image-size 640,427");
  ASSERT_EQ(to_colmap.exit_code, 0) << to_colmap.err;
  const Map from_colmap = read_colmap(colmap, false);
  ASSERT_EQ(from_colmap.frames.size(), 5u);
  EXPECT_EQ(from_colmap.frames[0].camera->model, CameraModel::kRadial);

  // align reads the COLMAP folder by content; the same landmarks align at the identity.
  // --aligned-out picks the writer by extension: PLY with covariances, or our format.
  const test::CliRun align = run("align " + shell_quote(colmap) + " " + shell_quote(ours) +
                                 " --ground-truth identity --min-observations 0 --aligned-out " +
                                 shell_quote(path("aligned.ply")));
  ASSERT_EQ(align.exit_code, 0) << align.err;
  const Map aligned_ply = read_ply_map(path("aligned.ply"));
  ASSERT_EQ(aligned_ply.landmarks.size(), map.landmarks.size());
  for (std::size_t i = 0; i < map.landmarks.size(); ++i) {
    EXPECT_FALSE(aligned_ply.landmarks[i].covariance_unknown);
    EXPECT_LT((aligned_ply.landmarks[i].p_world - map.landmarks[i].p_world).norm(),
              1e-6 * (1.0 + map.landmarks[i].p_world.norm()));
  }
  const test::CliRun align_txt =
      run("align " + shell_quote(colmap) + " " + shell_quote(ours) +
          " --ground-truth identity --aligned-out " + shell_quote(path("aligned.txt")));
  ASSERT_EQ(align_txt.exit_code, 0) << align_txt.err;
  const Map aligned_map = read_map(path("aligned.txt"), keep_all);
  EXPECT_EQ(aligned_map.frames.size(), 5u);
  const test::CliRun forced = run("align " + shell_quote(colmap) + " " + shell_quote(ours) +
                                  " --format lmalign --ground-truth identity");
  EXPECT_EQ(forced.exit_code, 2);  // a folder is not an lmalign map file

  // split --retriangulate uses the frames' own RADIAL intrinsics from the COLMAP folder.
  const test::CliRun split = run("split " + shell_quote(colmap) + " --frames 0-4 -o " +
                                 shell_quote(path("split.txt")) + " --retriangulate");
  ASSERT_EQ(split.exit_code, 0) << split.err;
  const Map split_map = read_map(path("split.txt"), keep_all);
  EXPECT_GT(split_map.landmarks.size(), map.landmarks.size() / 2);
}

// experiment reads its maps through the same dispatch: a stella_vslam source, an lmalign target.
TEST_F(CliConvert, ExperimentReadsAStellaVslamSource) {
  const std::string desk = test::data_file("tum_fr1_desk/map_fr1_desk.txt");
  LMALIGN_REQUIRE_FILE(desk);
  const Map map = read_map(desk);
  std::ofstream(path("desk.msg"), std::ios::binary)
      << test::stella_map_bytes(map, PinholeIntrinsics::tum_fr1());
  write_transform(path("gt.txt"), Isometry3::Identity());
  std::ofstream(path("cfg.yaml")) << "source: desk.msg\ntarget: " << desk
                                  << "\nground_truth: gt.txt\nstrategies: [base]\n"
                                     "experiments:\n  - {name: yaws, type: yaw, yaw_deg: [0]}\n";
  const test::CliRun r = run("experiment " + shell_quote(path("cfg.yaml")) + " -o " +
                             shell_quote(path("out")) + " --no-plots");
  ASSERT_EQ(r.exit_code, 0) << r.err << r.out;
  const std::string csv = test::read_text(path("out/results.csv"));
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 2) << csv;  // header + one run
  EXPECT_NE(csv.find(",true,"), std::string::npos) << csv;        // it succeeded
}

}  // namespace
}  // namespace lmalign
