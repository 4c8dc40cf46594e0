"""The merge's pairs on Dask (docs/merge.md, "Scale-out on Dask"): a LocalCluster of 2 worker
processes on loopback gives the in-process result bit for bit, also when a worker dies in the
middle of the run, and `lmalign merge --dask-scheduler` (the CLI handing over to Python) too; with
scale='free' on three real maps without metric scale, the same similarities as in process."""
import os
import pathlib
import subprocess

import distributed  # Debian's python3-distributed (Makefile DEB_PACKAGES): a failure if missing
import numpy as np
import pytest

import lmalign
from conftest import write_desk_windows, write_stella_manifest

pytestmark = pytest.mark.skipif(not lmalign.HAVE_MERGE,
                                reason="lmalign built without lmalign::merge (no Ceres)")

OUTPUTS = ("poses.yaml", "poses.json", "edges.csv", "summary.json", "merged_map.txt")


def local_cluster():
    return distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                    host="127.0.0.1", dashboard_address=None,
                                    worker_dashboard_address=None)


@pytest.fixture(scope="module")
def desk(tmp_path_factory):
    """(manifest, in-process MergeOutcome) of 3 real desk windows with 3 deg / 0.1 m priors
    (3 pairs: each untrusted prior edge of a merge this small gets the complete search, a few
    seconds, and the module merges 4 times)."""
    d = tmp_path_factory.mktemp("desk")
    manifest = write_desk_windows(d / "maps", count=3, prior_sigma=(3.0, 0.1))
    return manifest, lmalign.merge(manifest, d / "in_process", ground_truth="identity")


def assert_same_merge(run, reference):
    assert np.array_equal(run.T_world_map, reference.T_world_map)  # bit for bit
    assert np.array_equal(run.covariances, reference.covariances)
    assert np.array_equal(run.components, reference.components)
    assert run.edges == reference.edges
    assert np.array_equal(run.rejected, reference.rejected)
    assert run.final_chi2 == reference.final_chi2
    for name in OUTPUTS:
        a = pathlib.Path(run.output_dir) / name
        b = pathlib.Path(reference.output_dir) / name
        assert a.exists() == b.exists(), name
        if a.exists():
            assert a.read_bytes() == b.read_bytes(), name


def test_a_local_cluster_gives_the_in_process_result(desk, tmp_path):
    manifest, reference = desk
    with local_cluster() as cluster, distributed.Client(cluster) as client:
        run = lmalign.merge(manifest, tmp_path / "dask", ground_truth="identity",
                            dask_client=client)
        # Every pair ran as a task on the workers (the worker processes, not this one).
        assert run.backend == "dask" and len(run.edges) == 3
    assert_same_merge(run, reference)
    assert run.evaluation["max_translation_m"] == reference.evaluation["max_translation_m"]


class KillOnFirstEdge(distributed.WorkerPlugin):
    """Kills the worker process it runs in when an edge task starts executing there, once
    (the marker file makes the retry and the restarted worker survive)."""

    def __init__(self, marker):
        self.marker = marker

    def transition(self, key, start, finish, **kwargs):
        if (finish == "executing" and str(key).startswith("lmalign-edge-")
                and not os.path.exists(self.marker)):
            with open(self.marker, "w") as f:
                f.write("%s %d\n" % (key, os.getpid()))
            os._exit(17)


def test_a_worker_killed_mid_run_changes_nothing(desk, tmp_path):
    manifest, reference = desk
    marker = tmp_path / "killed"
    with local_cluster() as cluster, distributed.Client(cluster) as client:
        pids = set(client.run(os.getpid).values())
        client.register_worker_plugin(KillOnFirstEdge(str(marker)), name="kill-once")
        run = lmalign.merge(manifest, tmp_path / "dask", ground_truth="identity",
                            dask_client=client)
        killed_pid = int(marker.read_text().split()[1])
    assert killed_pid in pids  # a worker really died while running an edge task
    assert_same_merge(run, reference)


def test_the_cli_dask_scheduler_flag_gives_the_in_process_result(desk, cli, tmp_path):
    manifest, reference = desk
    out = tmp_path / "cli"
    with local_cluster() as cluster:
        done = subprocess.run([cli, "merge", str(manifest), "-o", str(out), "--dask-scheduler",
                               cluster.scheduler_address, "--ground-truth", "identity"],
                              capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "(dask)" in done.stdout, done.stdout
    for name in OUTPUTS:
        a, b = out / name, pathlib.Path(reference.output_dir) / name
        assert a.exists() == b.exists(), name
        if a.exists():
            assert a.read_bytes() == b.read_bytes(), name


@pytest.fixture(scope="module")
def stella_free(tmp_path_factory):
    """(manifest, truth, in-process MergeOutcome with scale='free') of the three real monocular
    stella_vslam maps (SOURCE.md's similarities as the truth)."""
    d = tmp_path_factory.mktemp("stella")
    manifest, truth = write_stella_manifest(d / "maps")
    return manifest, truth, lmalign.merge(manifest, d / "in_process", ground_truth=truth,
                                          scale="free")


def test_a_local_cluster_gives_the_in_process_similarities(stella_free, tmp_path):
    manifest, truth, reference = stella_free
    with local_cluster() as cluster, distributed.Client(cluster) as client:
        run = lmalign.merge(manifest, tmp_path / "dask", ground_truth=truth, dask_client=client,
                            scale="free")
        assert run.backend == "dask" and len(run.edges) == 3
    assert_same_merge(run, reference)
    assert np.array_equal(run.scales, reference.scales)
    # The similarities themselves: every edge estimated a scale, the scales match SOURCE.md.
    assert all(e.scale_free for e in run.edges)
    assert run.evaluation["max_pair_scale_error"] < 0.01
    assert run.evaluation["max_pair_scale_error"] == reference.evaluation["max_pair_scale_error"]


def test_the_cli_passes_scale_on_to_dask(stella_free, cli, tmp_path):
    manifest, truth, reference = stella_free
    out = tmp_path / "cli"
    with local_cluster() as cluster:
        done = subprocess.run([cli, "merge", str(manifest), "-o", str(out), "--dask-scheduler",
                               cluster.scheduler_address, "--scale", "free", "--ground-truth",
                               str(truth)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "(dask)" in done.stdout and "scale of 94eb7149" in done.stdout, done.stdout
    for name in OUTPUTS:
        a, b = out / name, pathlib.Path(reference.output_dir) / name
        assert a.exists() == b.exists(), name
        if a.exists():
            assert a.read_bytes() == b.read_bytes(), name
