// Similarity transforms and estimation with scale (core/similarity.hpp,
// registration/similarity.hpp, map/transform.hpp, io/transform_io.hpp's read_similarity).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/similarity.hpp"
#include "lmalign/io/transform_io.hpp"
#include "lmalign/map/transform.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/similarity.hpp"

namespace lmalign {
namespace {

Similarity3 sim(double s, double x, double y, double z, double r, double p, double yaw) {
  return {s, pose_from_xyz_rpy_deg(x, y, z, r, p, yaw)};
}

Points3 random_points(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  Points3 p(n);
  for (Vec3& v : p) v = Vec3(u(rng), u(rng), 0.5 * u(rng));
  return p;
}

Points3 moved_by(const Similarity3& S, const Points3& p) {
  Points3 out;
  for (const Vec3& v : p) out.push_back(S * v);
  return out;
}

TEST(Similarity, MatrixInverseAndComposition) {
  const Similarity3 A = sim(0.37, 1, 2, 3, 10, 20, 30);
  const Similarity3 B = sim(3.0, -1, 0.5, 2, -5, 40, 170);
  const Vec3 p(0.3, -0.7, 1.1);
  EXPECT_LT(((A * B) * p - A * (B * p)).norm(), 1e-12);
  EXPECT_LT((A.inverse() * (A * p) - p).norm(), 1e-12);
  const Mat4 M = A.matrix();
  EXPECT_LT((M.topLeftCorner<3, 3>() * p + M.topRightCorner<3, 1>() - A * p).norm(), 1e-12);
  const Similarity3 back = similarity_from_matrix(M, "test");
  EXPECT_NEAR(back.scale, 0.37, 1e-12);
  EXPECT_LT((back.rigid.matrix() - A.rigid.matrix()).norm(), 1e-12);
}

TEST(Similarity, FromMatrixRefusesWhatIsNotAScaledRotation) {
  Mat4 M = sim(2.0, 0, 0, 0, 0, 0, 20).matrix();
  Mat4 shear = M;
  shear(0, 1) += 0.3;
  EXPECT_THROW(similarity_from_matrix(shear, "m"), InvalidArgument);
  try {
    similarity_from_matrix(shear, "truth.txt");
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("truth.txt: the 3x3 block is neither a rotation nor a "
                                         "scaled rotation"),
              std::string::npos)
        << e.what();
  }
  Mat4 mirror = M;
  mirror.row(2) *= -1.0;  // det < 0: a reflection, not a scale
  mirror(3, 2) = 0.0;
  EXPECT_THROW(similarity_from_matrix(mirror, "m"), InvalidArgument);
  Mat4 zero = M;
  zero.topLeftCorner<3, 3>().setZero();
  EXPECT_THROW(similarity_from_matrix(zero, "m"), InvalidArgument);
  Mat4 nan = M;
  nan(0, 3) = std::nan("");
  EXPECT_THROW(similarity_from_matrix(nan, "m"), InvalidArgument);
  Mat4 row = M;
  row(3, 0) = 0.1;
  EXPECT_THROW(similarity_from_matrix(row, "m"), InvalidArgument);
}

TEST(Similarity, ErrorMeasuresScaleRotationAndTranslation) {
  const Similarity3 truth = sim(2.0, 1, 0, 0, 0, 0, 0);
  const Similarity3 est = sim(2.02, 1, 0.1, 0, 0, 0, 3);
  const SimilarityError e = similarity_error(est, truth);
  EXPECT_NEAR(e.scale_error, 0.01, 1e-12);
  EXPECT_NEAR(e.rotation_deg, 3.0, 1e-9);
  EXPECT_NEAR(e.translation_m, 0.1, 1e-12);
}

TEST(Similarity, UmeyamaWithScaleRecoversTheSimilarityExactly) {
  const Points3 src = random_points(50, 1);
  for (const double s : {0.37, 3.0}) {
    const Similarity3 S = sim(s, 0.5, -1, 2, 20, -30, 120);
    const auto est = umeyama_similarity(src, moved_by(S, src));
    ASSERT_TRUE(est.has_value());
    EXPECT_NEAR(est->scale, s, 1e-12 * s);
    EXPECT_LT((est->matrix() - S.matrix()).norm(), 1e-10);
  }
  // Weights: a pair with weight 0 is ignored (an outlier moved far).
  Points3 tgt = moved_by(sim(0.37, 0, 0, 0, 0, 0, 10), src);
  tgt[0] += Vec3(5, 5, 5);
  std::vector<double> w(src.size(), 1.0);
  w[0] = 0.0;
  const auto est = umeyama_similarity(src, tgt, &w);
  ASSERT_TRUE(est.has_value());
  EXPECT_NEAR(est->scale, 0.37, 1e-12);
  // Fewer than 3 pairs, or coincident source points: none.
  const Points3 two(2, Vec3::Ones());
  const Points3 same(5, Vec3::Ones());
  EXPECT_FALSE(umeyama_similarity(two, two).has_value());
  EXPECT_FALSE(umeyama_similarity(same, random_points(5, 2)).has_value());
  EXPECT_THROW(umeyama_similarity(src, Points3(3)), InvalidArgument);
}

TEST(Similarity, GaussNewtonStepsConvergeToTheSimilarity) {
  const Points3 src = random_points(200, 3);
  const Similarity3 truth = sim(3.0, 0.2, -0.1, 0.3, 2, -1, 4);
  const Points3 tgt = moved_by(truth, src);
  Similarity3 est;  // identity
  for (int it = 0; it < 20; ++it) {
    const Points3 moved = moved_by(est, src);
    Vec3 pivot = Vec3::Zero();
    for (const Vec3& m : moved) pivot += m;
    pivot /= static_cast<double>(moved.size());
    const SimilarityStep st = solve_similarity_step(moved, tgt, nullptr, {}, pivot);
    ASSERT_TRUE(st.ok);
    est = similarity_increment(st.xi, pivot) * est;
  }
  EXPECT_NEAR(est.scale, 3.0, 1e-9);
  EXPECT_LT((est.matrix() - truth.matrix()).norm(), 1e-8);
}

TEST(Similarity, CovarianceOfScaleGrowsWithTheNoise) {
  // Point-to-point (identity information): the variance factor is the residuals'; doubling the
  // noise doubles the scale's standard deviation.
  const Points3 src = random_points(400, 4);
  std::mt19937 rng(5);
  std::normal_distribution<double> n01(0.0, 1.0);
  Points3 noise(src.size());
  for (Vec3& v : noise) v = Vec3(n01(rng), n01(rng), n01(rng));
  double sd[2];
  for (int k = 0; k < 2; ++k) {
    Points3 tgt = src;
    for (std::size_t i = 0; i < src.size(); ++i) tgt[i] += (k + 1) * 0.01 * noise[i];
    const SimilarityStep st = solve_similarity_step(src, tgt, nullptr, {}, Vec3::Zero());
    const auto cov = similarity_covariance(st, Vec3::Zero());
    ASSERT_TRUE(cov.has_value());
    EXPECT_TRUE(cov->allFinite());
    sd[k] = std::sqrt((*cov)(6, 6));
    // sd of log scale ~ sigma / sqrt(sum |p - c|^2) for isotropic noise: about 1e-2 / sqrt(400
    // * 2.9) = 3e-4.
    EXPECT_GT(sd[k], 1e-4 * (k + 1));
    EXPECT_LT(sd[k], 1e-3 * (k + 1));
  }
  EXPECT_NEAR(sd[1] / sd[0], 2.0, 0.05);
}

TEST(Similarity, ScaleModes) {
  EXPECT_EQ(parse_scale_mode("auto"), ScaleMode::kAuto);
  EXPECT_EQ(parse_scale_mode("free"), ScaleMode::kFree);
  EXPECT_EQ(parse_scale_mode("fixed"), ScaleMode::kFixed);
  EXPECT_THROW(parse_scale_mode("metric"), InvalidArgument);
  EXPECT_EQ(to_string(ScaleMode::kFree), "free");
  EXPECT_EQ(resolve_scale_mode(ScaleMode::kAuto, true, true), ScaleMode::kFixed);
  EXPECT_EQ(resolve_scale_mode(ScaleMode::kAuto, false, true), ScaleMode::kFree);
  EXPECT_EQ(resolve_scale_mode(ScaleMode::kAuto, true, false), ScaleMode::kFree);
  EXPECT_EQ(resolve_scale_mode(ScaleMode::kFixed, false, false), ScaleMode::kFixed);
  EXPECT_EQ(resolve_scale_mode(ScaleMode::kFree, true, true), ScaleMode::kFree);
  EXPECT_DOUBLE_EQ(initial_scale_from_spacing(0.02, 0.01), 0.5);
  EXPECT_DOUBLE_EQ(initial_scale_from_spacing(1.0, 100.0), 10.0);
  EXPECT_DOUBLE_EQ(initial_scale_from_spacing(100.0, 1.0), 0.1);
  EXPECT_THROW(initial_scale_from_spacing(0.0, 1.0), InvalidArgument);
}

TEST(Similarity, TransformMapScalesCovariancesBySquare) {
  Map m;
  Frame f;
  f.id = 1;
  f.p_world_camera = Vec3(1, 0, 0);
  m.frames.push_back(f);
  Landmark l;
  l.id = 7;
  l.p_world = Vec3(0, 2, 0);
  l.cov_world_m2 = Vec3(1e-4, 2e-4, 3e-4).asDiagonal();
  m.landmarks.push_back(l);
  const Similarity3 S = sim(0.5, 1, 1, 1, 0, 0, 90);
  const Map out = transform_map(m, S);
  EXPECT_LT((out.landmarks[0].p_world - S * l.p_world).norm(), 1e-12);
  EXPECT_LT((out.frames[0].p_world_camera - S * f.p_world_camera).norm(), 1e-12);
  const Mat3 R = S.rigid.linear();
  EXPECT_LT((out.landmarks[0].cov_world_m2 - 0.25 * R * l.cov_world_m2 * R.transpose()).norm(),
            1e-15);
  // Scale 1: the rigid transform_map.
  const Map rigid = transform_map(m, Similarity3{1.0, S.rigid});
  const Map ref = transform_map(m, S.rigid);
  EXPECT_EQ(rigid.landmarks[0].p_world, ref.landmarks[0].p_world);
}

TEST(Similarity, ReadSimilarityNamesTheFile) {
  const std::string path = ::testing::TempDir() + "lmalign_sim_test.txt";
  {
    std::ofstream o(path);
    o << "0 -0.37 0 1\n0.37 0 0 2\n0 0 0.37 3\n0 0 0 1\n";
  }
  const Similarity3 S = read_similarity(path);
  EXPECT_NEAR(S.scale, 0.37, 1e-12);
  EXPECT_THROW(read_transform(path), ParseError);  // not rigid
  {
    std::ofstream o(path);
    o << "1 0.5 0 1\n0 1 0 2\n0 0 1 3\n0 0 0 1\n";
  }
  try {
    read_similarity(path);
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("neither a rotation nor a scaled rotation"),
              std::string::npos)
        << e.what();
  }
  std::remove(path.c_str());
}

