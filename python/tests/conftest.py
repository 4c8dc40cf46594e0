"""Shared fixtures of the Python tests (run by ctest: tests/CMakeLists.txt, label python).

Real data: $LMALIGN_DATA, else $LMALIGN_DEFAULT_DATA_DIR (set by ctest), else ../shared/data
beside the repository. Missing data skips a test locally and fails it with CI=true (house rule,
as tests/support/data_path.hpp).
"""
import os
import pathlib

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
