#!/usr/bin/env python3
"""Tests of bench/run_accuracy.py's bookkeeping (no timing, no real alignment): the protocol's 39
displacements, the config's checks, the metrics (success, medians of the successes, trust
precision and recall, binned success), and a whole run with a stand-in `lmalign` that writes
results.csv as the real one does, and `align --json` for the default's regret and basin. Run by
ctest (tests/CMakeLists.txt)."""
import csv
import json
import math
import os
import shutil
import stat
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import accuracy_default  # noqa: E402
import run_accuracy  # noqa: E402
import size_sweep  # noqa: E402

# A stand-in for the `lmalign` subcommands the driver calls. experiment: one row per case and
# strategy, the case's offset in `value`; strategy "good" succeeds (error 1 deg, 2 cm, trusted),
# "far" succeeds below an offset of 1 m only and is trusted always, "bad" never succeeds and is
# never trusted. align (the default, bench/accuracy_default.py): from a --displace start with
# x in (-0.8, 1) m it finds the truth (gated score 100); x >= 1: a wrong pose scoring 60 (a search
# failure, regret 40); x <= -0.8: a wrong pose scoring 100.5 (a score failure). From an
# --initial-guess (with --prior-sigma: initialisation "given" only if its rotation sigma is at
# most 0.5 deg) it reaches the truth when the guess is within 2 m and 11 deg of it. With
# --strategy exhaustive (the reference search) a start with x >= 1 finds the truth too, in 0.5 s
# instead of 0.2. A right answer's pose is the truth, a wrong one's 5 m from it along x. Every call
# is appended to CALLS.
FAKE_LMALIGN = r'''#!/usr/bin/python3
import json, os, sys
with open(os.environ["FAKE_CALLS"], "a") as f:
    f.write(json.dumps(sys.argv[1:]) + "\n")
cmd = sys.argv[1]
if cmd == "split":
    out = sys.argv[sys.argv.index("-o") + 1]
    open(out, "w").write("LANDMARK\n")
elif cmd == "simulate":
    out = sys.argv[sys.argv.index("-o") + 1]
    os.makedirs(out, exist_ok=True)
    for n in ["source.txt", "target.txt"]:
        open(os.path.join(out, n), "w").write("LANDMARK\n")
    open(os.path.join(out, "T_target_source.txt"), "w").write(
        "1 0 0 0.5\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")
elif cmd == "experiment":
    import yaml
    cfg_path = sys.argv[2]
    out = sys.argv[sys.argv.index("-o") + 1] if "-o" in sys.argv else sys.argv[sys.argv.index("--resume") + 1]
    cfg = yaml.safe_load(open(cfg_path))
    for p in [cfg["source"], cfg["target"]]:
        if not os.path.isfile(p):
            sys.stderr.write("lmalign: error: cannot open " + p + "\n"); sys.exit(2)
    os.makedirs(out, exist_ok=True)
    cols = ("experiment,case,label,group,variable,value,x_m,y_m,z_m,roll_deg,pitch_deg,yaw_deg,"
            "strategy,k,initial_score_m2,final_score_m2,iterations,termination,time_s,"
            "rotation_error_deg,translation_error_m,success,decided_by,trustworthy")
    lines = [cols]
    case = 0
    for e in cfg["experiments"]:
        n = len(e["poses"]) if e["type"] == "poses" else e["samples"]
        for i in range(n):
            value = 0.0 if e["type"] == "poses" else e["translation_m"] * (i + 0.5) / n
            x = e["poses"][i].get("x_m", 0.0) if e["type"] == "poses" else value
            for s in cfg["strategies"]:
                ok = s == "good" or s == "base" or (s == "far" and value < 1.0)
                trusted = s in ("good", "far")
                rot, tr = (1.0, 0.02) if ok else (40.0, 3.0)
                lines.append("%s,%d,c%d,,x,%g,%r,0,0,0,0,0,%s,5,1,1,10,transform,%g,%g,%g,%s,ground_truth,%s"
                             % (e["name"], case, i, value, x, s, 0.01 * (1 + i % 3), rot, tr,
                                "true" if ok else "false", "true" if trusted else "false"))
            case += 1
    open(os.path.join(out, "results.csv"), "w").write("\n".join(lines) + "\n")
    open(os.path.join(out, "config.yaml"), "w").write(open(cfg_path).read())
    open(os.path.join(out, "summary.json"), "w").write("{}")
    print("experiment %s" % cfg_path)
    print("  source %s (1200 landmarks), target %s (1300 landmarks)" % (cfg["source"], cfg["target"]))
elif cmd == "convert":
    # The Sim(3) datasets: the source moved by --transform, marked with --map-scale.
    out = sys.argv[3]
    open(out, "w").write("MAP scale " + sys.argv[sys.argv.index("--map-scale") + 1] + "\n")
elif cmd == "align":
    import math
    arg = lambda name: sys.argv[sys.argv.index(name) + 1] if name in sys.argv else None
    truth = arg("--ground-truth")
    T = ([[float(v) for v in l.split()] for l in open(truth) if l.strip()]
         if truth != "identity" else [[float(r == c) for c in range(4)] for r in range(4)])
    strategy = arg("--strategy") or "adaptive"
    r = {"strategy": strategy, "wall_time_s": 0.2, "total_time_s": 0.2, "scale_mode": "fixed"}
    if open(sys.argv[2]).read().startswith("MAP scale arbitrary"):
        # A Sim(3) source: the truth's scale from the 3x3 block; 1.25x the rigid time.
        det = (T[0][0] * (T[1][1] * T[2][2] - T[1][2] * T[2][1]) -
               T[0][1] * (T[1][0] * T[2][2] - T[1][2] * T[2][0]) +
               T[0][2] * (T[1][0] * T[2][1] - T[1][1] * T[2][0]))
        r.update(total_time_s=0.25, scale_mode="free", scale=det ** (1 / 3), scale_error=0.002)
    if arg("--initial-guess"):
        G = [[float(v) for v in l.split()] for l in open(arg("--initial-guess")) if l.strip()]
        prior = [float(v) for v in arg("--prior-sigma").split(",")]
        dt = math.sqrt(sum((G[i][3] - T[i][3]) ** 2 for i in range(3)))
        trace = sum(G[i][k] * T[i][k] for i in range(3) for k in range(3))
        angle = math.degrees(math.acos(max(-1.0, min(1.0, (trace - 1) / 2))))
        ok = dt < 2.0 and angle < 11.0
        r.update(initialisation="given" if prior[0] <= 0.5 else "prior",
                 gated_score=100.0 if ok else 40.0)
    else:
        x = float(arg("--displace").split(",")[0])
        ok = -0.8 < x < (1.0 if strategy == "adaptive" else 1e9)
        r.update(initialisation="global",
                 gated_score=100.0 if ok else (60.0 if x >= 1.0 else 100.5))
        if strategy == "exhaustive":
            r.update(wall_time_s=0.5, total_time_s=0.5)
    r["T_target_source"] = [row[:] for row in T]
    if not ok:
        r["T_target_source"][0][3] += 5.0
    r.update(right_basin=ok, trustworthy=ok, rotation_error_deg=0.5 if ok else 90.0,
             translation_error_m=0.01 if ok else 5.0, trust_reason="ok")
    json.dump({"results": [r]}, open(arg("--json"), "w"))
else:
    sys.exit(2)
'''

