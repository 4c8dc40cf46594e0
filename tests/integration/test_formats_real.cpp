// Other map formats on real data: Balbianello (a real Bundler reconstruction from GTSAM's
// examples, ../shared/data/bundler_balbianello), the real files of ../shared/data/real_formats
// (written by COLMAP, OpenVSLAM / stella_vslam, OpenMVG and a COLMAP exporter; each folder's
// SOURCE.md gives the counts checked here) and the real desk map written as COLMAP text.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>
#include <nlohmann/json.hpp>

#include "lmalign/core/error.hpp"
#include "lmalign/map/formats/bundler.hpp"
#include "lmalign/map/formats/colmap.hpp"
#include "lmalign/map/formats/formats.hpp"
#include "lmalign/map/formats/ply.hpp"
#include "lmalign/map/formats/stella_vslam.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/map/split.hpp"
#include "lmalign/weights/weights.hpp"
#include "support/data_path.hpp"
#include "support/map_compare.hpp"
#include "support/stella_map_writer.hpp"
#include "support/temp_dir.hpp"

namespace lmalign {
namespace {

const std::string kBundler = "bundler_balbianello/Balbianello.out";
const std::string kDesk = "tum_fr1_desk/map_fr1_desk.txt";

AnyMapReadOptions balbianello_options() {
  AnyMapReadOptions options;
  options.image_size_px = std::array<long long, 2>{640, 427};  // SOURCE.md: all five photos
  return options;
}

// Each camera's reprojection of its points matches the file: SOURCE.md gives, with Bundler's
// own conventions, a median of 0.13 px, a 95th percentile of 0.66 px and a max of 6.9 px over the
// 1,417 observations. A wrong sign or axis in the conversion gives hundreds of pixels.
TEST(BundlerReal, ReprojectionMatchesTheFile) {
  const std::string path = test::data_file(kBundler);
  LMALIGN_REQUIRE_FILE(path);
  EXPECT_EQ(detect_map_format(path), MapFormat::kBundler);
  const Map map = read_bundler(path, {640, 427});
  ASSERT_EQ(map.frames.size(), 5u);
  ASSERT_EQ(map.landmarks.size(), 544u);
  std::vector<double> errors_px;
  for (const Landmark& landmark : map.landmarks) {
    for (const Observation& obs : landmark.observations) {
      const Frame& frame = *map.find_frame(obs.frame_id);
      const Vec3 p_camera = frame.T_world_camera().inverse() * landmark.p_world;
      ASSERT_GT(p_camera.z(), 0.0) << "landmark " << landmark.id << " behind camera " << frame.id;
      errors_px.push_back(
          (frame.camera->project(p_camera) - Eigen::Vector2d(obs.u_px, obs.v_px)).norm());
    }
  }
  ASSERT_EQ(errors_px.size(), 1417u);
  std::sort(errors_px.begin(), errors_px.end());
  EXPECT_LT(errors_px[errors_px.size() / 2], 0.2);
  EXPECT_LT(errors_px[errors_px.size() * 95 / 100], 0.7);
  EXPECT_LT(errors_px.back(), 7.0);
  // Pixels are inside the 640 x 427 images (origin top-left, v down).
  for (const Landmark& landmark : map.landmarks) {
    for (const Observation& obs : landmark.observations) {
      EXPECT_TRUE(obs.u_px >= 0 && obs.u_px <= 640 && obs.v_px >= 0 && obs.v_px <= 427);
    }
  }
}

// Derived covariances: every kept landmark has >= 2 views and a positive definite covariance;
// the map round-trips bit-exactly through our text format and through COLMAP text.
TEST(BundlerReal, ConfidencesAndRoundTrips) {
  const std::string path = test::data_file(kBundler);
  LMALIGN_REQUIRE_FILE(path);
  AnyMapReadOptions keep = balbianello_options();
  keep.map.min_observations = 0;
  keep.keep_unknown_covariance = true;
  const Map all = read_any_map(path, keep);
  ASSERT_EQ(all.landmarks.size(), 544u);
  std::size_t flagged = 0;
  for (const Landmark& l : all.landmarks) {
    if (l.covariance_unknown) {
      ++flagged;
      EXPECT_EQ(l.cov_world_m2, Mat3::Zero());
    } else {
      EXPECT_GE(l.observations.size(), 2u);
      EXPECT_GT(Eigen::SelfAdjointEigenSolver<Mat3>(l.cov_world_m2).eigenvalues()(0), 0.0);
    }
  }
  EXPECT_LT(flagged, all.landmarks.size() / 2);  // most points are well triangulated

  const Map map = read_any_map(path, balbianello_options());
  EXPECT_EQ(map.landmarks.size(), all.landmarks.size() - flagged);
  test::ScratchDir dir("bundler_real");
  write_map(dir.file("ours.txt"), map);
  MapReadOptions ro;
  ro.min_observations = 0;
  EXPECT_TRUE(test::maps_identical(read_map(dir.file("ours.txt"), ro), map));

  write_colmap_text(dir.file("colmap"), map);
  const Map colmap = read_colmap(dir.file("colmap"), false);
  ASSERT_EQ(colmap.frames.size(), map.frames.size());
  for (std::size_t i = 0; i < map.frames.size(); ++i) {
    EXPECT_LT((colmap.frames[i].T_world_camera().matrix() - map.frames[i].T_world_camera().matrix())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-12);
    EXPECT_EQ(colmap.frames[i].camera->params, map.frames[i].camera->params);
  }
  ASSERT_EQ(colmap.landmarks.size(), map.landmarks.size());
  for (std::size_t i = 0; i < map.landmarks.size(); ++i) {
    EXPECT_EQ(colmap.landmarks[i].p_world, map.landmarks[i].p_world);
    ASSERT_EQ(colmap.landmarks[i].observations.size(), map.landmarks[i].observations.size());
    for (std::size_t k = 0; k < map.landmarks[i].observations.size(); ++k) {
      EXPECT_EQ(colmap.landmarks[i].observations[k].u_px, map.landmarks[i].observations[k].u_px);
      EXPECT_EQ(colmap.landmarks[i].observations[k].v_px, map.landmarks[i].observations[k].v_px);
    }
  }
}

// The real desk map through our COLMAP writer and back through the dispatching reader: poses,
// positions and observations survive; covariances are re-derived (1 px, TUM intrinsics).
TEST(ColmapReal, DeskMapThroughColmapText) {
  const std::string path = test::data_file(kDesk);
  LMALIGN_REQUIRE_FILE(path);
  const Map desk = read_map(path);
  test::ScratchDir dir("colmap_desk");
  write_colmap_text(dir.file("model"), desk);
  AnyMapReadOptions options;
  options.map.min_observations = 0;
  options.keep_unknown_covariance = true;
  const Map back = read_any_map(dir.file("model"), options);
  ASSERT_EQ(back.frames.size(), desk.frames.size());
  for (std::size_t i = 0; i < desk.frames.size(); ++i) {
    EXPECT_LT((back.frames[i].p_world_camera - desk.frames[i].p_world_camera).norm(), 1e-12);
    EXPECT_LT(back.frames[i].T_world_camera().linear().isApprox(
                  desk.frames[i].T_world_camera().linear(), 1e-12)
                  ? 0
                  : 1,
              1);
  }
  ASSERT_EQ(back.landmarks.size(), desk.landmarks.size());
  std::size_t known = 0;
  for (std::size_t i = 0; i < desk.landmarks.size(); ++i) {
    EXPECT_EQ(back.landmarks[i].p_world, desk.landmarks[i].p_world);
    EXPECT_EQ(back.landmarks[i].observations.size(), desk.landmarks[i].observations.size());
    if (!back.landmarks[i].covariance_unknown) ++known;
  }
  EXPECT_GT(known, desk.landmarks.size() / 2);
}

// The real desk map as a stella_vslam map database, written by the test's own MessagePack
// encoder, read back: poses, positions and every observation's pixel.
TEST(StellaVslamReal, DeskMapThroughTheTestsOwnMessagePackWriter) {
  const std::string path = test::data_file(kDesk);
  LMALIGN_REQUIRE_FILE(path);
  const Map desk = read_map(path);
  test::ScratchDir dir("stella_desk");
  {
    std::ofstream out(dir.file("desk.msg"), std::ios::binary);
    out << test::stella_map_bytes(desk, PinholeIntrinsics::tum_fr1());
  }
  EXPECT_EQ(detect_map_format(dir.file("desk.msg")), MapFormat::kStellaVslam);
  const Map back = read_stella_vslam(dir.file("desk.msg"));
  ASSERT_EQ(back.frames.size(), desk.frames.size());
  for (const Frame& f : desk.frames) {  // the reader orders frames by id
    const Frame* b = back.find_frame(f.id);
    ASSERT_NE(b, nullptr);
    EXPECT_LT((b->p_world_camera - f.p_world_camera).norm(), 1e-12);
    EXPECT_TRUE(b->T_world_camera().linear().isApprox(f.T_world_camera().linear(), 1e-12));
    EXPECT_EQ(b->camera->model, CameraModel::kPinhole);
    EXPECT_EQ(b->camera->params, (std::vector<double>{517.3, 516.5, 318.6, 255.3}));
  }
  ASSERT_EQ(back.landmarks.size(), desk.landmarks.size());
  std::map<Id, const Landmark*> by_id;
  for (const Landmark& l : back.landmarks) by_id[l.id] = &l;
  auto key = [](const Observation& o) { return std::make_tuple(o.frame_id, o.u_px, o.v_px); };
  for (const Landmark& l : desk.landmarks) {
    const Landmark& b = *by_id.at(l.id);
    EXPECT_EQ(b.p_world, l.p_world);
    std::vector<std::tuple<Id, double, double>> expected, got;
    for (const Observation& o : l.observations) expected.push_back(key(o));
    for (const Observation& o : b.observations) got.push_back(key(o));
    std::sort(expected.begin(), expected.end());
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, expected) << "landmark " << l.id;
  }
  // Through read_any_map: covariances derived (1 px), most landmarks keep one.
  const Map any = read_any_map(dir.file("desk.msg"));
  EXPECT_GT(any.landmarks.size(), desk.landmarks.size() / 2);
}

// The real desk map as a COLMAP binary model written by the test's own minimal writer (COLMAP's
// layout: cameras.bin, images.bin, points3D.bin), read back by the dispatching reader.
template <typename T>
void put(std::string& out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out.append(bytes, sizeof(T));
}

TEST(ColmapReal, DeskMapThroughTheTestsOwnBinaryWriter) {
  const std::string path = test::data_file(kDesk);
  LMALIGN_REQUIRE_FILE(path);
  const Map desk = read_map(path);
  std::string cameras, images, points;
  put<std::uint64_t>(cameras, 1);
  put<std::uint32_t>(cameras, 1);
  put<std::int32_t>(cameras, 1);  // PINHOLE
  put<std::uint64_t>(cameras, 640);
  put<std::uint64_t>(cameras, 480);
  for (double p : {517.3, 516.5, 318.6, 255.3}) put(cameras, p);
  // 2-D points per frame, and each landmark's track (image id, index).
  std::map<Id, std::vector<std::pair<const Observation*, Id>>> points2d;
  std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> tracks(desk.landmarks.size());
  for (std::size_t l = 0; l < desk.landmarks.size(); ++l) {
    for (const Observation& o : desk.landmarks[l].observations) {
      auto& list = points2d[o.frame_id];
      tracks[l].emplace_back(static_cast<std::uint32_t>(o.frame_id + 1),
                             static_cast<std::uint32_t>(list.size()));
      list.emplace_back(&o, desk.landmarks[l].id);
    }
  }
  put<std::uint64_t>(images, desk.frames.size());
  for (const Frame& f : desk.frames) {
    const Quat q_cw = f.q_world_camera.normalized().conjugate();
    const Vec3 t_cw = -(q_cw * f.p_world_camera);
    put<std::uint32_t>(images, static_cast<std::uint32_t>(f.id + 1));  // COLMAP ids from 1
    for (double v : {q_cw.w(), q_cw.x(), q_cw.y(), q_cw.z(), t_cw.x(), t_cw.y(), t_cw.z()}) {
      put(images, v);
    }
    put<std::uint32_t>(images, 1);
    images += "frame.png";
    images.push_back('\0');
    const auto& list = points2d[f.id];
    put<std::uint64_t>(images, list.size());
    for (const auto& [o, landmark_id] : list) {
      put(images, o->u_px);
      put(images, o->v_px);
      put<std::uint64_t>(images, static_cast<std::uint64_t>(landmark_id + 1));
    }
  }
  put<std::uint64_t>(points, desk.landmarks.size());
  for (std::size_t l = 0; l < desk.landmarks.size(); ++l) {
    put<std::uint64_t>(points, static_cast<std::uint64_t>(desk.landmarks[l].id + 1));
    for (int i = 0; i < 3; ++i) put(points, desk.landmarks[l].p_world(i));
    for (int i = 0; i < 3; ++i) put<std::uint8_t>(points, 128);
    put(points, 0.0);
    put<std::uint64_t>(points, tracks[l].size());
    for (const auto& [image, index] : tracks[l]) {
      put(points, image);
      put(points, index);
    }
  }
  test::ScratchDir dir("colmap_desk_bin");
  for (const auto& [file, bytes] :
       {std::pair<const char*, const std::string*>{"cameras.bin", &cameras},
        {"images.bin", &images},
        {"points3D.bin", &points}}) {
    std::ofstream(dir.file(file), std::ios::binary) << *bytes;
  }
  EXPECT_EQ(detect_map_format(dir.path()), MapFormat::kColmapBinary);
  AnyMapReadOptions options;
  options.map.min_observations = 0;
  options.keep_unknown_covariance = true;
  const Map back = read_any_map(dir.path(), options);
  ASSERT_EQ(back.frames.size(), desk.frames.size());
  for (std::size_t i = 0; i < desk.frames.size(); ++i) {
    EXPECT_EQ(back.frames[i].id, desk.frames[i].id + 1);
    EXPECT_LT((back.frames[i].p_world_camera - desk.frames[i].p_world_camera).norm(), 1e-12);
  }
  ASSERT_EQ(back.landmarks.size(), desk.landmarks.size());
  for (std::size_t l = 0; l < desk.landmarks.size(); ++l) {
    EXPECT_EQ(back.landmarks[l].p_world, desk.landmarks[l].p_world);
    ASSERT_EQ(back.landmarks[l].observations.size(), desk.landmarks[l].observations.size());
    for (std::size_t k = 0; k < desk.landmarks[l].observations.size(); ++k) {
      EXPECT_EQ(back.landmarks[l].observations[k].frame_id,
                desk.landmarks[l].observations[k].frame_id + 1);
      EXPECT_EQ(back.landmarks[l].observations[k].u_px, desk.landmarks[l].observations[k].u_px);
    }
  }
  // Observation count and mean viewing distance come from the tracks: the same as the desk map's.
  for (std::size_t l = 0; l < desk.landmarks.size(); l += 97) {
    EXPECT_NEAR(mean_observation_distance_m(back.landmarks[l], back),
                mean_observation_distance_m(desk.landmarks[l], desk), 1e-9);
  }
}

// ---- ../shared/data/real_formats

const std::string kStella = "real_formats/stella_openhps_aist_living_lab_1/";
struct StellaCounts {
  const char* folder;
  std::size_t keyframes;
  std::size_t landmarks;
  std::size_t observations;
};
// SOURCE.md's counts (kf->landmark observations: every lm_ids entry >= 0).
constexpr StellaCounts kStellaMaps[] = {
    {"94eb7149", 15, 1062, 7685}, {"356a5a6e", 14, 1018, 6825}, {"4683e8ac", 23, 1701, 12495}};

// Three monocular equirectangular maps written by OpenVSLAM / stella_vslam: every keyframe,
// landmark and observation is read with its camera (EQUIRECTANGULAR 1920 x 960), and the stored
// landmarks reproject onto their keypoints through it: the camera, the pose inversion (rot_cw x
// y z w) and the keypoints (undist_keypts as [x, y]) are read right. Measured: median 0.84-0.89
// px, 95th percentile 3.1 px; a wrong convention gives hundreds of pixels.
TEST(StellaVslamReal, ThreeEquirectangularMapsReadWithTheirCamera) {
  for (const StellaCounts& c : kStellaMaps) {
    const std::string path = test::data_file(kStella + c.folder + "/map.msg");
    LMALIGN_REQUIRE_FILE(path);
    SCOPED_TRACE(path);
    EXPECT_EQ(detect_map_format(path), MapFormat::kStellaVslam);
    const Map map = read_stella_vslam(path);
    ASSERT_EQ(map.frames.size(), c.keyframes);
    ASSERT_EQ(map.landmarks.size(), c.landmarks);
    std::size_t observations = 0;
    std::vector<double> errors_px;
    for (const Frame& f : map.frames) {
      ASSERT_TRUE(f.camera.has_value());
      EXPECT_EQ(f.camera->model, CameraModel::kEquirectangular);
      EXPECT_EQ(f.camera->params, (std::vector<double>{1920, 960}));
    }
    for (const Landmark& l : map.landmarks) {
      for (const Observation& o : l.observations) {
        ++observations;
        const Frame& f = *map.find_frame(o.frame_id);
        const Eigen::Vector2d px = f.camera->project(f.T_world_camera().inverse() * l.p_world);
        double du = std::abs(px.x() - o.u_px);
        du = std::min(du, 1920.0 - du);  // the longitude wraps around
        errors_px.push_back(std::hypot(du, px.y() - o.v_px));
      }
    }
    EXPECT_EQ(observations, c.observations);
    std::sort(errors_px.begin(), errors_px.end());
    EXPECT_LT(errors_px[errors_px.size() / 2], 1.0);
    EXPECT_LT(errors_px[errors_px.size() * 95 / 100], 3.5);

    // Through read_any_map: covariances triangulated from bearing vectors, with rays all
    // around the camera; almost every landmark (two or more views) gets one.
    const Map any = read_any_map(path);
    EXPECT_GT(any.landmarks.size(), c.landmarks * 95 / 100);
    for (const Landmark& l : any.landmarks) {
      ASSERT_FALSE(l.covariance_unknown);
      ASSERT_GT(Eigen::SelfAdjointEigenSolver<Mat3>(l.cov_world_m2).eigenvalues()(0), 0.0);
    }
  }
}

// split --retriangulate on an equirectangular map: the landmarks re-estimated from a window's
// bearing vectors alone land near the positions stella_vslam stored (its own bundle adjustment
// over all keyframes). The keyframes lie almost on a line (SOURCE.md), so only landmarks with
// parallax are compared.
TEST(StellaVslamReal, RetriangulatedWindowAgreesWithTheStoredLandmarks) {
  const std::string path = test::data_file(kStella + "4683e8ac/map.msg");
  LMALIGN_REQUIRE_FILE(path);
  AnyMapReadOptions all;
  all.map.min_observations = 0;
  const Map map = read_any_map(path, all);
  SplitOptions o;
  o.first_frame_id = map.frames.front().id;
  o.last_frame_id = map.frames.back().id;
  o.retriangulate = true;
  o.min_observations = 3;
  o.min_parallax_deg = 5.0;
  SplitStats stats;
  const Map window = split_map(map, o, &stats);
  ASSERT_GT(window.landmarks.size(), 500u);
  std::map<Id, const Landmark*> stored;
  for (const Landmark& l : map.landmarks) stored[l.id] = &l;
  std::vector<double> relative;  // |retriangulated - stored| / distance to the nearest camera
  for (const Landmark& l : window.landmarks) {
    double nearest = std::numeric_limits<double>::infinity();
    for (const Frame& f : window.frames) {
      nearest = std::min(nearest, (f.p_world_camera - l.p_world).norm());
    }
    relative.push_back((l.p_world - stored.at(l.id)->p_world).norm() / nearest);
  }
  std::sort(relative.begin(), relative.end());
  EXPECT_LT(relative[relative.size() / 2], 0.02);
}

// A COLMAP text model written by COLMAP (kapture's Maupertuis sample): 1 SIMPLE_PINHOLE camera,
// 4 images, 1,039 points, 3,355 track elements; coordinates printed with 6 digits.
TEST(ColmapReal, MaupertuisModelReadsWithItsCamera) {
  const std::string dir = test::data_file("real_formats/colmap_txt_kapture_maupertuis");
  LMALIGN_REQUIRE_FILE(dir);
  EXPECT_EQ(detect_map_format(dir), MapFormat::kColmapText);
  std::vector<double> errors;
  const Map map = read_colmap(dir, false, {}, &errors);
  ASSERT_EQ(map.frames.size(), 4u);
  ASSERT_EQ(map.landmarks.size(), 1039u);
  std::size_t observations = 0;
  for (const Landmark& l : map.landmarks) observations += l.observations.size();
  EXPECT_EQ(observations, 3355u);
  for (const Frame& f : map.frames) {
    EXPECT_EQ(f.camera->model, CameraModel::kSimplePinhole);
    EXPECT_EQ(f.camera->params, (std::vector<double>{1847.53, 959.5, 539.5}));
    EXPECT_EQ(f.camera->width_px, 1919);
  }
  // The stored points reproject onto their pixels within COLMAP's stored ERROR (max 2.66 px).
  double worst = 0.0;
  for (const Landmark& l : map.landmarks) {
    for (const Observation& o : l.observations) {
      const Frame& f = *map.find_frame(o.frame_id);
      worst = std::max(worst, (f.camera->project(f.T_world_camera().inverse() * l.p_world) -
                               Eigen::Vector2d(o.u_px, o.v_px))
                                  .norm());
    }
  }
  EXPECT_LT(worst, 8.0);
  const Map any = read_any_map(dir);
  EXPECT_GT(any.landmarks.size(), 1000u);
}

// A COLMAP-like model written by kapture's early exporter: fields separated by ", ", two
// OPENCV_FISHEYE cameras (Intel T265), six images, no points. The cameras and images read.
TEST(ColmapReal, T265FisheyeModelReadsItsCameras) {
  const std::string dir = test::data_file("real_formats/colmap_txt_kapture_t265_nonstandard");
  LMALIGN_REQUIRE_FILE(dir);
  const Map map = read_colmap(dir, false);
  ASSERT_EQ(map.frames.size(), 6u);
  EXPECT_TRUE(map.landmarks.empty());
  for (const Frame& f : map.frames) {
    ASSERT_TRUE(f.camera.has_value());
    EXPECT_EQ(f.camera->model, CameraModel::kOpenCvFisheye);
    EXPECT_EQ(f.camera->width_px, 848);
    EXPECT_EQ(f.camera->height_px, 800);
  }
  EXPECT_EQ(
      map.find_frame(1)->camera->params,
      (std::vector<double>{283.999, 285.266, 417.246, 400.402, -0.002, 0.039, -0.038, 0.007}));
  // It has no 3-D point: as a map to align it is refused, in one line naming it.
  try {
    read_any_map(dir);
    ADD_FAILURE() << "a map without landmarks was read";
  } catch (const InvalidArgument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("map '" + dir + "' has no landmarks (colmap-text: 6 frames, 0 landmarks)"),
              std::string::npos)
        << what;
    EXPECT_EQ(what.find('\n'), std::string::npos);
  }
}

