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
