// `lmalign convert` and the dispatching reader of align / split on real Bundler data
// (../shared/data/bundler_balbianello): Bundler -> ours and -> COLMAP text, then align and split
// reading the COLMAP folder by content.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

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

  // Without the image size (the file has none): a PLY output (no pixels) is written; our
  // format and split's output store pixels from the top-left corner, so they need the size and
  // say so in one line.
  const test::CliRun no_size = run("convert " + shell_quote(bundler) + " " + shell_quote(ours));
  test::expect_one_line_error(no_size, "give the image size (--image-size W,H)", "convert");
  EXPECT_FALSE(std::filesystem::exists(ours));
  const test::CliRun to_ply =
      run("convert " + shell_quote(bundler) + " " + shell_quote(path("b.ply")));
  ASSERT_EQ(to_ply.exit_code, 0) << to_ply.err;
  EXPECT_GT(read_ply_map(path("b.ply")).landmarks.size(), 200u);
  test::expect_one_line_error(run("split " + shell_quote(bundler) + " --frames 0-4 -o " +
                                  shell_quote(path("w.txt")) + " --retriangulate"),
                              "--image-size W,H", "split");

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

  // align reads the COLMAP folder by content; the same landmarks align at the identity (base ICP
  // from the identity: this checks the readers and writers, not a search).
  // --aligned-out picks the writer by extension: PLY with covariances, or our format.
  const test::CliRun align = run("align " + shell_quote(colmap) + " " + shell_quote(ours) +
                                 " --strategy base --ground-truth identity --min-observations 0 " +
                                 "--aligned-out " + shell_quote(path("aligned.ply")));
  ASSERT_EQ(align.exit_code, 0) << align.err;
  const Map aligned_ply = read_ply_map(path("aligned.ply"));
  ASSERT_EQ(aligned_ply.landmarks.size(), map.landmarks.size());
  for (std::size_t i = 0; i < map.landmarks.size(); ++i) {
    EXPECT_FALSE(aligned_ply.landmarks[i].covariance_unknown);
    EXPECT_LT((aligned_ply.landmarks[i].p_world - map.landmarks[i].p_world).norm(),
              1e-6 * (1.0 + map.landmarks[i].p_world.norm()));
  }
  const test::CliRun align_txt = run("align " + shell_quote(colmap) + " " + shell_quote(ours) +
                                     " --strategy base --ground-truth identity --aligned-out " +
                                     shell_quote(path("aligned.txt")));
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

// convert keeps landmarks of low parallax with their (large) covariance and drops only what
// cannot be triangulated, printing every kind: the real desk map written as a COLMAP model and
// read back. Measured: 22,338 landmarks, 4,785 triangulated at >= 1 deg, 1,291 below it kept,
// 16,257 seen from one frame and 5 that do not triangulate dropped.
TEST_F(CliConvert, KeepsLowParallaxLandmarksAndCountsEveryKind) {
  const std::string desk = test::data_file("tum_fr1_desk/map_fr1_desk.txt");
  LMALIGN_REQUIRE_FILE(desk);
  const std::string colmap = path("desk") + "/";
  ASSERT_EQ(run("convert " + shell_quote(desk) + " " + shell_quote(colmap)).exit_code, 0);
  const test::CliRun all = run("convert " + shell_quote(colmap) + " " + shell_quote(path("a.txt")));
  ASSERT_EQ(all.exit_code, 0) << all.err;
  const test::CliRun one_deg = run("convert " + shell_quote(colmap) + " " +
                                   shell_quote(path("b.txt")) + " --min-parallax 1");
  ASSERT_EQ(one_deg.exit_code, 0) << one_deg.err;
  // "kept N <what>" / "dropped N <what>", and the total line.
  const auto count = [](const std::string& out, const std::string& verb, const std::string& what) {
    const std::size_t at = out.find(what);
    if (at == std::string::npos) return std::size_t{0};
    const std::size_t line = out.rfind(verb + " ", at);
    return static_cast<std::size_t>(std::stoul(out.substr(line + verb.size() + 1)));
  };
  const std::size_t low = count(all.out, "kept", "with low parallax (< 1 deg)");
  const std::size_t triangulated = count(all.out, "kept", "with a triangulated covariance");
  const std::size_t one_view = count(all.out, "dropped", "seen in fewer than 2 usable views");
  const std::size_t failed = count(all.out, "dropped", "that cannot be triangulated");
  EXPECT_GT(low, 500u) << all.out;
  EXPECT_GT(triangulated, 4000u) << all.out;
  EXPECT_GT(one_view, 10000u) << all.out;
  EXPECT_NE(all.out.find("landmarks: " + std::to_string(low + triangulated) + " of " +
                         std::to_string(low + triangulated + one_view + failed) + " kept, " +
                         std::to_string(one_view + failed) + " dropped"),
            std::string::npos)
      << all.out;
  // --min-parallax 1 drops exactly the low-parallax kind, and says so.
  EXPECT_EQ(count(one_deg.out, "dropped", "with parallax below 1 deg"), low) << one_deg.out;
  EXPECT_EQ(one_deg.out.find("with low parallax"), std::string::npos) << one_deg.out;
  MapReadOptions every;
  every.min_observations = 0;
  const Map kept_all = read_map(path("a.txt"), every);
  const Map kept_one = read_map(path("b.txt"), every);
  ASSERT_EQ(kept_all.landmarks.size(), low + triangulated);
  ASSERT_EQ(kept_one.landmarks.size(), triangulated);
  // The low-parallax ones (in a.txt, not in b.txt) have well-defined, larger covariances.
  std::set<Id> well_conditioned;
  for (const Landmark& l : kept_one.landmarks) well_conditioned.insert(l.id);
  std::vector<double> low_sd_m, other_sd_m;
  for (const Landmark& l : kept_all.landmarks) {
    const double largest = Eigen::SelfAdjointEigenSolver<Mat3>(l.cov_world_m2).eigenvalues()(2);
    ASSERT_TRUE(std::isfinite(largest) && largest > 0.0) << l.id;
    (well_conditioned.count(l.id) ? other_sd_m : low_sd_m).push_back(std::sqrt(largest));
  }
  ASSERT_EQ(low_sd_m.size(), low);
  std::sort(low_sd_m.begin(), low_sd_m.end());
  std::sort(other_sd_m.begin(), other_sd_m.end());
  EXPECT_GT(low_sd_m[low_sd_m.size() / 2], 2.0 * other_sd_m[other_sd_m.size() / 2]);
}