// Each real file records whether it has a metric scale: COLMAP and Bundler (structure from
// motion) and monocular stella_vslam do not; our own desk map (RGB-D SLAM) does.
TEST(FormatsReal, EachFileRecordsItsScale) {
  const std::vector<std::pair<std::string, MapScale>> files = {
      {kStella + "94eb7149/map.msg", MapScale::kArbitrary},
      {"real_formats/colmap_txt_kapture_maupertuis", MapScale::kArbitrary},
      {kBundler, MapScale::kArbitrary},
      {"real_formats/ply_openmvg_kapture_maupertuis/colorized.ply", MapScale::kUnknown},
      {kDesk, MapScale::kMetric}};
  for (const auto& [file, scale] : files) {
    const std::string path = test::data_file(file);
    LMALIGN_REQUIRE_FILE(path);
    AnyMapReadOptions keep;
    keep.keep_unknown_covariance = true;  // the PLY has no covariances
    EXPECT_EQ(read_any_map(path, keep).header.scale, scale) << file;
  }
}

// Every map file in ../shared/data/real_formats reads through read_any_map, found by walking the
// folder (a file added there is covered without editing this list): the three stella_vslam maps,
// the COLMAP model and OpenMVG's three PLYs (two binary with double coordinates, one ASCII; the
// four camera centres OpenMVG adds as green vertices are left out, OpenMVGCameraCentresLeftOut;
// no covariances, so they are assumed from the spacing). The one model without a 3-D
// point is refused in one line naming it. Counts from each folder's SOURCE.md.
TEST(FormatsReal, EveryRealFileReads) {
  const std::string root = test::data_file("real_formats");
  LMALIGN_REQUIRE_FILE(root);
  const std::map<std::string, std::size_t> expected_vertices = {
      {"ply_openmvg_kapture_maupertuis/cloud_and_poses.ply", 365},
      {"ply_openmvg_kapture_maupertuis/colorized.ply", 365},
      {"ply_openmvg_kapture_maupertuis/robust.ply", 523}};
  const std::string empty_model = "colmap_txt_kapture_t265_nonstandard";
  std::map<std::string, std::size_t> read;  // relative path -> landmarks
  std::vector<std::string> refused;
  std::vector<std::filesystem::path> candidates;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(root)) {
    candidates.push_back(entry.path());
  }
  std::sort(candidates.begin(), candidates.end());
  for (const std::filesystem::path& p : candidates) {
    const std::string relative = std::filesystem::relative(p, root).generic_string();
    SCOPED_TRACE(relative);
    if (std::filesystem::is_regular_file(p) &&
        std::filesystem::exists(p.parent_path() / "cameras.txt")) {
      continue;  // a file of a COLMAP model, read as its folder
    }
    MapFormat format;
    try {
      format = detect_map_format(p.string());
    } catch (const InvalidArgument&) {
      continue;  // not a map (SOURCE.md, a README, OpenMVG's JSON, the camera YAML)
    }
    if (std::filesystem::is_directory(p) && format == MapFormat::kLmalign) continue;
    try {
      const Map map = read_any_map(p.string());
      ASSERT_FALSE(map.landmarks.empty());
      for (const Landmark& l : map.landmarks) {
        ASSERT_TRUE(l.p_world.allFinite()) << l.id;
        ASSERT_FALSE(l.covariance_unknown) << l.id;
      }
      // OpenMVG's PLYs store no covariance: assumed from the spacing, and flagged.
      EXPECT_EQ(map.header.covariance_assumed, format == MapFormat::kPly);
      read[relative] = map.landmarks.size();
    } catch (const InvalidArgument& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
      EXPECT_NE(what.find("map '" + p.string() + "' has no landmarks"), std::string::npos) << what;
      refused.push_back(relative);
    }
  }
  EXPECT_EQ(refused, std::vector<std::string>{empty_model});
  ASSERT_EQ(read.size(), 7u);  // 3 stella_vslam maps, 1 COLMAP model, 3 PLYs
  for (const auto& [file, vertices] : expected_vertices) EXPECT_EQ(read.at(file), vertices);
  EXPECT_GT(read.at("colmap_txt_kapture_maupertuis"), 1000u);
  for (const StellaCounts& c : kStellaMaps) {
    const std::size_t n =
        read.at(std::string("stella_openhps_aist_living_lab_1/") + c.folder + "/map.msg");
    EXPECT_GT(n, c.landmarks * 9 / 10);
    EXPECT_LE(n, c.landmarks);
  }
  // The binary PLY (double coordinates, camera centres first) and the ASCII one (camera centres
  // last) hold the same 365 landmarks to the ASCII's 16 digits.
  const Map binary = read_ply_map(root + "/ply_openmvg_kapture_maupertuis/cloud_and_poses.ply");
  const Map ascii = read_ply_map(root + "/ply_openmvg_kapture_maupertuis/colorized.ply");
  ASSERT_EQ(binary.landmarks.size(), 365u);
  ASSERT_EQ(ascii.landmarks.size(), 365u);
  for (std::size_t i = 0; i < 365; ++i) {
    const Vec3& b = binary.landmarks[i].p_world;
    ASSERT_LT((b - ascii.landmarks[i].p_world).norm(), 1e-12 * (1.0 + b.norm())) << i;
  }
}

