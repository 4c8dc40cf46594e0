"""The Python package writes through lmalign's one output writer (docs/robustness.md,
"Outputs"): a FIFO, a device and a symlink stay what they were, '-' is the standard output, a
missing directory is an IoError naming it; experiment(plots=True) draws with the script
shipped inside the package."""
import os
import stat
import subprocess
import threading

import pytest

import lmalign
from conftest import data_dir


@pytest.fixture
def pair(cli, tmp_path):
    """A small simulated pair (source.txt, target.txt; lmalign simulate)."""
    subprocess.run([cli, "simulate", "--scene", "road", "--landmarks", "60", "-o",
                    str(tmp_path / "sim")], check=True, stdout=subprocess.DEVNULL)
    return tmp_path / "sim" / "source.txt", tmp_path / "sim" / "target.txt"


@pytest.fixture
def small_map(pair):
    return lmalign.read_map(pair[1], min_observations=0)


def test_a_fifo_gets_the_map_in_place_and_stays_a_fifo(tmp_path, small_map):
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    received = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_text()))
    reader.start()
    lmalign.write_map(fifo, small_map)
    reader.join()
    assert received[0].count("LANDMARK") == len(small_map)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_a_symlink_is_written_through_and_stays_a_link(tmp_path, small_map):
    (tmp_path / "real.txt").write_text("old\n")
    (tmp_path / "link.txt").symlink_to("real.txt")
    lmalign.write_map(tmp_path / "link.txt", small_map)
    assert (tmp_path / "link.txt").is_symlink()
    assert len(lmalign.read_map(tmp_path / "real.txt", min_observations=0)) == len(small_map)


def test_dash_is_the_standard_output(capfd, small_map):
    lmalign.write_map("-", small_map)
    out = capfd.readouterr().out
    assert out.count("LANDMARK") == len(small_map)


def test_a_missing_directory_is_an_io_error_naming_it(tmp_path, small_map):
    target = tmp_path / "no" / "such" / "x.txt"
    with pytest.raises(lmalign.IoError, match="the directory '%s' does not exist"
                       % str(tmp_path / "no" / "such")):
        lmalign.write_map(target, small_map)
    assert not (tmp_path / "no").exists()


@pytest.mark.skipif(os.geteuid() != 0, reason="mknod needs root")
def test_a_copy_of_dev_full_stays_a_device_and_the_write_is_an_io_error(tmp_path, small_map):
    full = tmp_path / "full"
    os.mknod(full, stat.S_IFCHR | 0o666, os.makedev(1, 7))
    with pytest.raises(lmalign.IoError, match="No space left on device"):
        lmalign.write_map(full, small_map)
    assert stat.S_ISCHR(os.lstat(full).st_mode)


def test_experiment_plots_with_the_packaged_script(tmp_path, pair):
    pytest.importorskip("matplotlib")
    source, target = pair
    config = tmp_path / "c.yaml"
    config.write_text("source: %s\ntarget: %s\nground_truth: identity\nstrategies: [base]\n"
                      "experiments:\n  - name: yaw\n    type: yaw\n    yaw_deg: [0, 10]\n"
                      % (source, target))
    # A plot that is a symlink stays one: the PNG lands in its target.
    plots = tmp_path / "out" / "plots"
    plots.mkdir(parents=True)
    (plots / "yaw_violin.png").symlink_to(tmp_path / "kept.png")
    report = lmalign.experiment(config, tmp_path / "out", data_dir=data_dir(), plots=True)
    names = sorted(os.path.basename(p) for p in report["plots"])
    assert "yaw_violin.png" in names, names
    assert (plots / "yaw_violin.png").is_symlink()
    assert (tmp_path / "kept.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for p in report["plots"]:
        with open(p, "rb") as f:
            assert f.read(8) == b"\x89PNG\r\n\x1a\n"
    assert not [n for n in os.listdir(plots) if n.startswith(".lmalign-plots")]
