// `lmalign align` and `lmalign split` read every format the library reads (issue 19, item 6):
// the real Bundler reconstruction of Balbianello, aligned onto itself from a known displacement.
#include <fstream>
#include <iomanip>
#include <map>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "support/data_path.hpp"
#include "support/run_cli.hpp"

namespace lmalign {
namespace {

class CliAlignFormats : public test::CliTest {};

TEST_F(CliAlignFormats, AlignsARealBundlerMapOntoItselfFromADisplacement) {
  const std::string out = test::data_file("bundler_balbianello/Balbianello.out");
  LMALIGN_REQUIRE_FILE(out);
  // Bundler pixels are centred on the image; with the size (640 x 427 photos) they are moved to
  // the top-left corner.
  const test::CliRun r =
      run("align " + out + " " + out + " --image-size 640,427 --displace 0.3,-0.2,0.1,0,0,40 " +
          "--ground-truth identity --json " + path("b.json"));
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const auto j = nlohmann::json::parse(test::read_text(path("b.json")));
  ASSERT_EQ(j["results"].size(), 1u);
  EXPECT_EQ(j["results"][0]["strategy"], "adaptive");
  // The same landmarks on both sides: the displacement is undone almost exactly.
  EXPECT_LT(j["results"][0]["rotation_error_deg"].get<double>(), 0.5);
  EXPECT_LT(j["results"][0]["translation_error_m"].get<double>(), 0.01);
  EXPECT_GT(j["source_landmarks"].get<int>(), 100);
}

// The Bundler reader without the image size, and the outputs that need it (the default's
// alignment of the same file is the test above, which runs in Release only: the Makefile's
// SANITIZE_EXCLUDE).
TEST_F(CliAlignFormats, ABundlerMapReadsWithoutItsImageSizeAndOutputsThatNeedItSaySo) {
  const std::string out = test::data_file("bundler_balbianello/Balbianello.out");
  LMALIGN_REQUIRE_FILE(out);
  const test::CliRun sized = run("align " + out + " " + out +
                                 " --image-size 640,427 --strategy base --ground-truth identity "
                                 "--json " +
                                 path("b.json"));
  ASSERT_EQ(sized.exit_code, 0) << sized.out << sized.err;
  const auto j = nlohmann::json::parse(test::read_text(path("b.json")));
  EXPECT_GT(j["source_landmarks"].get<int>(), 100);

  // Without the image size (the file has none) it reads the same landmarks: triangulation needs
  // only the focal length (base ICP, undisplaced: the reader is what is checked here). An output
  // that stores top-left pixels needs the size, and says so.
  const test::CliRun unsized =
      run("align " + out + " " + out + " --strategy base --ground-truth identity --json " +
          path("u.json"));
  ASSERT_EQ(unsized.exit_code, 0) << unsized.out << unsized.err;
  const auto u = nlohmann::json::parse(test::read_text(path("u.json")));
  EXPECT_LT(u["results"][0]["rotation_error_deg"].get<double>(), 0.5);
  EXPECT_LT(u["results"][0]["translation_error_m"].get<double>(), 0.01);
  EXPECT_EQ(u["source_landmarks"], j["source_landmarks"]);
  const test::CliRun e = run("align " + out + " " + out + " --aligned-out " + path("a.txt"));
  EXPECT_EQ(e.exit_code, 2) << e.out << e.err;
  EXPECT_NE(e.err.find("--image-size W,H"), std::string::npos) << e.err;
  const test::CliRun bad = run("align " + out + " " + out + " --image-size 640x427");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--image-size"), std::string::npos) << bad.err;
}

// Bare point clouds (issue: maps without covariances): the real desk map's landmark positions as
// XYZ text (source) and as a PLY without covariance properties (target). Both read with assumed
// covariances; base ICP and the default undo a displacement; the default and the covariance
// strategy flag the assumption in their result and trust reason; observations and distance,
// whose weights are all 0 without observations, match nothing and say so, untrusted.
TEST_F(CliAlignFormats, PointCloudsWithoutCovariancesAlign) {
  const std::string desk = test::data_file("tum_fr1_desk/map_fr1_desk.txt");
  LMALIGN_REQUIRE_FILE(desk);
  {
    std::ifstream in(desk);
    std::ofstream xyz(path("desk.xyz"));
    std::ostringstream vertices;
    std::size_t n = 0;
    std::string line;
    while (std::getline(in, line)) {
      std::istringstream fields(line);
      std::string type, id, x, y, z, c;
      fields >> type >> id >> x >> y >> z;
      if (type != "LANDMARK") continue;
      for (int i = 0; i < 9; ++i) fields >> c;
      int observations = 0;
      fields >> observations;
      if (observations < 2) continue;
      xyz << x << " " << y << " " << z << "\n";
      vertices << x << " " << y << " " << z << "\n";
      ++n;
    }
    std::ofstream(path("desk.ply")) << "ply\nformat ascii 1.0\nelement vertex " << n
                                    << "\nproperty double x\nproperty double y\nproperty "
                                       "double z\nend_header\n"
                                    << vertices.str();
  }
  const test::CliRun r = run("align " + path("desk.xyz") + " " + path("desk.ply") +
                             " --strategy base,covariance,observations,distance,adaptive "
                             "--displace 0.1,-0.05,0.02,0,0,10 --ground-truth identity --json " +
                             path("c.json"));
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("source: covariances assumed (the map stores none)"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("target: covariances assumed"), std::string::npos) << r.out;
  const auto j = nlohmann::json::parse(test::read_text(path("c.json")));
  EXPECT_EQ(j["source_landmarks"], 6081);  // the real map's landmarks with 2+ observations
  EXPECT_EQ(j["target_covariance_assumed"], true);
  EXPECT_EQ(j["target_scale"], "unknown");
  std::map<std::string, nlohmann::json> by_name;
  for (const auto& e : j["results"]) by_name[e["strategy"].get<std::string>()] = e;
  ASSERT_EQ(by_name.size(), 5u);
  for (const char* name : {"base", "adaptive"}) {
    SCOPED_TRACE(name);
    EXPECT_EQ(by_name[name]["right_basin"], true);
    EXPECT_LT(by_name[name]["rotation_error_deg"].get<double>(), 0.01);
    EXPECT_EQ(by_name[name]["trustworthy"], true);
  }
  // Point clouds do not say whether they are metric: `auto` estimates the scale, here 1.
  for (const char* name : {"base", "adaptive"}) {
    SCOPED_TRACE(name);
    EXPECT_EQ(by_name[name]["scale_mode"], "free");
    EXPECT_NEAR(by_name[name]["scale"].get<double>(), 1.0, 1e-3);
  }
  EXPECT_EQ(by_name["base"]["covariances_assumed"], false);
  EXPECT_EQ(by_name["base"]["trust_reason"], "ok");
  for (const char* name : {"covariance", "adaptive"}) {
    SCOPED_TRACE(name);
    EXPECT_EQ(by_name[name]["covariances_assumed"], true);
    EXPECT_NE(by_name[name]["trust_reason"].get<std::string>().find(
                  "covariances assumed from the landmark spacing"),
              std::string::npos);
  }
  for (const char* name : {"observations", "distance"}) {
    SCOPED_TRACE(name);
    EXPECT_EQ(by_name[name]["trustworthy"], false);
    EXPECT_EQ(by_name[name]["termination"], "no_correspondences");
    EXPECT_NE(by_name[name]["trust_reason"].get<std::string>().find("weight 0"), std::string::npos)
        << by_name[name]["trust_reason"];
  }
}

// `--scale auto` (the default) follows the maps' headers: the real desk map in our format is
// metric, so it stays rigid; the same map shrunk by 0.4 and marked as of arbitrary scale (our
// format's `MAP scale arbitrary` record, as COLMAP's and Bundler's maps are read), are aligned with
// a similarity and the scale is recovered against the similarity given as the ground truth.
TEST_F(CliAlignFormats, AutoScaleFollowsTheMapsHeaders) {
  const std::string desk = test::data_file("tum_fr1_desk/map_fr1_desk.txt");
  LMALIGN_REQUIRE_FILE(desk);
  const double s = 0.4;
  {
    std::ifstream in(desk);
    std::ofstream out(path("small.txt"));
    out << "MAP scale arbitrary\n";
    std::string line;
    while (std::getline(in, line)) {
      std::istringstream fields(line);
      std::string type;
      fields >> type;
      if (type == "FRAME") {  // FRAME id x y z qw qx qy qz: the position times s
        std::string id;
        double v[7];
        fields >> id;
        for (double& x : v) fields >> x;
        out << "FRAME " << id << std::setprecision(17);
        for (int i = 0; i < 7; ++i) out << " " << v[i] * (i < 3 ? s : 1.0);
        out << "\n";
        continue;
      }
      if (type != "LANDMARK") {
        out << line << "\n";
        continue;
      }
      // LANDMARK id x y z c00..c22 rest: positions times s, covariances times s^2.
      std::string id;
      double v[12];
      fields >> id;
      for (double& x : v) fields >> x;
      std::string rest;
      std::getline(fields, rest);
      out << "LANDMARK " << id << std::setprecision(17);
      for (int i = 0; i < 12; ++i) out << " " << v[i] * (i < 3 ? s : s * s);
      out << rest << "\n";
    }
  }
  // The truth maps the shrunk source back onto the desk map: [I/s 0; 0 1].
  std::ofstream(path("gt.txt")) << 1.0 / s << " 0 0 0\n0 " << 1.0 / s << " 0 0\n0 0 " << 1.0 / s
                                << " 0\n0 0 0 1\n";
  // The scale mode follows the headers whatever the strategy: the metric pair with base ICP.
  const test::CliRun rigid =
      run("align " + desk + " " + desk + " --strategy base --json " + path("r.json"));
  ASSERT_EQ(rigid.exit_code, 0) << rigid.out << rigid.err;
  const auto r = nlohmann::json::parse(test::read_text(path("r.json")));
  EXPECT_EQ(r["results"][0]["scale_mode"], "fixed");

  const test::CliRun sim = run("align " + path("small.txt") + " " + desk + " --ground-truth " +
                               path("gt.txt") + " --json " + path("s.json"));
  ASSERT_EQ(sim.exit_code, 0) << sim.out << sim.err;
  const auto j = nlohmann::json::parse(test::read_text(path("s.json")));
  const auto& e = j["results"][0];
  EXPECT_EQ(e["scale_mode"], "free");
  EXPECT_NEAR(e["scale"].get<double>(), 1.0 / s, 0.01 / s);
  EXPECT_LT(e["scale_error"].get<double>(), 0.01);
  EXPECT_LT(e["rotation_error_deg"].get<double>(), 0.5);
  EXPECT_EQ(e["trustworthy"], true);

  // --scale fixed overrides the header: no scale is estimated (base ICP: the mode is checked).
  const test::CliRun fixed = run("align " + path("small.txt") + " " + desk +
                                 " --strategy base --scale fixed --json " + path("f.json"));
  ASSERT_EQ(fixed.exit_code, 0) << fixed.out << fixed.err;
  const auto f = nlohmann::json::parse(test::read_text(path("f.json")));
  EXPECT_EQ(f["results"][0]["scale_mode"], "fixed");
  EXPECT_EQ(f["results"][0]["scale"].get<double>(), 1.0);
}

}  // namespace
}  // namespace lmalign