// --transform moves the map by a similarity (positions s R p + t, covariances s^2 R C R^T,
// frames with it) and --map-scale records the header's scale; bad values are refused in one
// line naming the option or the file.
// OpenMVG's camera centres (docs/map-format.md): convert and align say how many vertices they
// left out and why; the converted map holds the 365 landmarks of the real colorized.ply.
TEST_F(CliConvert, SaysWhichOpenMvgCameraCentresItLeftOut) {
  const std::string ply =
      test::data_file("real_formats/ply_openmvg_kapture_maupertuis/colorized.ply");
  LMALIGN_REQUIRE_FILE(ply);
  const test::CliRun convert =
      run("convert " + shell_quote(ply) + " " + shell_quote(path("c.ply")));
  ASSERT_EQ(convert.exit_code, 0) << convert.err;
  EXPECT_NE(convert.out.find("landmarks: 365 of 365 kept"), std::string::npos) << convert.out;
  EXPECT_NE(convert.out.find("left out 4 vertices that are OpenMVG's camera centres, not "
                             "landmarks (at the camera centres of the sfm_data.json beside it)"),
            std::string::npos)
      << convert.out;
  EXPECT_EQ(read_ply_map(path("c.ply")).landmarks.size(), 365u);
  const test::CliRun align =
      run("align " + shell_quote(ply) + " " + shell_quote(ply) + " --strategy base");
  ASSERT_EQ(align.exit_code, 0) << align.err;
  EXPECT_NE(align.out.find(ply + ": left out 4 vertices that are OpenMVG's camera centres"),
            std::string::npos)
      << align.out;
}

TEST_F(CliConvert, TransformMovesTheMapBySimilarityAndMapScaleMarksIt) {
  const std::string desk = test::data_file("tum_fr1_desk/ground_truth_pair/desk_gt_a.txt");
  LMALIGN_REQUIRE_FILE(desk);
  // s = 2, a quarter turn about z, t = (1, 2, 3).
  std::ofstream(path("M.txt")) << "0 -2 0 1\n2 0 0 2\n0 0 2 3\n0 0 0 1\n";
  const test::CliRun r = run("convert " + desk + " " + path("moved.txt") + " --transform " +
                             path("M.txt") + " --map-scale arbitrary");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const Map in = read_map(desk);
  const Map out = read_map(path("moved.txt"));
  EXPECT_EQ(out.header.scale, MapScale::kArbitrary);
  ASSERT_EQ(out.landmarks.size(), in.landmarks.size());
  ASSERT_EQ(out.frames.size(), in.frames.size());
  Mat3 sR;
  sR << 0, -2, 0, 2, 0, 0, 0, 0, 2;
  const Vec3 t(1, 2, 3);
  for (std::size_t i = 0; i < in.landmarks.size(); i += 97) {
    EXPECT_LT((out.landmarks[i].p_world - (sR * in.landmarks[i].p_world + t)).norm(), 1e-9);
    EXPECT_LT(
        (out.landmarks[i].cov_world_m2 - sR * in.landmarks[i].cov_world_m2 * sR.transpose()).norm(),
        1e-9 * (1.0 + in.landmarks[i].cov_world_m2.norm()));
  }
  EXPECT_LT((out.frames[0].p_world_camera - (sR * in.frames[0].p_world_camera + t)).norm(), 1e-9);

  const test::CliRun bad_scale = run("convert " + desk + " " + path("x.txt") + " --map-scale huge");
  EXPECT_EQ(bad_scale.exit_code, 2);
  EXPECT_NE(bad_scale.err.find("--map-scale 'huge'"), std::string::npos) << bad_scale.err;
  std::ofstream(path("shear.txt")) << "1 0.5 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
  const test::CliRun shear =
      run("convert " + desk + " " + path("y.txt") + " --transform " + path("shear.txt"));
  EXPECT_EQ(shear.exit_code, 2);
  EXPECT_NE(shear.err.find(path("shear.txt")), std::string::npos) << shear.err;
  EXPECT_FALSE(std::filesystem::exists(path("x.txt")));
  EXPECT_FALSE(std::filesystem::exists(path("y.txt")));
}

}  // namespace
}  // namespace lmalign
