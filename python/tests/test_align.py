"""lmalign.align(): equal to the CLI bit for bit on the real pair, recovers a known transform
from arrays, and releases the GIL."""
import json
import subprocess
import threading
import time

import numpy as np
import pytest

import lmalign


def run_cli(cli, args, tmp_path):
    out = tmp_path / "cli.json"
    subprocess.run([cli, "align", *map(str, args), "--json", str(out)], check=True,
                   stdout=subprocess.DEVNULL)
    return {r["strategy"]: r for r in json.loads(out.read_text())["results"]}


def assert_same_as_cli(result, cli_result):
    # Exact equality: nlohmann::json writes doubles in round-trip form.
    assert result.T_target_source.tolist() == cli_result["T_target_source"]
    assert result.converged == cli_result["converged"]
    assert result.termination == cli_result["termination"]
    assert result.iterations == cli_result["iterations"]
    assert result.num_correspondences == cli_result["num_correspondences"]
    assert result.initial_score_m2 == cli_result["initial_score_m2"]
    assert result.final_score_m2 == cli_result["final_score_m2"]
    assert result.trustworthy == cli_result["trustworthy"]
    assert result.trust_reason == cli_result["trust_reason"]
    assert result.inlier_fraction == cli_result.get("inlier_fraction")
    assert result.overlap_fraction == cli_result.get("overlap_fraction")
    assert result.mean_nis == cli_result.get("mean_nis")
    # The one serialisation: Python's to_json() is the CLI's entry, but for the CLI's own
    # ground-truth fields and the times.
    mine = json.loads(result.to_json())
    for key, value in mine.items():
        if key not in ("wall_time_s", "total_time_s"):
            assert cli_result[key] == value, key
    if cli_result["covariance_6x6"] is None:
        assert result.covariance is None
    else:
        assert result.covariance.reshape(-1).tolist() == cli_result["covariance_6x6"]


STRATEGIES = ["base", "observations", "robust_obs"]


def test_equals_cli_bit_for_bit_on_the_desk_pair(desk_pair, cli, tmp_path):
    source_path, target_path = desk_pair
    cli_results = run_cli(cli, [source_path, target_path, "--strategy", ",".join(STRATEGIES)],
                          tmp_path)
    source, target = lmalign.read_map(source_path), lmalign.read_map(target_path)
    for strategy in STRATEGIES:
        assert_same_as_cli(lmalign.align(source, target, strategy=strategy),
                           cli_results[strategy])


def test_equals_cli_with_displacement_and_options(desk_pair, cli, tmp_path):
    """The CLI's --displace, done in Python with transform_points / transform_covariances, on
    array inputs; and the limits (k, max_iterations, max_distance_m) passed as the CLI's."""
    source_path, target_path = desk_pair
    displace = [0, 1, 0.4, 10, 0, 22.5]
    cli_results = run_cli(cli, [source_path, target_path, "--strategy", "covariance,mutual",
                                "--displace", ",".join(map(str, displace)), "--k", 7,
                                "--max-iterations", 80, "--max-distance", 2.5], tmp_path)
    source, target = lmalign.read_map(source_path), lmalign.read_map(target_path)
    T = lmalign.pose_from_xyz_rpy_deg(*displace)
    moved = lmalign.transform_points(T, source.positions)
    moved_cov = lmalign.transform_covariances(T, source.covariances)
    for strategy in ("covariance", "mutual"):
        r = lmalign.align(moved, target, strategy=strategy, source_covariances=moved_cov, k=7,
                          max_iterations=80, max_distance_m=2.5)
        assert_same_as_cli(r, cli_results[strategy])


def test_equals_cli_with_settings(desk_pair, cli, tmp_path):
    """settings= is the CLI's --set: typed values here, text there, the same result."""
    source_path, target_path = desk_pair
    cli_results = run_cli(cli, [source_path, target_path, "--strategy", "adaptive",
                                "--set", "score.samples=512", "--set", "init.yaw_step_deg=4",
                                "--set", "estimate.half_sample_planes=0"], tmp_path)
    source, target = lmalign.read_map(source_path), lmalign.read_map(target_path)
    r = lmalign.align(source, target, strategy="adaptive",
                      settings={"score.samples": 512, "init.yaw_step_deg": 4,
                                "estimate.half_sample_planes": "0"})
    assert_same_as_cli(r, cli_results["adaptive"])
    assert json.loads(r.to_json())["settings"]["score.samples"] == "512"


