"""Shared fixtures of the Python tests (run by ctest: tests/CMakeLists.txt, label python).

Real data: $LMALIGN_DATA, else $LMALIGN_DEFAULT_DATA_DIR (set by ctest), else ../shared/data
beside the repository. Missing data skips a test locally and fails it with CI=true (house rule,
as tests/support/data_path.hpp).
"""
import os
import pathlib

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def data_dir():
    for var in ("LMALIGN_DATA", "LMALIGN_DEFAULT_DATA_DIR"):
        if os.environ.get(var):
            return pathlib.Path(os.environ[var])
    return REPO.parent / "shared" / "data"


def require_file(path):
    path = pathlib.Path(path)
    if not path.exists():
        message = "real data not found: %s (set LMALIGN_DATA)" % path
        if os.environ.get("CI") == "true":
            pytest.fail("real data missing in CI: " + message)
        pytest.skip(message)
    return path


@pytest.fixture
def desk_pair():
    """(source, target) paths of the real TUM fr1/desk ground-truth pair (truth: identity)."""
    d = data_dir() / "tum_fr1_desk" / "ground_truth_pair"
    return require_file(d / "desk_gt_a.txt"), require_file(d / "desk_gt_b.txt")


@pytest.fixture
def cli():
    """Path of the lmalign executable of this build (ctest sets LMALIGN_CLI)."""
    path = os.environ.get("LMALIGN_CLI")
    if not path or not os.path.exists(path):
        pytest.fail("LMALIGN_CLI does not name the lmalign executable (run through ctest)")
    return path


def write_desk_windows(directory, count=4, frames=30, prior_sigma=None):
    """Cuts the real desk map (motion-capture anchored, map_fr1_desk_gt.txt) into `count` windows
    of `frames` frames with lmalign.split, writes them and a merge manifest into `directory`,
    and returns the manifest's path. Every window stays in the map's frame: the truth is the
    identity. prior_sigma (rot_deg, trans_m): each map gets the identity prior with that sigma.
    """
    import lmalign

    path = require_file(data_dir() / "tum_fr1_desk" / "ground_truth_pair" /
                        "map_fr1_desk_gt.txt")
    full = lmalign.read_map(path, min_observations=0)
    directory = pathlib.Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    lines = ["maps:"]
    for k in range(count):
        window = lmalign.split(full, k * frames, k * frames + frames - 1)
        lmalign.write_map(directory / ("w%d.txt" % k), window)
        lines += ["  - name: w%d" % k, "    path: w%d.txt" % k]
        if prior_sigma is not None:
            lines += ["    T_world_map: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]",
                      "    prior_sigma: [%r, %r]" % tuple(prior_sigma)]
    manifest = directory / "manifest.yaml"
    manifest.write_text("\n".join(lines) + "\n")
    return manifest


# The similarities SOURCE.md of real_formats/stella_openhps_aist_living_lab_1 estimated from
# matching keyframes (an estimate, not ground truth: its own cycle closes to 0.1% in scale), as
# S_world_map with the frame of 4683e8ac as the world: p_world = s R p_map + t.
STELLA_TRUTH = {
    "356a5a6e": (0.79165, [[0.999826, 0.01738, -0.006787], [-0.017191, 0.999489, 0.026942],
                           [0.007252, -0.026821, 0.999614]], [-0.003697, -0.008522, 0.128970]),
    "94eb7149": (1.06574, [[0.999738, 0.021504, -0.007805], [-0.021262, 0.999328, 0.029848],
                           [0.008441, -0.029675, 0.999524]], [-0.005149, -0.005160, 0.153141]),
    "4683e8ac": (1.0, np.eye(3).tolist(), [0.0, 0.0, 0.0]),
}


def write_stella_manifest(directory):
    """A merge manifest of the three real monocular stella_vslam maps of one video (each of its
    own arbitrary scale; no priors) and a ground-truth YAML of STELLA_TRUTH (rotations
    re-orthonormalised: SOURCE.md rounds them to 6 digits). Returns (manifest, truth) paths."""
    base = data_dir() / "real_formats" / "stella_openhps_aist_living_lab_1"
    directory = pathlib.Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    lines, truth = ["maps:"], ["maps:"]
    for name, (s, R, t) in STELLA_TRUTH.items():
        path = require_file(base / name / "map.msg")
        lines += ["  - name: %s" % name, "    path: %s" % path]
        u, _, vt = np.linalg.svd(np.array(R))
        S = np.eye(4)
        S[:3, :3] = s * (u @ vt)
        S[:3, 3] = t
        truth.append("  %s: [%s]" % (name, ", ".join(
            "[%s]" % ", ".join(repr(float(v)) for v in row) for row in S)))
    manifest = directory / "manifest.yaml"
    manifest.write_text("\n".join(lines) + "\n")
    truth_path = directory / "truth.yaml"
    truth_path.write_text("\n".join(truth) + "\n")
    return manifest, truth_path