# A stand-in for bench/peer_open3d_global.cpp (see the peers test): the transform and CPU time
# by --seed; every call is appended to CALLS as ["peer", ...].
FAKE_PEER = r'''#!/usr/bin/python3
import json, math, os, sys
with open(os.environ["FAKE_CALLS"], "a") as f:
    f.write(json.dumps(["peer"] + sys.argv[1:]) + "\n")
seed = int(sys.argv[sys.argv.index("--seed") + 1])
T = [[float(r == c) for c in range(4)] for r in range(4)]
if seed == 2:
    c, s = math.cos(math.radians(10)), math.sin(math.radians(10))
    T[0][:2], T[1][:2] = [c, -s], [s, c]
if seed == 3:
    T[1][3] = 0.2
print(json.dumps({"T_target_source": T, "cpu_s": {1: 0.1, 2: 0.5, 3: 0.3}[seed], "voxel_m": 0.02}))
'''

CONFIG = """
strategies: [good, far, bad]
k: 5
random: {samples: 20, seed: 3, roll_pitch_deg: 2}
reference: {strategy: base, max_iterations: 150}
kinds:
  indoor:  {rotation_deg: 5, translation_m: 0.10, random_translation_m: 3, reference_max_distance_m: 0.1}
  outdoor: {rotation_deg: 5, translation_m: 1.0, random_translation_m: 10, reference_max_distance_m: 0.25}
datasets:
  - {name: files, kind: indoor, up_axis: z, source: "${LMALIGN_DATA}/a.txt", target: "${LMALIGN_DATA}/b.txt", truth: identity}
  - {name: windows, kind: indoor, split: {map: "${LMALIGN_DATA}/full.txt", source_frames: 0-9, target_frames: 5-19}}
  - {name: road, kind: outdoor, up_axis: y, simulate: {scene: road, seed: 4, overlap: 0.25, landmarks: 100}}
"""


def load_yaml(path):
    import yaml
    with open(path) as f:
        return yaml.safe_load(f)


def row(strategy, success, trusted, rot=1.0, tr=0.01, t=0.1, experiment="random", value=0.0):
    return {"strategy": strategy, "success": "true" if success else "false",
            "trustworthy": "true" if trusted else "false", "rotation_error_deg": str(rot),
            "translation_error_m": str(tr), "time_s": str(t), "experiment": experiment,
            "value": str(value)}


class Protocol(unittest.TestCase):
    def test_39_distinct_displacements_of_method_section_5(self):
        poses = run_accuracy.protocol_poses()
        self.assertEqual(len(poses), 39)
        keys = {tuple(sorted(p.items())) for _, p in poses}
        self.assertEqual(len(keys), 39)
        self.assertEqual(poses[0][1], dict(x_m=0.0, y_m=1.0, z_m=0.4, roll_deg=10.0,
                                           pitch_deg=0.0, yaw_deg=22.5))
        self.assertIn(dict(x_m=3.0, y_m=-3.0, z_m=0.0, roll_deg=0.0, pitch_deg=0.0, yaw_deg=0.0),
                      [p for _, p in poses])
        self.assertIn(dict(x_m=-0.5, y_m=-0.5, z_m=0.0, roll_deg=0.0, pitch_deg=0.0,
                           yaw_deg=-30.0), [p for _, p in poses])