TEST(Similarity, FreeScaleNeedsASixDofEstimator) {
  const Points3 src = random_points(100, 6);
  SourceLandmarks s;
  s.positions = src;
  Map t;
  for (std::size_t i = 0; i < src.size(); ++i) {
    Landmark l;
    l.id = static_cast<Id>(i);
    l.p_world = 2.0 * src[i];
    l.cov_world_m2 = 1e-4 * Mat3::Identity();
    t.landmarks.push_back(l);
  }
  const PreparedTarget target(t);
  AlignRequest r;
  r.scale = ScaleMode::kFree;
  r.settings.emplace_back("estimate.four_dof", SettingValue(true));
  EXPECT_THROW(align(find_preset("adaptive"), s.view(), target, r), InvalidArgument);
  // Base ICP with Umeyama's scale: the target is the source doubled about the origin.
  AlignRequest b;
  b.scale = ScaleMode::kFree;
  const Summary out = align(find_preset("base"), s.view(), target, b);
  EXPECT_TRUE(out.scale.free);
  EXPECT_NEAR(out.scale.scale, 2.0, 1e-6);
  EXPECT_LT((out.similarity().matrix() - sim(2.0, 0, 0, 0, 0, 0, 0).matrix()).norm(), 1e-6);
}

}  // namespace
}  // namespace lmalign