def test_settings_are_checked_and_listed():
    target = random_scene(seed=6)
    source = target + [0.01, 0.0, 0.0]
    with pytest.raises(lmalign.InvalidArgument,
                       match=r"unknown setting 'schedule.max_iteration' \(nearest: "
                             r"'schedule.max_iterations'\)"):
        lmalign.align(source, target, strategy="base",
                      settings={"schedule.max_iteration": 3})
    with pytest.raises(lmalign.InvalidArgument,
                       match=r"schedule.max_iterations = 0 is outside its bound \[1, "):
        lmalign.align(source, target, strategy="base", settings={"schedule.max_iterations": 0})
    r = lmalign.align(source, target, strategy="base", settings={"schedule.max_iterations": 1})
    assert r.iterations == 1 and r.termination == "max_iterations"
    rows = {row["key"]: row for row in lmalign.options("robust_obs")}
    assert rows["schedule.max_iterations"]["value"] == "300"
    assert rows["schedule.max_iterations"]["unit"] == "count"
    assert rows["kernel.confidence"]["value"] == "observations"
    assert set(lmalign.strategies()) >= {"base", "robust_obs", lmalign.RECOMMENDED_STRATEGY}
    assert "usable: yes" in r.full_report() and r.usable


def random_scene(n=400, seed=3):
    rng = np.random.default_rng(seed)
    return rng.uniform(-2.0, 2.0, size=(n, 3))


@pytest.mark.parametrize("strategy, weights", [("base", None), ("mutual", None),
                                               ("robust_obs", "ones")])
def test_two_arrays_recover_a_known_transform(strategy, weights):
    target = random_scene()
    T_true = lmalign.pose_from_xyz_rpy_deg(0.08, -0.05, 0.03, 3.0, -2.0, 6.0)
    # p_target = T_true p_source  =>  p_source = T_true^-1 p_target
    source = lmalign.transform_points(np.linalg.inv(T_true), target)
    target_weights = np.ones(len(target)) if weights == "ones" else None
    r = lmalign.align(source, target, strategy=strategy, target_weights=target_weights)
    assert r.converged
    assert np.abs(r.T_target_source - T_true).max() < 1e-9
    assert r.final_score_m2 < 1e-20
    assert r.trustworthy, r.trust_reason
    assert r.T_target_source.dtype == np.float64 and r.T_target_source.shape == (4, 4)


def test_initial_guess_is_used():
    """From a guess that is the truth itself, the run stops at once with a zero score."""
    target = random_scene(seed=4)
    T_true = lmalign.pose_from_xyz_rpy_deg(1.0, 2.0, -0.5, 30.0, 10.0, 120.0)  # far: no basin
    source = lmalign.transform_points(np.linalg.inv(T_true), target)
    r = lmalign.align(source, target, strategy="base", initial_guess=T_true)
    assert r.initial_score_m2 < 1e-20
    assert np.abs(r.T_target_source - T_true).max() < 1e-9


def test_weighted_strategy_with_array_target_uses_target_weights():
    target = random_scene(seed=5)
    source = target + [0.02, 0.0, 0.0]
    with pytest.raises(lmalign.InvalidArgument, match="target_weights"):
        lmalign.align(source, target, strategy="observations")  # no weights for bare points
    r = lmalign.align(source, target, strategy="observations",
                      target_weights=np.ones(len(target)))
    assert np.allclose(r.T_target_source[:3, 3], [-0.02, 0, 0], atol=1e-9)


def test_threads_do_not_change_the_result(desk_pair):
    source, target = (lmalign.read_map(p) for p in desk_pair)
    one = lmalign.align(source, target, strategy="covariance", threads=1)
    two = lmalign.align(source, target, strategy="covariance", threads=2)
    assert one.T_target_source.tolist() == two.T_target_source.tolist()


def test_gil_is_released_two_alignments_overlap_in_time(desk_pair):
    """Two alignments started together on two Python threads run at the same time.

    Each result carries the interval of its alignment, [started_s, finished_s], taken inside the
    C++ call on the clock of time.monotonic(). Were the GIL held during the alignment, the
    second could only begin after the first had returned: the intervals would be disjoint.
    Released, they overlap (even on one core: the OS interleaves the two threads). Checked:
    with the release removed from the binding, this test fails.
    """
    source, target = (lmalign.read_map(p) for p in desk_pair)
    # A far start (the paper's Table 1 pose): each alignment lasts tens of milliseconds.
    T = lmalign.pose_from_xyz_rpy_deg(0, 1, 0.4, 10, 0, 22.5)
    source_far = lmalign.transform_points(T, source.positions)
    results = [None, None]
    barrier = threading.Barrier(2)

    def work(i):
        barrier.wait()
        before = time.monotonic()
        results[i] = lmalign.align(source_far, target, strategy="robust_obs", threads=1)
        assert before <= results[i].started_s <= results[i].finished_s <= time.monotonic()

    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    (a0, a1), (b0, b1) = ((r.started_s, r.finished_s) for r in results)
    assert a1 - a0 >= results[0].wall_time_s and b1 - b0 >= results[1].wall_time_s
    overlap = min(a1, b1) - max(a0, b0)
    assert overlap > 0, ((a0, a1), (b0, b1))


