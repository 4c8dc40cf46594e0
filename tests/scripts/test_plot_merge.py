#!/usr/bin/env python3
"""Tests of scripts/plot_merge.py (the pictures of `lmalign merge`): nodes at the maps' landmark
centres, landmarks attributed to the map that added them, robust axis limits that far landmarks
do not stretch, the top-down view along the frames' up axis, and a whole run on a small output
folder. Run by ctest (tests/CMakeLists.txt) with Debian's python3 (numpy, matplotlib)."""
import csv
import json
import os
import shutil
import sys
import tempfile
import unittest

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import plot_merge  # noqa: E402


def pose(t):
    return [[1, 0, 0, t[0]], [0, 1, 0, t[1]], [0, 0, 1, t[2]], [0, 0, 0, 1]]


class Pieces(unittest.TestCase):
    def test_nodes_at_the_landmark_centre_not_the_frame_origin(self):
        maps = [{"T_world_map": pose([100, 0, 0]), "landmark_centre_world": [1.0, 2.0, 3.0]},
                {"T_world_map": pose([5, 6, 7]), "landmark_centre_world": None},
                {"T_world_map": pose([8, 9, 10])}]  # an output from before the field
        np.testing.assert_array_equal(plot_merge.node_positions(maps, np),
                                      [[1, 2, 3], [5, 6, 7], [8, 9, 10]])

    def test_landmarks_attributed_to_the_map_that_added_them(self):
        maps = [{"component": 0, "merged_landmarks": [0, 3]},
                {"component": 1, "merged_landmarks": [0, 5]},
                {"component": 0, "merged_landmarks": [3, 4]},
                {"component": 0}]
        own = plot_merge.landmark_owners(np.arange(6), maps, 0, np)
        self.assertEqual(own.tolist(), [0, 0, 0, 2, -1, -1])

    def test_robust_limits_leave_far_landmarks_out(self):
        rng = np.random.default_rng(1)
        xy = rng.uniform(-10, 10, (2000, 2))
        far = np.array([[700.0, 0.0], [0.0, -650.0], [400.0, 400.0]])
        xlim, ylim, beyond = plot_merge.robust_limits(np.vstack([xy, far]), np.zeros((0, 2)), np)
        self.assertLess(xlim[1], 12.0)
        self.assertGreater(xlim[0], -12.0)
        self.assertGreater(ylim[0], -12.0)
        self.assertGreaterEqual(beyond, 3)
        # Nodes are always inside.
        xlim, _, _ = plot_merge.robust_limits(xy, np.array([[30.0, 0.0]]), np)
        self.assertGreaterEqual(xlim[1], 30.0)

    def test_top_down_along_the_frames_up_axis(self):
        # A road along x, 40 m long, 20 m wide, 30 m tall: the smallest principal axis is the
        # width (y), so without frames the view would look along the road's side, not down.
        rng = np.random.default_rng(2)
        pts = np.column_stack([rng.uniform(0, 40, 3000), rng.uniform(-10, 10, 3000),
                               rng.uniform(0, 30, 3000)])
        basis, _ = plot_merge.principal_basis(pts, np.array([0.0, 0.0, 1.0]), np)
        np.testing.assert_allclose(abs(basis[2] @ [0, 0, 1]), 1.0, atol=1e-9)
        self.assertGreater(abs(basis[0] @ [1, 0, 0]), 0.99)  # along the road
        self.assertAlmostEqual(np.linalg.det(basis), 1.0)
        basis, _ = plot_merge.principal_basis(pts, None, np)
        self.assertGreater(abs(basis[2] @ [0, 1, 0]), 0.99)


class WholeRun(unittest.TestCase):
    def setUp(self):
        self.out = tempfile.mkdtemp(prefix="lmalign_plot_merge_")

    def tearDown(self):
        shutil.rmtree(self.out)

    def test_writes_both_pngs_and_reads_the_frames_up_axis(self):
        rng = np.random.default_rng(3)
        lines = []
        # Camera frames looking along +x with y down: up is -y... here the world's up is +z:
        # camera x right = -y world, camera y down = -z world, camera z forward = +x world.
        # R columns: (0,-1,0), (0,0,-1), (1,0,0); as a quaternion w x y z:
        q = (0.5, -0.5, 0.5, -0.5)
        for f in range(4):
            lines.append("FRAME %d %g 0 1.5 %g %g %g %g" % ((f, 5.0 * f) + q))
        for k in range(400):
            p = (rng.uniform(0, 40), rng.uniform(-8, 8), rng.uniform(0, 10))
            lines.append("LANDMARK %d %g %g %g 1e-4 0 0 0 1e-4 0 0 0 1e-4 0" % ((k,) + p))
        lines.append("LANDMARK 400 900 0 0 1e-4 0 0 0 1e-4 0 0 0 1e-4 0")  # far away
        with open(os.path.join(self.out, "merged_map.txt"), "w") as f:
            f.write("\n".join(lines) + "\n")
        ids, pts, up = plot_merge.read_merged_map(os.path.join(self.out, "merged_map.txt"), np)
        self.assertEqual(len(ids), 401)
        np.testing.assert_allclose(up, [0, 0, 1], atol=1e-9)
        maps = [{"name": "a", "component": 0, "gauge": True, "T_world_map": pose([0, 0, 0]),
                 "landmark_centre_world": [10, 0, 5], "merged_landmarks": [0, 200]},
                {"name": "b", "component": 0, "gauge": False, "T_world_map": pose([3, 0, 0]),
                 "landmark_centre_world": [30, 0, 5], "merged_landmarks": [200, 401]}]
        with open(os.path.join(self.out, "poses.json"), "w") as f:
            json.dump({"num_components": 1, "maps": maps}, f)
        with open(os.path.join(self.out, "edges.csv"), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["source", "target", "trusted", "used", "rejected", "chi2", "inliers",
                        "inlier_ratio", "initialisation", "reason"])
            w.writerow(["a", "b", 1, 1, 0, 2.5, 100, 0.5, "global", "ok"])
        sys.argv = ["plot_merge.py", self.out, "--quiet"]
        plot_merge.main()
        for name in ["merge_graph.png", "merged_landmarks.png"]:
            with open(os.path.join(self.out, name), "rb") as f:
                data = f.read()
            self.assertTrue(data.startswith(b"\x89PNG\r\n\x1a\n"), name)
            self.assertGreater(len(data), 5000, name)


if __name__ == "__main__":
    unittest.main()
