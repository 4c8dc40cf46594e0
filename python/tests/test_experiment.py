"""lmalign.experiment() writes the same results.csv as `lmalign experiment` (but the timing)."""
import csv
import subprocess

import pytest

import lmalign
from conftest import data_dir

CONFIG = """\
source: ${LMALIGN_DATA}/tum_fr1_desk/ground_truth_pair/desk_gt_a.txt
target: ${LMALIGN_DATA}/tum_fr1_desk/ground_truth_pair/desk_gt_b.txt
ground_truth: identity
strategies: [base, covariance, robust_obs]
experiments:
  - name: yaw
    type: yaw
    yaw_deg: [0, 40]
"""


def rows_without_time(path):
    with open(path, newline="") as f:
        return [{k: v for k, v in row.items() if k != "time_s"} for row in csv.DictReader(f)]


def test_experiment_equals_cli(desk_pair, cli, tmp_path):
    config = tmp_path / "small.yaml"
    config.write_text(CONFIG)
    env = {"LMALIGN_DATA": str(data_dir()), "PATH": "/usr/bin:/bin"}
    subprocess.run([cli, "experiment", str(config), "-o", str(tmp_path / "cli"), "--no-plots"],
                   check=True, env=env, stdout=subprocess.DEVNULL)
    report = lmalign.experiment(config, tmp_path / "py", data_dir=data_dir(), threads=2)
    assert report["cases"] == 2 and report["runs"] == 6
    py_rows = rows_without_time(report["results_csv"])
    assert py_rows == rows_without_time(tmp_path / "cli" / "results.csv")
    assert len(py_rows) == 6
    assert report["summary"] is not None


def test_experiment_errors(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("source: a.txt\nno_such_key: 1\n")
    with pytest.raises(lmalign.ParseError) as info:
        lmalign.experiment(bad, tmp_path / "out", data_dir=tmp_path)
    assert info.value.file.endswith("bad.yaml")
