#!/usr/bin/env python3
"""Tests of bench/merge_real.py's bookkeeping (no alignment): a case's view of its config, and
the summary of a merge's outputs against the truth (parts, neighbouring edges found or why not,
false edges kept, pairs within the thresholds). Run by ctest (tests/CMakeLists.txt); needs numpy
and PyYAML."""
import csv
import json
import os
import sys
import tempfile
import unittest

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import merge_real  # noqa: E402

TH = {"rotation_deg": 2.0, "translation_m": 0.5}


def pose(yaw_deg, x, y=0.0):
    T = np.eye(4)
    T[:3, :3] = merge_real.axis_angle([0, 1, 0], np.radians(yaw_deg))
    T[:3, 3] = [x, y, 0.0]
    return T


class CaseConfig(unittest.TestCase):
    def test_a_case_replaces_keys_of_simulate_windows_split_and_the_pose_seed(self):
        cfg = {"simulate": {"frames": 30, "overlap": 0.25, "seed": 41}, "seed": 43,
               "windows": {"first": 1, "length": 8, "step": 6, "count": 4}}
        c = merge_real.case_config(cfg, {"name": "x", "simulate": {"overlap": 0.5},
                                         "windows": {"count": 3}, "poses": {"seed": 9}})
        self.assertEqual(c["simulate"], {"frames": 30, "overlap": 0.5, "seed": 41})
        self.assertEqual(c["windows"], {"first": 1, "length": 8, "step": 6, "count": 3})
        self.assertEqual(c["seed"], 9)
        self.assertEqual(cfg["simulate"]["overlap"], 0.25)  # the config itself is unchanged
        self.assertEqual(merge_real.case_config(cfg, {"name": "y"})["seed"], 43)


class Summarise(unittest.TestCase):
    """Three windows w0, w1, w2 of one drive. The merge kept w0 -> w1 (true) and w0 -> w2 (10 deg
    off: false), refused w1 -> w2 although it was right; w2 ended in a part of its own."""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        out = self.tmp.name
        os.makedirs(os.path.join(out, "edges"))
        self.truth = {"w0": pose(30, 1), "w1": pose(-100, 20, 1), "w2": pose(170, 40, 2)}
        est = {"w0": np.eye(4),
               "w1": np.linalg.inv(self.truth["w0"]) @ self.truth["w1"] @ pose(0.5, 0.1),
               "w2": pose(45, 3)}
        poses = {"maps": [{"name": n, "T_world_map": est[n].tolist(), "component": c}
                          for n, c in (("w0", 0), ("w1", 0), ("w2", 1))]}
        with open(os.path.join(out, "poses.json"), "w") as f:
            json.dump(poses, f)
        edges = [("w0", "w1", 1, 1, 0, "ok", 0.0), ("w0", "w2", 1, 1, 0, "ok", 10.0),
                 ("w1", "w2", 0, 0, 0, "untrusted: few landmarks agree", 0.0)]
        with open(os.path.join(out, "edges.csv"), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["source", "target", "trusted", "used", "rejected", "chi2", "inliers",
                        "inlier_ratio", "initialisation", "reason"])
            for s, t, trusted, used, rejected, reason, off_deg in edges:
                w.writerow([s, t, trusted, used, rejected, 0, 100, 0.3, "global", reason])
                T = pose(off_deg, 0) @ np.linalg.inv(self.truth[t]) @ self.truth[s]
                with open(os.path.join(out, "edges", "%s__%s.json" % (s, t)), "w") as g:
                    json.dump({"T_target_source": T.tolist()}, g)
        self.out = out

    def tearDown(self):
        self.tmp.cleanup()

    def test_parts_neighbours_false_edges_and_pairs(self):
        s = merge_real.summarise(self.out, ["w0", "w1", "w2"], self.truth, TH)
        self.assertEqual(s["parts"], 2)
        self.assertEqual(s["candidates"], 3)
        self.assertEqual(s["trusted"], 2)
        self.assertEqual(s["neighbour_pairs"], 2)
        self.assertEqual(s["neighbour_edges_found"], 1)
        self.assertEqual(s["neighbour_edges"][0]["status"], "found")
        self.assertEqual(s["neighbour_edges"][1]["status"],
                         "right, refused: untrusted: few landmarks agree")
        self.assertEqual(s["false_edges_kept"], 1)
        # w0-w1 is 0.5 deg / 0.1 m off: within; w2 is in another part: no pair with it is.
        self.assertEqual((s["pairs"], s["pairs_within"]), (3, 1))

    def test_a_pair_beyond_the_thresholds_is_not_within(self):
        s = merge_real.summarise(self.out, ["w0", "w1", "w2"], self.truth,
                                 {"rotation_deg": 0.4, "translation_m": 0.5})
        self.assertEqual(s["pairs_within"], 0)
        self.assertEqual(s["neighbour_edges"][0]["status"], "found")  # the edge itself is exact

    def test_a_neighbouring_pair_that_was_no_candidate_says_so(self):
        s = merge_real.summarise(self.out, ["w0", "w2", "w1"], self.truth, TH)
        self.assertEqual(s["neighbour_edges"][0]["status"], "kept but false")
        self.assertEqual(s["neighbour_edges"][1]["status"], "not a candidate")


if __name__ == "__main__":
    unittest.main()