// OpenMVG's camera centres (ply.hpp, docs/map-format.md): checked against sfm_data.json, read
// here on its own with nlohmann::json (its 4 poses' centres are exact, its 365 structure points
// are the final cloud). Each of the three PLYs loses exactly its 4 green vertices at those
// centres and keeps every other vertex; the final clouds are sfm_data.json's structure. Copied
// alone into a folder, the binary files are still recognised by OpenMVG's comment; the ASCII
// colorized.ply (no comment) then keeps them (the rule does not guess from the colour alone).
TEST(FormatsReal, OpenMvgCameraCentresLeftOut) {
  const std::string dir = test::data_file("real_formats/ply_openmvg_kapture_maupertuis");
  LMALIGN_REQUIRE_FILE(dir + "/sfm_data.json");
  std::ifstream in(dir + "/sfm_data.json");
  const nlohmann::json scene = nlohmann::json::parse(in);
  std::vector<Vec3> centres, structure;
  for (const auto& e : scene.at("extrinsics")) {
    const auto& c = e.at("value").at("center");
    centres.emplace_back(c[0].get<double>(), c[1].get<double>(), c[2].get<double>());
  }
  for (const auto& s : scene.at("structure")) {
    const auto& X = s.at("value").at("X");
    structure.emplace_back(X[0].get<double>(), X[1].get<double>(), X[2].get<double>());
  }
  ASSERT_EQ(centres.size(), 4u);
  ASSERT_EQ(structure.size(), 365u);
  const auto nearest = [](const Vec3& p, const std::vector<Vec3>& set) {
    double best = std::numeric_limits<double>::infinity();
    for (const Vec3& q : set) best = std::min(best, (p - q).norm());
    return best;
  };
  test::ScratchDir alone("openmvg_alone");
  const std::vector<std::tuple<std::string, std::size_t, bool>> files = {
      {"cloud_and_poses.ply", 365, true}, {"colorized.ply", 365, false}, {"robust.ply", 523, true}};
  for (const auto& [file, landmarks, has_comment] : files) {
    SCOPED_TRACE(file);
    PlyReadReport report;
    const Map map = read_ply_map(dir + "/" + file, &report);
    EXPECT_EQ(report.vertices, landmarks + 4);
    EXPECT_EQ(report.camera_centres_left_out, 4u);
    EXPECT_NE(report.camera_centres_rule.find("sfm_data.json"), std::string::npos);
    ASSERT_EQ(map.landmarks.size(), landmarks);
    // None at a camera centre (the nearest is > 1 cm away in a scene of about 1 unit).
    for (const Landmark& l : map.landmarks) ASSERT_GT(nearest(l.p_world, centres), 1e-3) << l.id;
    // The final clouds are the structure, point for point (16 digits in the ASCII file).
    if (landmarks == 365) {
      for (const Landmark& l : map.landmarks) {
        ASSERT_LT(nearest(l.p_world, structure), 1e-12 * (1.0 + l.p_world.norm())) << l.id;
      }
    }
    // Every centre was a vertex of the file: read without the rules they are all there.
    std::ifstream raw(dir + "/" + file, std::ios::binary);
    const std::vector<Vec3> none;
    const Map all = read_ply_map(raw, file, nullptr, &none);
    ASSERT_EQ(all.landmarks.size(), landmarks + 4);
    for (const Vec3& c : centres) {
      double best = std::numeric_limits<double>::infinity();
      for (const Landmark& l : all.landmarks) best = std::min(best, (l.p_world - c).norm());
      EXPECT_LT(best, 1e-12 * (1.0 + c.norm()));
    }
    // Without sfm_data.json beside it: the comment rule, or nothing left out.
    std::filesystem::copy_file(dir + "/" + file, alone.file(file));
    PlyReadReport alone_report;
    const Map copy = read_ply_map(alone.file(file), &alone_report);
    EXPECT_EQ(copy.landmarks.size(), has_comment ? landmarks : landmarks + 4);
    EXPECT_EQ(alone_report.camera_centres_left_out, has_comment ? 4u : 0u);
  }
  // read_any_map (convert, align) reports them apart from the landmarks.
  MapReadStats stats;
  read_any_map(dir + "/colorized.ply", {}, &stats);
  EXPECT_EQ(stats.landmarks_in_file, 365u);
  EXPECT_EQ(stats.camera_centres_left_out, 4u);
}