def test_adaptive_reports_its_verdict_as_the_cli_does(desk_pair, cli, tmp_path):
    """The default's verdict: covariance scale, ambiguity and the rival pose it measured, the same
    in Python as in the CLI's JSON. On the desk pair a distinct pose (the desk turned about its
    normal) scores most of the best, so there is a rival."""
    source_path, target_path = desk_pair
    cli_result = run_cli(cli, [source_path, target_path, "--strategy", "adaptive"],
                         tmp_path)["adaptive"]
    r = lmalign.align(lmalign.read_map(source_path), lmalign.read_map(target_path),
                      strategy="adaptive")
    assert r.T_target_source.tolist() == cli_result["T_target_source"]
    assert r.covariance_scale == cli_result["covariance_scale"]
    assert r.ambiguity == cli_result["ambiguity"]
    assert r.alias_waived_by_prior is False  # no prior: nothing waived
    assert cli_result["alias_waived_by_prior"] is False
    assert 0.0 < r.covariance_scale < 3.0
    assert r.rival_T_target_source is not None
    assert r.rival_T_target_source.tolist() == cli_result["rival"]["T_target_source"]
    # The rival is a distinct pose: it moves the source by more than the estimate's uncertainty.
    assert cli_result["rival"]["distance_m"] > 0.05 or cli_result["rival"]["angle_deg"] > 5.0
    assert r.T_target_source.shape == r.rival_T_target_source.shape == (4, 4)


@pytest.mark.parametrize("strategy", ["base", "adaptive"])
def test_free_scale_recovers_a_similarity_from_arrays(strategy):
    """scale='free': the target is the source moved by a similarity of scale 0.37."""
    source = random_scene(seed=7)
    T = lmalign.pose_from_xyz_rpy_deg(0.02, -0.01, 0.01, 1.0, -1.0, 3.0)
    S = T.copy()
    S[:3, :3] *= 0.37
    target = source @ S[:3, :3].T + S[:3, 3]
    r = lmalign.align(source, target, strategy=strategy, scale="free",
                      source_covariances=np.tile(1e-6 * np.eye(3), (len(source), 1, 1)),
                      target_covariances=np.tile(0.37**2 * 1e-6 * np.eye(3), (len(target), 1, 1)))
    assert r.scale_mode == "free"
    assert abs(r.scale / 0.37 - 1.0) < 0.01
    assert r.scale_sd is not None and r.scale_sd > 0.0
    assert np.abs(r.S_target_source - S).max() < 1e-3
    assert np.allclose(r.S_target_source[:3, :3], r.scale * r.T_target_source[:3, :3])
    fixed = lmalign.align(source, target, strategy=strategy, scale="fixed",
                          source_covariances=np.tile(1e-6 * np.eye(3), (len(source), 1, 1)),
                          target_covariances=np.tile(1e-6 * np.eye(3), (len(target), 1, 1)))
    assert fixed.scale == 1.0 and fixed.scale_sd is None and fixed.scale_mode == "fixed"
    with pytest.raises(lmalign.InvalidArgument, match=r"unknown scale mode 'metric' \(known: auto, free, fixed\)"):
        lmalign.align(source, target, strategy=strategy, scale="metric")


def test_auto_scale_follows_the_maps_headers(desk_pair, tmp_path):
    """scale='auto' (the default): free when either Map's header says its scale is not metric,
    fixed for metric Maps and for arrays (no header)."""
    with open(desk_pair[0]) as f:
        text = f.read()
    marked = tmp_path / "arbitrary.txt"
    marked.write_text("MAP scale arbitrary\n" + text)
    metric = lmalign.read_map(str(desk_pair[0]))
    arbitrary = lmalign.read_map(str(marked))
    assert metric.scale == "metric" and arbitrary.scale == "arbitrary"
    free = lmalign.align(arbitrary, metric, strategy="base")
    assert free.scale_mode == "free"
    assert abs(free.scale - 1.0) < 1e-3  # the same landmarks on both sides
    assert lmalign.align(metric, metric, strategy="base").scale_mode == "fixed"
    assert lmalign.align(arbitrary.positions, metric.positions, strategy="base").scale_mode == \
        "fixed"
    assert lmalign.align(arbitrary, metric, strategy="base", scale="fixed").scale_mode == "fixed"
