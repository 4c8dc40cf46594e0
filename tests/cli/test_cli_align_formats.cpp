// `lmalign align` and `lmalign split` read every format the library reads (issue 19, item 6):
// the real Bundler reconstruction of Balbianello, aligned onto itself from a known displacement.
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

  // Without the image size (the file has none) it aligns the same: triangulation needs only
  // the focal length. An output that stores top-left pixels needs the size, and says so.
  const test::CliRun unsized =
      run("align " + out + " " + out + " --displace 0.3,-0.2,0.1,0,0,40 --ground-truth identity " +
          "--json " + path("u.json"));
  ASSERT_EQ(unsized.exit_code, 0) << unsized.out << unsized.err;
  const auto u = nlohmann::json::parse(test::read_text(path("u.json")));
  EXPECT_LT(u["results"][0]["rotation_error_deg"].get<double>(), 0.5);
  EXPECT_EQ(u["source_landmarks"], j["source_landmarks"]);
  const test::CliRun e = run("align " + out + " " + out + " --aligned-out " + path("a.txt"));
  EXPECT_EQ(e.exit_code, 2) << e.out << e.err;
  EXPECT_NE(e.err.find("--image-size W,H"), std::string::npos) << e.err;
  const test::CliRun bad = run("align " + out + " " + out + " --image-size 640x427");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--image-size"), std::string::npos) << bad.err;
}

}  // namespace
}  // namespace lmalign