class Metrics(unittest.TestCase):
    def test_success_medians_of_successes_precision_recall_time(self):
        rows = [row("s", True, True, rot=1, tr=0.01, t=0.1),
                row("s", True, False, rot=3, tr=0.03, t=0.3),
                row("s", True, True, rot=2, tr=0.02, t=0.2),
                row("s", False, True, rot=90, tr=5, t=0.9, experiment="protocol"),
                row("s", False, False, rot=45, tr=2, t=0.4, experiment="protocol")]
        m = run_accuracy.strategy_metrics(rows)
        self.assertEqual(m["runs"], 5)
        self.assertAlmostEqual(m["success_rate"], 0.6)
        self.assertEqual(m["success_rate_by_experiment"], {"protocol": 0.0, "random": 1.0})
        self.assertAlmostEqual(m["median_rotation_error_deg"], 2.0)  # of the successes only
        self.assertAlmostEqual(m["median_translation_error_m"], 0.02)
        self.assertAlmostEqual(m["trust_precision"], 2 / 3)  # 3 trusted, 2 in the right basin
        self.assertAlmostEqual(m["trust_recall"], 2 / 3)  # 3 successes, 2 trusted
        self.assertAlmostEqual(m["median_time_s"], 0.3)
        self.assertAlmostEqual(m["max_time_s"], 0.9)

    def test_nees_mean_and_median_over_the_trusted_right_basin_results_only(self):
        rows = [row("s", True, True), row("s", True, True), row("s", True, True),
                row("s", False, False), row("s", True, True), row("s", True, False)]
        for r, v in zip(rows, ["2", "4", "30", "9000", "", "700"]):  # "": no covariance
            r["nees"] = v
        m = run_accuracy.strategy_metrics(rows)
        self.assertEqual(m["nees_runs"], 3)
        # the failure's 9000 and the untrusted success's 700 are left out
        self.assertAlmostEqual(m["mean_nees"], 12.0)
        self.assertAlmostEqual(m["median_nees"], 4.0)
        # results.csv of a version before the column: no NEES, not an error.
        m = run_accuracy.strategy_metrics([row("s", True, True)])
        self.assertIsNone(m["mean_nees"])
        self.assertEqual(m["nees_runs"], 0)

    def test_nothing_trusted_or_nothing_found_gives_none_not_zero_division(self):
        m = run_accuracy.strategy_metrics([row("s", False, False)])
        self.assertIsNone(m["trust_precision"])
        self.assertIsNone(m["trust_recall"])
        self.assertIsNone(m["median_rotation_error_deg"])
        self.assertEqual(m["success_rate"], 0.0)

    def test_binned_success_uses_random_starts_only(self):
        edges = run_accuracy.offset_bins(10.0, 5)
        self.assertEqual(edges, [0.0, 2.0, 4.0, 6.0, 8.0, 10.0])
        rows = [row("s", True, True, value=0.5), row("s", False, True, value=1.9),
                row("s", True, True, value=9.99), row("s", True, True, value=10.0),
                row("s", False, True, value=0.1, experiment="protocol")]
        self.assertEqual(run_accuracy.binned_success(rows, edges),
                         [[2, 1], [0, 0], [0, 0], [0, 0], [2, 2]])


class SizeSweep(unittest.TestCase):
    """bench/size_sweep.py's per-size summary and its table (issue 39, item 6)."""

    def test_counts_trusted_wrong_median_time_and_time_per_thousand(self):
        def run(size, right, trusted, t, peer_right=False, peer_t=1.0):
            return {"landmarks": size, "default_right": right, "default_trusted": trusted,
                    "default_time_s": t, "peer_right": peer_right, "peer_cpu_s": peer_t}
        rows = [run(1000, True, True, 0.5), run(1000, False, False, 2.5, True, 0.3),
                run(1000, False, True, 1.0),  # trusted and wrong: counted apart
                run(4000, True, True, 2.0), run(4000, True, False, 4.0)]
        s = size_sweep.summary(rows)
        self.assertEqual(list(s), [1000, 4000])
        a, b = s[1000], s[4000]
        self.assertEqual((a["runs"], a["default_right"], a["default_trusted"],
                          a["default_trusted_wrong"]), (3, 1, 2, 1))
        self.assertAlmostEqual(a["default_median_time_s"], 1.0)
        self.assertAlmostEqual(a["default_max_time_s"], 2.5)
        self.assertAlmostEqual(a["default_median_time_per_1000_s"], 1.0)
        self.assertAlmostEqual(b["default_median_time_per_1000_s"], 3.0 / 4.0)
        self.assertEqual((a["peer_right"], a["peer_median_cpu_s"]), (1, 1.0))
        md = size_sweep.markdown({"date_utc": "D", "host": "h", "cores": 2, "seeds": [1],
                                  "transforms": ["0,0,0,0,0,0"], "sizes": s})
        self.assertIn("| 1,000 | 3 | 1 | 2 (1) | 1.00 / 2.50 | 1.000 | 1 | 1.00 |", md)

    def test_bad_lists_are_one_error(self):
        with self.assertRaises(size_sweep.SweepError):
            size_sweep.parse_list("1000,x", int, "--sizes")
        with self.assertRaises(size_sweep.SweepError):
            size_sweep.main(["--transforms", "1,2,3", "--build-dir", "/nonexistent"])