// Balbianello without an image size (the file has none): the same frames and landmarks, its
// centred pixels reproject through the centred RADIAL camera as the file's do, and the derived
// covariances are those read with the size.
TEST(BundlerReal, ReadsWithoutTheImageSize) {
  const std::string path = test::data_file(kBundler);
  LMALIGN_REQUIRE_FILE(path);
  const Map centred = read_bundler(path, {});
  ASSERT_EQ(centred.frames.size(), 5u);
  ASSERT_EQ(centred.landmarks.size(), 544u);
  std::vector<double> errors_px;
  for (const Landmark& landmark : centred.landmarks) {
    for (const Observation& obs : landmark.observations) {
      const Frame& frame = *centred.find_frame(obs.frame_id);
      ASSERT_TRUE(frame.camera->centred_pixels);
      const Vec3 p_camera = frame.T_world_camera().inverse() * landmark.p_world;
      errors_px.push_back(
          (frame.camera->project(p_camera) - Eigen::Vector2d(obs.u_px, obs.v_px)).norm());
    }
  }
  std::sort(errors_px.begin(), errors_px.end());
  EXPECT_LT(errors_px[errors_px.size() / 2], 0.2);
  const Map unsized = read_any_map(path);
  const Map sized = read_any_map(path, balbianello_options());
  ASSERT_EQ(unsized.landmarks.size(), sized.landmarks.size());
  for (std::size_t i = 0; i < sized.landmarks.size(); ++i) {
    ASSERT_EQ(unsized.landmarks[i].id, sized.landmarks[i].id);
    EXPECT_LT((unsized.landmarks[i].cov_world_m2 - sized.landmarks[i].cov_world_m2).norm(),
              1e-6 * sized.landmarks[i].cov_world_m2.norm());
  }
}

}  // namespace
}  // namespace lmalign
