#!/usr/bin/env python3
"""Tests of bench/run_bench.py's bookkeeping (not of any timing): how rounds are merged, how the
ratios pair rounds, and how the paper protocol is timed and read back. Run by ctest
(tests/CMakeLists.txt) as `python3 tests/bench/test_run_bench.py`."""
import os
import shutil
import stat
import sys
import tempfile
import types
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import run_bench  # noqa: E402


def record(total_s, times_s, peak=1000, added=100, iterations=150, load=0.5):
    return {"config": "c", "iterations": iterations, "total_s": total_s, "times_s": times_s,
            "peak_rss_bytes": peak, "added_peak_rss_bytes": added, "loadavg_1min_before": load}


class MergeRounds(unittest.TestCase):
    def test_median_over_every_run_and_largest_memory(self):
        recs = [record(0.2, [0.2, 0.3], peak=10, added=1),
                record(0.1, [0.1, 0.1], peak=30, added=3, load=2.0),
                record(0.5, [0.5, 0.9], peak=20, added=2)]
        m = run_bench.merge_rounds(recs)
        self.assertEqual(m["rounds"], 3)
        self.assertEqual(m["times_s"], [0.2, 0.3, 0.1, 0.1, 0.5, 0.9])
        self.assertAlmostEqual(m["total_s"], 0.25)  # median of the six runs
        self.assertAlmostEqual(m["min_total_s"], 0.1)
        self.assertAlmostEqual(m["per_iteration_s"], 0.25 / 150)
        self.assertEqual(m["round_total_s"], [0.2, 0.1, 0.5])
        self.assertEqual(m["peak_rss_bytes"], 30)
        self.assertEqual(m["added_peak_rss_bytes"], 3)
        self.assertEqual(m["loadavg_1min_before"], 2.0)


class PairedRatio(unittest.TestCase):
    def test_a_slow_round_moves_both_sides_and_not_the_ratio(self):
        # The machine runs 3x slower in round 2 for both configurations: every round says 10x.
        mine = {"round_total_s": [0.1, 0.3, 0.1]}
        peer = {"round_total_s": [1.0, 3.0, 1.0]}
        ratio, per = run_bench.paired_ratio(peer, mine)
        self.assertAlmostEqual(ratio, 10.0)
        self.assertEqual(len(per), 3)
        for r in per:
            self.assertAlmostEqual(r, 10.0)

    def test_one_disturbed_round_does_not_set_the_median(self):
        mine = {"round_total_s": [0.1, 0.1, 0.1, 0.1, 0.1]}
        peer = {"round_total_s": [1.0, 1.1, 5.0, 0.9, 1.0]}  # round 3: the peer alone disturbed
        ratio, per = run_bench.paired_ratio(peer, mine)
        self.assertAlmostEqual(ratio, 10.0)
        self.assertAlmostEqual(max(per), 50.0)


FAKE_LMALIGN = """#!/bin/sh
# A stand-in for `lmalign experiment CONFIG -o OUT --no-plots`: writes OUT/results.csv.
out=""
while [ $# -gt 0 ]; do
  if [ "$1" = "-o" ]; then out="$2"; shift; fi
  shift
done
mkdir -p "$out"
printf 'experiment,strategy,iterations\\nt1,base,10\\nt1,covariance,32\\n' > "$out/results.csv"
exit {code}
"""


class Protocol(unittest.TestCase):
    def fake_build(self, code):
        build = tempfile.mkdtemp(prefix="fake_build_")
        self.addCleanup(shutil.rmtree, build, True)
        exe_dir = os.path.join(build, "apps", "lmalign")
        os.makedirs(exe_dir)
        exe = os.path.join(exe_dir, "lmalign")
        with open(exe, "w") as f:
            f.write(FAKE_LMALIGN.format(code=code))
        os.chmod(exe, os.stat(exe).st_mode | stat.S_IXUSR)
        return build

    def test_reads_runs_and_iterations_and_judges_the_target(self):
        args = types.SimpleNamespace(build_dir=self.fake_build(0), wait_policy="passive")
        rec = run_bench.protocol(args)
        self.assertIsNotNone(rec)
        self.assertEqual(rec["runs"], 2)
        self.assertEqual(rec["iterations"], 42)
        self.assertGreater(rec["wall_s"], 0.0)
        self.assertLess(rec["wall_s"], run_bench.PROTOCOL_TARGET_S)
        self.assertTrue(rec["met"])
        self.assertEqual(rec["target_s"], run_bench.PROTOCOL_TARGET_S)

    def test_a_failed_run_gives_no_record(self):
        args = types.SimpleNamespace(build_dir=self.fake_build(3), wait_policy="passive")
        self.assertIsNone(run_bench.protocol(args))

    def test_missing_executable_gives_no_record(self):
        empty = tempfile.mkdtemp(prefix="empty_build_")
        self.addCleanup(shutil.rmtree, empty, True)
        args = types.SimpleNamespace(build_dir=empty, wait_policy="default")
        self.assertIsNone(run_bench.protocol(args))


if __name__ == "__main__":
    unittest.main()
