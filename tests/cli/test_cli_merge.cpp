// `lmalign merge` end to end on a small synthetic fleet (`lmalign simulate --scene fleet`):
// the outputs, --resume reusing the finished edges, the plots, and one-line errors for bad
// manifests. Built only when the CLI has `merge` (Ceres found: LMALIGN_CLI_HAS_MERGE).
#ifdef LMALIGN_CLI_HAS_MERGE
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include "support/run_cli.hpp"

namespace lmalign {
namespace {

namespace fs = std::filesystem;
using test::CliTest;
using test::read_text;
using test::shell_quote;

using CliMerge = CliTest;

void write_text(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

std::size_t count_lines(const std::string& text) {
  std::size_t n = 0;
  for (char c : text) n += c == '\n' ? 1 : 0;
  return n;
}

TEST_F(CliMerge, SimulatedFleetMergesEndToEndAndResumeReusesEveryEdge) {
  const std::string scene = path("fleet"), out = path("out");
  const test::CliRun s =
      run("simulate --scene fleet --maps 5 --twins 0 --seed 4 --out " + shell_quote(scene));
  ASSERT_EQ(s.exit_code, 0) << s.err;
  for (const char* f : {"manifest.yaml", "ground_truth.yaml", "overlaps.csv", "maps/map_004.txt"}) {
    EXPECT_TRUE(fs::exists(scene + "/" + f)) << f;
  }
  // (A fleet's edge search, "check", as beyond 12 maps: a 5-map merge's own, "rescue", runs the
  // complete search on each untrusted pair, 5x this test's time under the sanitizers; the
  // default is SetReachesEveryEdge...'s.)
  const std::string merge = "merge " + shell_quote(scene + "/manifest.yaml") + " -o " +
                            shell_quote(out) + " --ground-truth " +
                            shell_quote(scene + "/ground_truth.yaml") +
                            " --thresholds 1,0.1 --set init.prior_complete_search=check";
  const test::CliRun r = run(merge);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  // 5 maps: every pair, all placed within 1 deg / 10 cm, no false edge kept.
  EXPECT_NE(r.out.find("merged 5 maps: 10 candidate pairs (0 reused)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("within: 100.0% of the maps (placed: 5 of 5); pairs within: 10 of 10"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("1 part(s), the largest of 5 map(s)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("false kept 0"), std::string::npos) << r.out;
  // No look-alike here: no fold reported (merge/folds.hpp), and none in summary.json.
  EXPECT_EQ(r.out.find("suspected fold"), std::string::npos) << r.out;
  EXPECT_NE(read_text(out + "/summary.json").find("\"suspected_folds\": []"), std::string::npos);
  for (const char* f :
       {"poses.yaml", "poses.json", "edges.csv", "summary.json", "merged_map.txt"}) {
    EXPECT_TRUE(fs::exists(out + "/" + f)) << f;
  }
  EXPECT_EQ(count_lines(read_text(out + "/edges.csv")), 11u);  // header + 10 pairs
  // The plots: valid PNGs (signature), written beside the outputs.
  for (const char* f : {"merge_graph.png", "merged_landmarks.png"}) {
    const std::string png = read_text(out + "/" + f);
    ASSERT_GT(png.size(), 1000u) << f << ": " << r.err;
    EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8)) << f;
  }
  EXPECT_NE(r.out.find("merge_graph.png"), std::string::npos) << r.out;
  std::map<std::string, std::string> edge_files;
  for (const auto& e : fs::directory_iterator(out + "/edges")) {
    edge_files[e.path().string()] = read_text(e.path());
  }
  EXPECT_EQ(edge_files.size(), 10u);
  // A second run into the same folder refuses without --resume, and reuses every edge with it.
  const test::CliRun again = run(merge);
  EXPECT_EQ(again.exit_code, 2);
  EXPECT_NE(again.err.find("--resume"), std::string::npos) << again.err;
  const test::CliRun resumed = run(merge + " --resume");
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  EXPECT_NE(resumed.out.find("10 candidate pairs (10 reused)"), std::string::npos) << resumed.out;
  EXPECT_NE(resumed.out.find("within: 100.0%"), std::string::npos) << resumed.out;
  for (const auto& [file, text] : edge_files) EXPECT_EQ(read_text(file), text) << file;
  EXPECT_TRUE(fs::exists(out + "/overlap_check.csv"));
  // --overlap-check off (the edges reused in another folder): no check, no overlap_check.csv,
  // the same poses (this fleet's parts agree with themselves); a value outside the three is one
  // line.
  const std::string off = path("off");
  fs::create_directories(off);
  fs::copy(out + "/edges", off + "/edges");
  const std::string merge_off = "merge " + shell_quote(scene + "/manifest.yaml") + " -o " +
                                shell_quote(off) + " --no-plots --resume --overlap-check off" +
                                " --set init.prior_complete_search=check";
  const test::CliRun r_off = run(merge_off);
  ASSERT_EQ(r_off.exit_code, 0) << r_off.err;
  EXPECT_NE(r_off.out.find("10 candidate pairs (10 reused)"), std::string::npos) << r_off.out;
  EXPECT_FALSE(fs::exists(off + "/overlap_check.csv"));
  EXPECT_EQ(r_off.out.find("overlap check:"), std::string::npos) << r_off.out;
  EXPECT_NE(r.out.find("overlap check:"), std::string::npos) << r.out;
  EXPECT_EQ(read_text(off + "/poses.yaml"), read_text(out + "/poses.yaml"));
  const test::CliRun bad = run(merge_off + " --overlap-check sometimes");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--overlap-check"), std::string::npos) << bad.err;
  EXPECT_EQ(count_lines(bad.err), 1u) << bad.err;
}

// --views roaming: 24 keyframes per map (FRAME lines), the manifest says how it was made; the
// default ring keeps 8; a bad value is one line naming the option, and nothing is written.
TEST_F(CliMerge, SimulateFleetViewsRoamingOrRing) {
  const std::string roaming = path("roaming"), ring = path("ring"), bad_dir = path("bad");
  ASSERT_EQ(
      run("simulate --scene fleet --maps 3 --twins 0 --views roaming --out " + shell_quote(roaming))
          .exit_code,
      0);
  ASSERT_EQ(run("simulate --scene fleet --maps 3 --twins 0 --out " + shell_quote(ring)).exit_code,
            0);
  auto frames = [](const std::string& file) {
    std::ifstream f(file);
    std::size_t n = 0;
    for (std::string line; std::getline(f, line);) n += line.rfind("FRAME ", 0) == 0 ? 1 : 0;
    return n;
  };
  EXPECT_EQ(frames(roaming + "/maps/map_000.txt"), 24u);
  EXPECT_EQ(frames(ring + "/maps/map_000.txt"), 8u);
  std::ifstream manifest(roaming + "/manifest.yaml");
  std::string first_line;
  std::getline(manifest, first_line);
  EXPECT_NE(first_line.find("--views roaming"), std::string::npos) << first_line;
  const test::CliRun bad =
      run("simulate --scene fleet --maps 3 --views sideways --out " + shell_quote(bad_dir));
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("--views sideways: expected 'ring' or 'roaming'"), std::string::npos)
      << bad.err;
  EXPECT_EQ(count_lines(bad.err), 1u) << bad.err;
  EXPECT_FALSE(std::filesystem::exists(bad_dir + "/manifest.yaml"));
}

// Maps that no kept edge joins (here: two fleet maps whose only edge cannot be trusted, their
// landmarks moved far apart) are reported alone in their parts, not placed, 0% within.
TEST_F(CliMerge, MapsAloneInTheirPartsAreReportedNotPlaced) {
  const std::string scene = path("fleet"), out = path("out");
  ASSERT_EQ(run("simulate --scene fleet --maps 2 --twins 0 --prior-sigma none --out " +
                shell_quote(scene))
                .exit_code,
            0);
  // Map 1 replaced by a map that shares nothing with map 0: 30 landmarks on a line far away.
  std::string far = "FRAME 0 0 0 0 1 0 0 0\n";
  for (int k = 0; k < 30; ++k) {
    far += "LANDMARK " + std::to_string(k) + " " + std::to_string(500 + k) +
           " 0 0 0.01 0 0 0 0.01 0 0 0 0.01 2 0 1 1 0 2 2\n";
  }
  {
    std::ofstream f(scene + "/maps/map_001.txt");
    f << far;
  }
  const test::CliRun r =
      run("merge " + shell_quote(scene + "/manifest.yaml") + " -o " + shell_quote(out) +
          " --no-plots --ground-truth " + shell_quote(scene + "/ground_truth.yaml"));
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("2 part(s), the largest of 1 map(s)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("map_000              component 0  not placed: alone in its part"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("within: 0.0% of the maps (placed: 0 of 2); pairs within: 0 of 1"),
            std::string::npos)
      << r.out;
}

// --set reaches every edge's alignment: a prior edge is checked by the global search by default,
// which on a merge of at most 12 maps also re-searches an untrusted answer (init.
// prior_complete_search=rescue; issues 41 and 37), and runs the prior's search alone with --set
// init.prior_check=off; a caller's init.prior_complete_search wins; a bad key or value is one
// line naming it, before any alignment; --set with Dask is refused.
TEST_F(CliMerge, SetReachesEveryEdgeAndABadSettingIsOneLine) {
  const std::string scene = path("fleet");
  ASSERT_EQ(run("simulate --scene fleet --maps 2 --twins 0 --seed 4 --out " + shell_quote(scene))
                .exit_code,
            0);
  auto merge = [&](const std::string& out, const std::string& extra) {
    return run("merge " + shell_quote(scene + "/manifest.yaml") + " -o " + shell_quote(out) +
               " --no-plots " + extra);
  };
  auto edge_json = [](const std::string& out) {
    std::string text;
    for (const auto& e : fs::directory_iterator(out + "/edges")) text += read_text(e.path());
    return text;
  };
  const test::CliRun plain = merge(path("plain"), "");
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  const std::string edges = edge_json(path("plain"));
  EXPECT_NE(edges.find("\"prior_checked\":true"), std::string::npos) << edges.substr(0, 2000);
  EXPECT_EQ(edges.find("\"prior_checked\":false"), std::string::npos);
  EXPECT_NE(edges.find("\"init.prior_complete_search\":\"rescue\""), std::string::npos);
  const test::CliRun alone = merge(path("alone"), "--set init.prior_check=off");
  ASSERT_EQ(alone.exit_code, 0) << alone.err;
  EXPECT_NE(edge_json(path("alone")).find("\"prior_checked\":false"), std::string::npos);
  const test::CliRun check = merge(path("check"), "--set init.prior_complete_search=check");
  ASSERT_EQ(check.exit_code, 0) << check.err;
  EXPECT_NE(edge_json(path("check")).find("\"init.prior_complete_search\":\"check\""),
            std::string::npos);
  for (const auto& [extra, expected] : std::map<std::string, std::string>{
           {"--set init.prior_chek=rivals", "init.prior_check"},
           {"--set init.prior_check=maybe", "init.prior_check"},
           {"--set novalue", "expected KEY=VALUE"},
           {"--set init.prior_check=off --dask-scheduler tcp://127.0.0.1:1", "Dask"},
           {"--candidates-per-map 0", "--candidates-per-map must be >= 1"},
           {"--candidates-per-map 6 --dask-scheduler tcp://127.0.0.1:1", "Dask"},
           {"--verify-per-map 100001", "--verify-per-map must be in [0, 100000]"},
           {"--verify-per-map 5 --dask-scheduler tcp://127.0.0.1:1", "Dask"}}) {
    const test::CliRun bad = merge(path("bad"), extra);
    EXPECT_EQ(bad.exit_code, 2) << extra;
    EXPECT_NE(bad.err.find(expected), std::string::npos) << extra << ": " << bad.err;
    EXPECT_EQ(count_lines(bad.err), 1u) << extra << ": " << bad.err;
    EXPECT_FALSE(fs::exists(path("bad") + "/edges")) << extra;
  }
}

TEST_F(CliMerge, WithoutMatplotlibThePlotsAreSkippedWithAWarning) {
  const std::string scene = path("fleet"), out = path("out");
  ASSERT_EQ(run("simulate --scene fleet --maps 2 --twins 0 --out " + shell_quote(scene)).exit_code,
            0);
  // An interpreter that fails stands for a Python without matplotlib.
  const test::CliRun r =
      run_with_env("LMALIGN_PYTHON=false",
                   "merge " + shell_quote(scene + "/manifest.yaml") + " -o " + shell_quote(out));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("warning: no plots"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(out + "/poses.yaml"));
  EXPECT_FALSE(fs::exists(out + "/merge_graph.png"));
}

TEST_F(CliMerge, BadManifestsGiveOneLineErrorsNamingTheFieldOrFile) {
  const std::string scene = path("fleet");
  ASSERT_EQ(run("simulate --scene fleet --maps 2 --twins 0 --out " + shell_quote(scene)).exit_code,
            0);
  const std::string map0 = scene + "/maps/map_000.txt";
  const std::string rigid = "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]";
  struct Case {
    std::string name, yaml, expected;
  } cases[] = {
      {"empty", "maps: []\n", "empty manifest"},
      {"duplicate", "maps:\n  - {name: a, path: " + map0 + "}\n  - {name: a, path: " + map0 + "}\n",
       "maps[1].name: duplicate map name 'a'"},
      {"unreadable", "maps:\n  - {name: a, path: " + map0 + "}\n  - {name: b, path: nowhere.txt}\n",
       "map 'b'"},
      {"not_spd",
       "maps:\n  - {name: a, path: " + map0 + ", T_world_map: " + rigid +
           ", prior_covariance: [[1,0,0,0,0,0],[0,1,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],"
           "[0,0,0,0,1,0],[0,0,0,0,0,-1]]}\n",
       "maps[0].prior_covariance: not positive definite"},
      {"not_rigid",
       "maps:\n  - {name: a, path: " + map0 +
           ", T_world_map: [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], prior_sigma: [1, 1]}\n",
       "maps[0].T_world_map: not a rigid transform"},
  };
  for (const Case& c : cases) {
    const std::string manifest = path(c.name + ".yaml");
    write_text(manifest, c.yaml);
    const test::CliRun r =
        run("merge " + shell_quote(manifest) + " -o " + shell_quote(path("out_" + c.name)));
    EXPECT_EQ(r.exit_code, 2) << c.name << ": " << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << c.name << ": " << r.err;
    EXPECT_NE(r.err.find(c.name == "unreadable" ? "nowhere.txt" : manifest), std::string::npos)
        << c.name << ": " << r.err;
    // One error line (after the progress line "reading N maps", when the maps are read).
    const std::size_t at = r.err.find("lmalign: error: ");
    ASSERT_NE(at, std::string::npos) << c.name << ": " << r.err;
    EXPECT_EQ(count_lines(r.err.substr(at)), 1u) << c.name << ": " << r.err;
    EXPECT_FALSE(fs::exists(path("out_" + c.name) + "/poses.yaml")) << c.name;
  }
}

}  // namespace
}  // namespace lmalign
#endif  // LMALIGN_CLI_HAS_MERGE