class StubAligner:
    """accuracy_default's Aligner without processes: right basin within `reach` of the truth
    (translation m along x, or yaw deg), scores per displacement from `scores`."""

    def __init__(self, reach_m=1.5, reach_deg=7.0, scores=None):
        self.T_true = accuracy_default.identity4()
        self.reach_m, self.reach_deg, self.scores = reach_m, reach_deg, scores or {}
        self.calls = 0

    def given(self, guess, prior):
        self.calls += 1
        dt = math.sqrt(sum(guess[i][3] ** 2 for i in range(3)))
        angle = math.degrees(math.acos(max(-1.0, min(1.0, (guess[0][0] + guess[1][1]
                                                           + guess[2][2] - 1) / 2))))
        ok = dt < self.reach_m and angle < self.reach_deg
        return {"right_basin": ok, "gated_score": 10.0, "initialisation": "given"}, prior

    def run(self, displace=None, **_):
        score, ok = self.scores[displace[0]]
        return {"gated_score": score, "right_basin": ok, "trustworthy": ok, "wall_time_s": 1.0,
                "strategy": "adaptive"}


class DefaultMeasures(unittest.TestCase):
    def test_basin_doubles_then_bisects_both_signs(self):
        a = StubAligner(reach_m=1.5)
        amount, at_limit = accuracy_default.measure_direction(
            a, "translation", [1.0, 0.0, 0.0], -1.0, [1, 1], 0.25, 64.0, 5, [0, 0, 0])
        # 0.25, 0.5, 1 ok, 2 fails; bisected 5 times in [1, 2]: 1.46875 <= 1.5.
        self.assertFalse(at_limit)
        self.assertAlmostEqual(amount, 1.46875)
        self.assertEqual(a.calls, 4 + 5)
        # Never failing: the limit itself, flagged.
        amount, at_limit = accuracy_default.measure_direction(
            StubAligner(reach_m=100), "translation", [0.0, 1.0, 0.0], 1.0, [1, 1], 0.25, 3.0, 5,
            [0, 0, 0])
        self.assertEqual((amount, at_limit), (3.0, True))
        # Failing at the first step: 0 after bisecting [0, first].
        amount, _ = accuracy_default.measure_direction(
            StubAligner(reach_m=0.01), "translation", [0.0, 0.0, 1.0], 1.0, [1, 1], 0.25, 3.0, 2,
            [0, 0, 0])
        self.assertEqual(amount, 0.0)
        # Yaw about a pivot: a rotation about the pivot moves the origin too (stub: within 1.5 m).
        amount, _ = accuracy_default.measure_direction(
            StubAligner(reach_m=1.5, reach_deg=90), "yaw", [0.0, 0.0, 1.0], 1.0, [1, 1], 1.0, 90.0,
            6, [10.0, 0.0, 0.0])
        # |origin moved| = 2 * 10 m * sin(yaw / 2) < 1.5 m: yaw < 8.6 deg.
        self.assertLess(amount, 8.6)
        self.assertGreater(amount, 8.0)

    def test_truth_refined_is_the_best_right_basin_run(self):
        class Priors(StubAligner):
            def given(self, guess, prior):  # score and basin by the prior's rotation sigma
                table = {0.05: (100.0, True), 1.0: (110.0, True), 3.0: (150.0, False)}
                score, ok = table[prior[0]]
                return {"gated_score": score, "right_basin": ok,
                        "initialisation": "given"}, prior
        run, used, tried = accuracy_default.truth_refined(
            Priors(), [[0.05, 0.005], [1.0, 0.3], [3.0, 1.0]])
        self.assertEqual(run["gated_score"], 110.0)  # the wrong-basin 150 does not count
        self.assertEqual(used, [1.0, 0.3])
        self.assertEqual([t["gated_score"] for t in tried], [100.0, 110.0, 150.0])

    def test_regret_classifies_search_and_score_failures(self):
        rows = [{"experiment": "p", "case": str(i), "value": "0", "x_m": str(float(i)),
                 "y_m": "0", "z_m": "0", "roll_deg": "0", "pitch_deg": "0", "yaw_deg": "0",
                 "strategy": s} for i in range(4) for s in ("a", "b")]  # 4 starts, 2 strategies
        a = StubAligner(scores={0.0: (10.0, True), 1.0: (5.0, False), 2.0: (10.05, False),
                                3.0: (12.0, False)})
        rep = accuracy_default.regret_report(a, rows, [[0.05, 0.005]])
        self.assertEqual(rep["starts"], 4)
        g = rep["regret"]
        self.assertEqual(g["search_failures"], 1)  # 5 < 10 by 50%
        self.assertEqual(g["score_failures"], 2)   # 10.05 within 1%, 12 above the truth
        self.assertAlmostEqual(g["max"], 5.0)
        self.assertAlmostEqual(g["max_relative"], 0.5)
        self.assertAlmostEqual(g["fraction_above_tolerance"], 0.25)
        self.assertEqual(g["worst_start"]["gated_score"], 5.0)
        self.assertAlmostEqual(rep["right_basin_rate"], 0.25)


class Driver(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="lmalign_acc_")
        self.data = os.path.join(self.tmp, "data")
        os.makedirs(self.data)
        for n in ["a.txt", "b.txt", "full.txt"]:
            with open(os.path.join(self.data, n), "w") as f:
                f.write("LANDMARK\n")
        self.fake = os.path.join(self.tmp, "lmalign")
        with open(self.fake, "w") as f:
            f.write(FAKE_LMALIGN)
        os.chmod(self.fake, os.stat(self.fake).st_mode | stat.S_IXUSR)
        self.config = os.path.join(self.tmp, "accuracy.yaml")
        with open(self.config, "w") as f:
            f.write(CONFIG)
        self.calls = os.path.join(self.tmp, "calls.txt")
        os.environ["FAKE_CALLS"] = self.calls
        os.environ["LMALIGN_DATA"] = self.data
        self.out = os.path.join(self.tmp, "out")
        # A full run writes bench/results/accuracy.json: point it into the temporary folder.
        self.saved_results = run_accuracy.RESULTS_JSON
        run_accuracy.RESULTS_JSON = os.path.join(self.tmp, "results.json")

    def tearDown(self):
        run_accuracy.RESULTS_JSON = self.saved_results
        shutil.rmtree(self.tmp)

    def run_driver(self, *extra, default=False):
        """The driver on the test config; the default's regret and basin (many fake alignments)
        only when asked."""
        flags = ([] if default else ["--no-regret", "--no-basin"]) + (
            [] if "--peer" in extra else ["--no-peers"])
        return run_accuracy.main(["--config", self.config, "--lmalign", self.fake, "--output",
                                  self.out, "--threads", "1"] + flags + list(extra))

    def calls_of(self, command):
        with open(self.calls) as f:
            return [c for c in map(json.loads, f) if c[0] == command]

    def test_whole_run_writes_csv_json_plots_and_the_configs(self):
        self.assertEqual(self.run_driver(), 0)
        with open(os.path.join(self.out, "accuracy.json")) as f:
            rep = json.load(f)
        self.assertEqual(list(rep["datasets"]), ["files", "windows", "road"])
        files = rep["datasets"]["files"]
        self.assertEqual(files["landmarks"], {"source": 1200, "target": 1300})
        self.assertEqual(files["thresholds"]["translation_m"], 0.10)
        good, far, bad = (files["strategies"][s] for s in ["good", "far", "bad"])
        self.assertEqual(good["runs"], 39 + 20)
        self.assertEqual(good["success_rate"], 1.0)
        self.assertEqual(good["trust_precision"], 1.0)
        self.assertEqual(bad["success_rate"], 0.0)
        self.assertIsNone(bad["trust_precision"])
        # far: every protocol case (offset 0 here) and the random starts below 1 m of 3 m.
        n_far = sum(1 for i in range(20) if 3.0 * (i + 0.5) / 20 < 1.0)
        self.assertEqual(far["successes"], 39 + n_far)
        self.assertAlmostEqual(far["trust_precision"], (39 + n_far) / 59)
        self.assertEqual(far["trust_recall"], 1.0)
        self.assertEqual(sum(b["runs"] for b in far["success_by_offset"]), 20)
        self.assertEqual(far["success_by_offset"][0]["successes"], 4)  # [0, 0.6): 4 of 4
        self.assertEqual(rep["datasets"]["road"]["thresholds"]["translation_m"], 1.0)
        self.assertEqual(files["reference"]["max_distance_m"], 0.1)
        self.assertEqual(rep["overall"]["good"]["runs"], 3 * 59)
        self.assertEqual(rep["overall"]["bad"]["worst_dataset"], "files")
        # accuracy.csv: one row per dataset and strategy.
        with open(os.path.join(self.out, "accuracy.csv")) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual(len(rows), 9)
        self.assertEqual(rows[0]["dataset"], "files")
        self.assertEqual(rows[0]["source_landmarks"], "1200")
        for name in ["files", "windows", "road"]:
            self.assertTrue(os.path.isfile(os.path.join(self.out, "plots", name + ".png")))
        # The Markdown tables: the matrix row of each strategy, and each dataset's table.
        with open(os.path.join(self.out, "accuracy.md")) as f:
            md = f.read()
        self.assertIn("| strategy | files | windows | road |", md)
        self.assertIn("| good | 100% | 100% | 100% |", md)
        self.assertIn("| bad | 0% | 0% | 0% |", md)
        self.assertIn("**road** (outdoor; 1200 source / 1300 target landmarks", md)
        self.assertIn("| good | 100% | 100% | 100% | 1.00 | 0.020 | 1.00 | 1.00 |", md)
        # A full run also writes the results JSON.
        self.assertTrue(os.path.isfile(run_accuracy.RESULTS_JSON))

        # The experiment configs: radius, up axis and thresholds from the dataset's kind.
        road = load_yaml(os.path.join(self.out, "road", "experiment_full.yaml"))
        rand = road["experiments"][1]
        self.assertEqual(rand["type"], "random")
        self.assertEqual(rand["translation_m"], 10.0)
        self.assertEqual(rand["up_axis"], "y")
        self.assertEqual(rand["samples"], 20)
        self.assertEqual(rand["roll_pitch_deg"], 2.0)
        self.assertEqual(rand["yaw_deg"], 180)
        self.assertEqual(road["success"], {"rotation_deg": 5.0, "translation_m": 1.0})
        self.assertEqual(len(road["experiments"][0]["poses"]), 39)
        self.assertTrue(road["ground_truth"].endswith("T_target_source.txt"))
        # The reference starts at the truth: D = the simulator's transform (x = 0.5 m).
        ref = load_yaml(os.path.join(self.out, "road", "reference.yaml"))
        self.assertEqual(ref["max_distance_m"], 0.25)
        self.assertEqual(ref["strategies"], ["base"])
        self.assertAlmostEqual(ref["experiments"][0]["poses"][0]["x_m"], 0.5)
        # The windows were split with re-triangulation, from the data folder.
        splits = self.calls_of("split")
        self.assertEqual(len(splits), 2)
        self.assertIn("--retriangulate", splits[0])
        self.assertEqual(splits[0][1], os.path.join(self.data, "full.txt"))
        self.assertEqual(splits[0][splits[0].index("--frames") + 1], "0-9")

        # A second run reuses every finished experiment and made map.
        n = len(self.calls_of("experiment"))
        self.assertEqual(self.run_driver("--no-plots"), 0)
        self.assertEqual(len(self.calls_of("experiment")), n)
        self.assertEqual(len(self.calls_of("split")), 2)
        self.assertEqual(self.calls_of("align"), [])  # --no-regret --no-basin

    def test_default_regret_basin_time_and_cache(self):
        self.assertEqual(self.run_driver("--quick", "--no-plots", "--strategies", "good",
                                         "--datasets", "files", default=True), 0)
        with open(os.path.join(self.out, "accuracy.json")) as f:
            rep = json.load(f)
        with open(os.path.join(self.out, "accuracy.md")) as f:
            md = f.read()
        files = rep["datasets"]["files"]
        # The regret of every start against the score refined from the truth.
        dflt = files["default"]
        self.assertEqual(dflt["strategy"], "adaptive")
        self.assertEqual(dflt["starts"], 8 + 10)
        self.assertEqual(dflt["truth_refined"]["gated_score"], 100.0)
        self.assertEqual(dflt["truth_refined"]["prior_sigma"], [0.05, 0.005])
        self.assertEqual(len(dflt["truth_refined"]["tried"]), 2)  # the truth and basin priors
        # Quick protocol (every 5th): x = 0, 0, 0.5, -0.9, 1.25, 0.5, -0.5, 0.5: one x >= 1, one
        # x <= -0.8; random x = 3 (i + 0.5) / 10 >= 1: i = 3..9.
        self.assertEqual(dflt["regret"]["search_failures"], 1 + 7)
        self.assertEqual(dflt["regret"]["score_failures"], 1)
        self.assertAlmostEqual(dflt["regret"]["max"], 40.0)
        self.assertAlmostEqual(dflt["regret"]["max_relative"], 0.4)
        self.assertAlmostEqual(dflt["regret"]["fraction_above_tolerance"], 8 / 18)
        self.assertAlmostEqual(dflt["right_basin_rate"], 9 / 18)
        self.assertEqual(dflt["trust_precision"], 1.0)
        self.assertAlmostEqual(dflt["median_time_s"], 0.2)
        # The basin: the prior halved until "given"; 2 m found as 1.82 (doubled from 0.02 m to
        # 1.28, the 2 m limit fails, 2 bisections), 11 deg as 10 (8 ok, 16 and 12 fail).
        basin = dflt["basin"]
        self.assertEqual(basin["prior_sigma"], [0.5, 0.025])
        self.assertEqual(sorted(basin["directions"]), ["x_m", "y_m", "yaw_deg", "z_m"])
        for k in ["x_m", "y_m", "z_m"]:
            self.assertAlmostEqual(basin["directions"][k]["+"], 1.82)
            self.assertAlmostEqual(basin["directions"][k]["-"], 1.82)
        self.assertAlmostEqual(basin["directions"]["yaw_deg"]["+"], 10.0)
        self.assertAlmostEqual(basin["directions"]["yaw_deg"]["-"], 10.0)
        with open(os.path.join(self.out, "default.csv")) as f:
            drows = list(csv.DictReader(f))
        self.assertEqual([r["dataset"] for r in drows], ["files"])
        self.assertEqual(drows[0]["search_failures"], "8")
        self.assertEqual(drows[0]["basin_yaw_deg_plus"], "10.0")
        self.assertIn("| files | 1200 / 1300 | 50% | 1.00 / 1.00 | 100 | 40 (40.0%) | 44% "
                      "| 8 / 1 | 0.200 / 0.20 |", md)
        self.assertIn("| files | 0.5, 0.025 | -1.82 / +1.82 | -1.82 / +1.82 | -1.82 / +1.82 "
                      "| – | -10 / +10 |", md)
        # A second run reuses every alignment (cached by arguments and binary).
        n_align = len(self.calls_of("align"))
        self.assertEqual(self.run_driver("--quick", "--no-plots", "--strategies", "good",
                                         "--datasets", "files", default=True), 0)
        self.assertEqual(len(self.calls_of("align")), n_align)

    def test_reference_search_beside_the_default_from_the_same_starts(self):
        with open(self.config, "w") as f:
            f.write(CONFIG + "default: {reference_strategy: exhaustive}\n")
        self.assertEqual(self.run_driver("--quick", "--no-plots", "--no-basin", "--strategies",
                                         "good", "--datasets", "files", default=True), 0)
        with open(os.path.join(self.out, "accuracy.json")) as f:
            dflt = json.load(f)["datasets"]["files"]["default"]
        ref = dflt["reference"]
        # The same 18 starts, the same truth-refined score (refined once, by the default).
        self.assertEqual(ref["strategy"], "exhaustive")
        self.assertEqual(ref["starts"], dflt["starts"])
        self.assertEqual(ref["truth_refined"], dflt["truth_refined"])
        aligns = self.calls_of("align")
        exhaustive = [c for c in aligns if "--strategy" in c]
        default_starts = [c for c in aligns if "--strategy" not in c and "--displace" in c]
        # One run per distinct start, each strategy (the 18 starts repeat some displacements).
        self.assertEqual(len(exhaustive), len(default_starts))
        self.assertGreater(len(exhaustive), 10)
        self.assertTrue(all(c[c.index("--strategy") + 1] == "exhaustive" for c in exhaustive))
        self.assertTrue(all("--displace" in c for c in exhaustive))
        # The reference finds the 8 starts with x >= 1 that the default's search misses.
        self.assertAlmostEqual(ref["right_basin_rate"], 17 / 18)
        self.assertEqual(ref["regret"]["search_failures"], 0)
        self.assertEqual(ref["regret"]["score_failures"], 1)
        self.assertEqual(ref["reference_scores_higher"], 8)
        self.assertEqual(ref["default_scores_higher"], 0)
        # The same answer: 9 right in both, and the score failure (the same wrong pose).
        self.assertAlmostEqual(ref["same_answer_rate"], 10 / 18)
        self.assertAlmostEqual(ref["median_time_ratio_default_over_reference"], 0.4)
        self.assertAlmostEqual(ref["median_time_s"], 0.5)
        with open(os.path.join(self.out, "default.csv")) as f:
            row = next(csv.DictReader(f))
        self.assertEqual(row["reference_strategy"], "exhaustive")
        self.assertEqual(row["reference_scores_higher"], "8")
        with open(os.path.join(self.out, "accuracy.md")) as f:
            md = f.read()
        self.assertIn("| files | 94% | 1.00 / 1.00 | 0 (0.0%) | 0 / 1 | 0.500 / 0.50 | 56% "
                      "| 0 / 8 | 0.40x |", md)
        # --no-reference skips it (the default's own runs are cached).
        n = len(self.calls_of("align"))
        self.assertEqual(self.run_driver("--quick", "--no-plots", "--no-basin", "--no-reference",
                                         "--strategies", "good", "--datasets", "files",
                                         default=True), 0)
        self.assertEqual(len(self.calls_of("align")), n)
        with open(os.path.join(self.out, "accuracy.json")) as f:
            self.assertNotIn("reference", json.load(f)["datasets"]["files"]["default"])

    def test_peer_beside_the_default_right_basin_cpu_ratio_and_cache(self):
        # A stand-in for lmalign_peer_open3d_global: seed 1 finds the truth (identity) in 0.1 s,
        # seed 2 is 10 deg off (0.5 s), seed 3 is 0.2 m off (0.3 s; the threshold is 0.1 m).
        peer = os.path.join(self.tmp, "peer")
        with open(peer, "w") as f:
            f.write(FAKE_PEER)
        os.chmod(peer, os.stat(peer).st_mode | stat.S_IEXEC)
        self.assertEqual(self.run_driver("--quick", "--no-plots", "--strategies", "good",
                                         "--datasets", "files", "--peer", peer), 0)
        with open(os.path.join(self.out, "accuracy.json")) as f:
            p = json.load(f)["datasets"]["files"]["peers"]
        self.assertEqual([r["seed"] for r in p["peer_runs"]], [1, 2, 3])
        self.assertEqual([r["right_basin"] for r in p["peer_runs"]], [True, False, False])
        self.assertAlmostEqual(p["peer_runs"][1]["rotation_error_deg"], 10.0)
        self.assertAlmostEqual(p["peer_runs"][2]["translation_error_m"], 0.2)
        self.assertEqual(p["peer_right_basin"], 1)
        self.assertAlmostEqual(p["peer_median_cpu_s"], 0.3)
        # The default once, on the maps as given (displacement 0), on one thread.
        self.assertTrue(p["default"]["right_basin"] and p["default"]["trustworthy"])
        self.assertAlmostEqual(p["cpu_ratio_peer_over_default"], 0.3 / 0.2)
        aligns = [c for c in self.calls_of("align") if "--displace" in c]
        self.assertEqual([c[c.index("--displace") + 1] for c in aligns], ["0,0,0,0,0,0"])
        with open(os.path.join(self.out, "peers.csv")) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual([(r["dataset"], r["peer_right"], r["peer_runs"]) for r in rows],
                         [("files", "1", "3")])
        with open(os.path.join(self.out, "accuracy.md")) as f:
            md = f.read()
        self.assertIn("| files | 1200 / 1300 | right, trusted, 0.50° / 0.01 m | 0.20 | 1 of 3 "
                      "| 0.00° / 0 m | 0.30 | 1.50x |", md)  # medians of (0, 10, 0) deg, (0, 0, 0.2) m
        # A second run reuses the peer's runs and the default's (cached by arguments, binary).
        n_peer, n_align = len(self.calls_of("peer")), len(aligns)
        self.assertEqual(n_peer, 3)
        self.assertEqual(self.run_driver("--quick", "--no-plots", "--strategies", "good",
                                         "--datasets", "files", "--peer", peer), 0)
        self.assertEqual(len(self.calls_of("peer")), n_peer)
        self.assertEqual(len([c for c in self.calls_of("align") if "--displace" in c]), n_align)
        # A peer that fails is one error naming it, not a traceback.
        with open(peer, "w") as f:
            f.write("#!/bin/sh\necho 'bad map' >&2\nexit 2\n")
        shutil.rmtree(os.path.join(self.out, "files", "peers"))
        with self.assertRaises(run_accuracy.BenchError) as e:
            self.run_driver("--quick", "--no-plots", "--strategies", "good", "--datasets",
                            "files", "--peer", peer)
        self.assertIn("bad map", str(e.exception))

    def test_similarity_datasets_move_the_source_and_time_it_against_rigid(self):
        with open(self.config, "a") as f:
            f.write("similarity:\n  - {name: files_sim3, of: files, scale: 0.5, yaw_deg: 90, "
                    "translation: [1, 2, 3], starts: 4}\n")
        self.assertEqual(self.run_driver("--no-plots", "--strategies", "good", "--datasets",
                                         "files"), 0)
        with open(os.path.join(self.out, "accuracy.json")) as f:
            rep = json.load(f)
        sim = rep["similarity"]["files_sim3"]
        # The source was moved by M = [0.5 Rz(90) t] and marked arbitrary; the truth is M^-1.
        conv = self.calls_of("convert")
        self.assertEqual(len(conv), 1)
        self.assertEqual(conv[0][1], os.path.join(self.data, "a.txt"))
        M = accuracy_default.read_transform(conv[0][conv[0].index("--transform") + 1])
        self.assertAlmostEqual(M[0][1], -0.5)
        self.assertAlmostEqual(M[1][0], 0.5)
        self.assertEqual([M[i][3] for i in range(3)], [1.0, 2.0, 3.0])
        S = accuracy_default.read_transform(
            os.path.join(self.out, "files_sim3", "maps", "S_target_source.txt"))
        MS = accuracy_default.matmul4(S, M)
        for r in range(4):
            for c in range(4):
                self.assertAlmostEqual(MS[r][c], float(r == c))
        # The first 4 of the 8 quick protocol starts, each rigid and Sim(3), one thread each:
        # x = 0, 0, 0.5, -0.9: the fake finds the truth from all but -0.9.
        aligns = self.calls_of("align")
        self.assertEqual(len(aligns), 8)
        self.assertEqual(sim["starts"], 4)
        self.assertEqual(sim["scale_mode"], ["free"])
        self.assertAlmostEqual(sim["right_basin_rate"], 0.75)
        self.assertAlmostEqual(sim["median_scale_error"], 0.002)
        self.assertAlmostEqual(sim["median_time_ratio"], 1.25)
        self.assertEqual(sim["time_ratio_range"], [1.25, 1.25])
        with open(os.path.join(self.out, "similarity.csv")) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual(rows[0]["name"], "files_sim3")
        self.assertEqual(rows[0]["median_time_ratio"], "1.25")
        with open(os.path.join(self.out, "accuracy.md")) as f:
            self.assertIn("| files_sim3 | files | 0.5 | 4 | 75% | 75% | 0.200% |", f.read())

    def test_similarity_config_errors_name_the_field(self):
        for entry, message in [
                ("{name: x, of: nope, scale: 2}", "similarity[0].of: 'nope'"),
                ("{name: x, of: files, scale: -1}", "similarity[0].scale: expected a number > 0"),
                ("{name: x, of: files, scale: 2, yaw: 3}", "unknown key 'yaw'"),
                ("{name: files, of: files, scale: 2}", "similarity[0].name: 'files' is used")]:
            with open(self.config, "w") as f:
                f.write(CONFIG + "similarity:\n  - " + entry + "\n")
            with self.assertRaises(run_accuracy.BenchError) as e:
                self.run_driver("--datasets", "files")
            self.assertIn(message, str(e.exception))

    def test_quick_and_selection(self):
        self.assertEqual(self.run_driver("--quick", "--no-plots", "--strategies", "good",
                                         "--datasets", "files"), 0)
        with open(os.path.join(self.out, "accuracy.json")) as f:
            rep = json.load(f)
        self.assertEqual(list(rep["datasets"]), ["files"])
        self.assertEqual(list(rep["datasets"]["files"]["strategies"]), ["good"])
        self.assertEqual(rep["datasets"]["files"]["strategies"]["good"]["runs"], 8 + 10)
        self.assertFalse(os.path.isfile(run_accuracy.RESULTS_JSON))
        with self.assertRaises(run_accuracy.BenchError) as e:
            self.run_driver("--strategies", "nope")
        self.assertIn("nope", str(e.exception))

    def test_missing_dataset_file_is_one_error_naming_it(self):
        os.remove(os.path.join(self.data, "b.txt"))
        with self.assertRaises(run_accuracy.BenchError) as e:
            self.run_driver("--datasets", "files", "--no-plots")
        self.assertIn("dataset files: target", str(e.exception))
        self.assertIn(os.path.join(self.data, "b.txt"), str(e.exception))

    def test_config_errors_name_the_field(self):
        bad = CONFIG.replace("kind: outdoor, up_axis: y", "kind: underwater, up_axis: y")
        with open(self.config, "w") as f:
            f.write(bad)
        with self.assertRaises(run_accuracy.BenchError) as e:
            run_accuracy.load_config(self.config, self.data)
        self.assertIn("datasets[2].kind", str(e.exception))
        with open(self.config, "w") as f:
            f.write(CONFIG.replace("name: windows", "name: files"))
        with self.assertRaises(run_accuracy.BenchError) as e:
            run_accuracy.load_config(self.config, self.data)
        self.assertIn("used twice", str(e.exception))
        with open(self.config, "w") as f:
            f.write(CONFIG.replace("reference_max_distance_m: 0.25}",
                                   "reference_max_distance_m: 0.25, basin_prior_sigma: [1, -2]}"))
        with self.assertRaises(run_accuracy.BenchError) as e:
            run_accuracy.load_config(self.config, self.data)
        self.assertIn("datasets[2].basin_prior_sigma", str(e.exception))
        with open(self.config, "w") as f:
            f.write(CONFIG + "default: {reference_strategy: [exhaustive]}\n")
        with self.assertRaises(run_accuracy.BenchError) as e:
            run_accuracy.load_config(self.config, self.data)
        self.assertIn("default.reference_strategy", str(e.exception))


if __name__ == "__main__":
    unittest.main()
