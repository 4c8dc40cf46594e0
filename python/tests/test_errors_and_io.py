"""Every wrong shape or dtype raises the documented error; library errors map to lmalign's
exceptions; map I/O gives float64 C-contiguous arrays and round-trips exactly."""
import numpy as np
import pytest

import lmalign

GOOD = np.random.default_rng(7).uniform(-1, 1, size=(50, 3))


def test_exception_hierarchy():
    assert issubclass(lmalign.InvalidArgument, ValueError)
    assert issubclass(lmalign.ParseError, ValueError)
    assert issubclass(lmalign.IoError, OSError)
    for e in (lmalign.InvalidArgument, lmalign.ParseError, lmalign.IoError):
        assert issubclass(e, lmalign.Error)


@pytest.mark.parametrize("argument", ["source", "target"])
@pytest.mark.parametrize("bad, expected", [
    (np.zeros((5, 2)), r"\(N, 3\).*\(5, 2\)"),
    (np.zeros((5, 3, 1)), r"\(N, 3\)"),
    (np.zeros(3), r"\(N, 3\)"),
    (np.zeros((4, 3), dtype=complex), "dtype complex128"),
    (np.zeros((4, 3), dtype=bool), "dtype bool"),
    (np.array([["a", "b", "c"]]), "dtype <U1"),
    (np.array([[object(), 1, 2]], dtype=object), "dtype object"),
])
def test_wrong_point_arrays_raise_value_error_naming_argument_and_shape(argument, bad,
                                                                        expected):
    args = {"source": GOOD, "target": GOOD}
    args[argument] = bad
    with pytest.raises(ValueError, match="^" + argument + ": .*" + expected):
        lmalign.align(args["source"], args["target"], strategy="base")


@pytest.mark.parametrize("keyword, bad, expected", [
    ("source_covariances", np.zeros((50, 3)), r"source_covariances: expected shape \(N, 3, 3\)"),
    ("source_covariances", np.zeros((49, 3, 3)), r"source_covariances: expected shape \(N, 3, 3\)"),
    ("target_covariances", np.zeros((50, 3, 3), dtype=complex), "target_covariances: .*complex"),
    ("target_weights", np.ones((50, 1)), r"target_weights: expected shape \(N,\)"),
    ("target_weights", np.ones(51), r"target_weights: expected shape \(N,\).*\(51,\)"),
    ("initial_guess", np.eye(3), r"initial_guess: expected shape \(4, 4\), got \(3, 3\)"),
    ("initial_guess", np.eye(4, dtype=complex), "initial_guess: .*complex"),
])
def test_wrong_optional_arrays_raise_value_error(keyword, bad, expected):
    with pytest.raises(ValueError, match=expected):
        lmalign.align(GOOD, GOOD, strategy="base", **{keyword: bad})


@pytest.mark.parametrize("call, expected", [
    (lambda: lmalign.transform_points(np.eye(4), np.zeros((3, 4))),
     r"^points: expected shape \(N, 3\), got \(3, 4\)"),
    (lambda: lmalign.transform_points(np.eye(4)[:3], GOOD), r"^T: expected shape \(4, 4\)"),
    (lambda: lmalign.transform_covariances(np.eye(4), np.zeros((2, 3))),
     r"^covariances: expected shape \(N, 3, 3\)"),
    (lambda: lmalign.align([[0, 0, 0], [1, 1]], GOOD),
     r"^source: expected an array of shape \(N, 3\), got an object numpy cannot convert"),
])
def test_wrong_arrays_of_the_helpers_raise_value_error(call, expected):
    with pytest.raises(ValueError, match=expected):
        call()


def test_non_rigid_initial_guess_is_invalid_argument():
    guess = np.eye(4)
    guess[0, 0] = 2.0
    with pytest.raises(lmalign.InvalidArgument, match="initial_guess: expected a rigid"):
        lmalign.align(GOOD, GOOD, initial_guess=guess)


def test_other_real_dtypes_and_layouts_are_converted_once():
    """float32, int and Fortran-ordered / strided inputs give the float64 result."""
    reference = lmalign.align(GOOD, GOOD + 0.01, strategy="base").T_target_source
    for source in (np.asfortranarray(GOOD), np.concatenate([GOOD, GOOD], axis=1)[:, :3],
                   GOOD.tolist()):
        r = lmalign.align(source, GOOD + 0.01, strategy="base")
        assert r.T_target_source.tolist() == reference.tolist()
    ints = (GOOD * 1000).astype(np.int32)
    r = lmalign.align(ints, ints.astype(np.float32) + 10, strategy="base")
    assert np.allclose(r.T_target_source[:3, 3], [10, 10, 10], atol=1e-6)


def test_library_errors_map_to_python_exceptions(tmp_path):
    with pytest.raises(lmalign.InvalidArgument, match="strategy"):
        lmalign.align(GOOD, GOOD, strategy="no_such_strategy")
    with pytest.raises(lmalign.InvalidArgument, match="unknown option"):
        lmalign.align(GOOD, GOOD, max_iteration=3)
    with pytest.raises(lmalign.InvalidArgument):
        lmalign.align(np.zeros((0, 3)), GOOD)
    nan = GOOD.copy()
    nan[3, 1] = np.nan
    with pytest.raises(lmalign.InvalidArgument):
        lmalign.align(nan, GOOD)
    with pytest.raises(lmalign.IoError, match="missing.txt"):
        lmalign.read_map(str(tmp_path / "missing.txt"))
    bad = tmp_path / "bad.txt"
    bad.write_text("# a map\nFRAME 0 0 0 0 1 0 0 0\nLANDMARK 1 0 0\n")
    with pytest.raises(lmalign.ParseError) as info:
        lmalign.read_map(str(bad))
    assert info.value.file == str(bad)
    assert info.value.line == 3
    assert info.value.detail and info.value.detail in str(info.value)


def test_map_arrays_and_exact_round_trip(desk_pair, tmp_path):
    m = lmalign.read_map(desk_pair[0])
    n = len(m)
    assert n > 100
    for array, shape, dtype in ((m.positions, (n, 3), np.float64),
                                (m.covariances, (n, 3, 3), np.float64),
                                (m.observation_counts, (n,), np.int64),
                                (m.landmark_ids, (n,), np.int64),
                                (m.frame_poses, (m.num_frames, 4, 4), np.float64)):
        assert array.shape == shape and array.dtype == dtype and array.flags.c_contiguous
    assert (m.observation_counts >= 2).all()  # read_map's default min_observations
    out = tmp_path / "copy.txt"
    lmalign.write_map(str(out), m)
    again = lmalign.read_map(str(out))
    assert again.positions.tolist() == m.positions.tolist()
    assert again.covariances.tolist() == m.covariances.tolist()
    assert again.observation_counts.tolist() == m.observation_counts.tolist()


def test_split_keeps_only_the_window(desk_pair):
    m = lmalign.read_map(desk_pair[0])
    ids = np.sort(m.frame_ids)
    first, last = int(ids[0]), int(ids[len(ids) // 2])
    mini = lmalign.split(m, first, last)
    assert 0 < len(mini) < len(m)
    assert set(mini.frame_ids.tolist()) == {i for i in m.frame_ids.tolist() if first <= i <= last}
    assert (mini.observation_counts >= 2).all()
    again, stats = lmalign.split(m, first, last, return_stats=True)
    assert again.positions.tolist() == mini.positions.tolist()
    assert stats["landmarks_kept"] == len(mini) and stats["frames_kept"] == mini.num_frames
    # Every landmark of the map is kept, outside the window, or dropped for too few observations.
    assert (stats["landmarks_kept"] + stats["landmarks_outside_window"]
            + stats["dropped_too_few_observations"]) == len(m)
    with pytest.raises(lmalign.InvalidArgument, match="first_frame_id"):
        lmalign.split(m, last, first)


def test_trajectory_evaluation_recovers_a_known_world_offset():
    """The estimate is the ground truth in another world frame: ATE after alignment is ~0 and
    T_gt_est is that frame change."""
    stamps = np.arange(40) * 0.1
    poses = np.stack([lmalign.pose_from_xyz_rpy_deg(np.sin(t), np.cos(t), 0.1 * t, 5 * t, 0, 20 * t)
                      for t in stamps])
    T_gt_est = lmalign.pose_from_xyz_rpy_deg(0.5, -0.2, 0.1, 0, 0, 30)
    est = np.linalg.inv(T_gt_est) @ poses
    d = lmalign.evaluate_trajectory((stamps, est), (stamps, poses))
    assert d["pairs"] == 40
    assert d["ate_translation_m"]["rmse"] < 1e-9
    assert np.abs(d["T_gt_est"] - T_gt_est).max() < 1e-9
    with pytest.raises(ValueError, match=r"estimate: expected shape \(N, 4, 4\)"):
        lmalign.evaluate_trajectory((stamps, est[:, :3]), (stamps, poses))


def test_tum_trajectory_file_round_trip_and_errors(tmp_path):
    """read_tum_trajectory: 'timestamp tx ty tz qx qy qz qw' (scalar last), sorted by time."""
    path = tmp_path / "traj.txt"
    # yaw 90 deg about z: q = (x y z w) = (0, 0, sin 45, cos 45); written out of time order.
    s = np.sqrt(0.5)
    path.write_text("# t tx ty tz qx qy qz qw\n"
                    "2.0 1 2 3 0 0 %.17g %.17g\n" % (s, s) +
                    "1.0 0 0 0 0 0 0 1\n"
                    "3.0 0 1 0 0 0 0 1\n")
    stamps, poses = lmalign.read_tum_trajectory(path)
    assert stamps.tolist() == [1.0, 2.0, 3.0]
    assert poses.shape == (3, 4, 4) and poses.dtype == np.float64
    expected = lmalign.pose_from_xyz_rpy_deg(1, 2, 3, 0, 0, 90)
    assert np.abs(poses[1] - expected).max() < 1e-12
    # The same trajectory from a file and from arrays evaluates the same.
    d = lmalign.evaluate_trajectory(path, (stamps, poses), align=False)
    assert d["pairs"] == 3 and d["ate_translation_m"]["max"] == 0.0
    bad = tmp_path / "bad.txt"
    bad.write_text("1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0\n")
    with pytest.raises(lmalign.ParseError) as info:
        lmalign.read_tum_trajectory(bad)
    assert info.value.line == 2
    with pytest.raises(lmalign.IoError):
        lmalign.evaluate_trajectory(tmp_path / "missing.txt", (stamps, poses))


def test_read_map_reads_other_formats_by_content(desk_pair, tmp_path):
    """The real Balbianello Bundler file reads by content (format 'auto') with its image size,
    with covariances re-estimated from its views; an unknown format name is refused."""
    from conftest import data_dir, require_file
    out = require_file(data_dir() / "bundler_balbianello" / "Balbianello.out")
    m = lmalign.read_map(out, min_observations=2, image_size=(640, 427))
    assert m.positions.shape[1] == 3 and 100 < m.positions.shape[0] <= 544
    assert len(m.frame_ids) == 5
    assert np.all(np.isfinite(m.covariances))
    assert m.scale == "arbitrary" and not m.covariance_assumed  # structure from motion
    # Without the image size (the file has none) the same landmarks and covariances; writing it
    # where pixels are stored from the top-left corner needs the size.
    u = lmalign.read_map(out, min_observations=2)
    assert np.array_equal(u.landmark_ids, m.landmark_ids)
    assert np.allclose(u.covariances, m.covariances, rtol=1e-6, atol=0)
    with pytest.raises(lmalign.InvalidArgument, match="image-size"):
        lmalign.write_map(tmp_path / "b.txt", u)
    assert lmalign.read_map(desk_pair[0]).scale == "metric"
    with pytest.raises(lmalign.InvalidArgument):
        lmalign.read_map(out, format="no-such-format")


def test_point_clouds_without_covariances_read_with_assumed_ones(desk_pair, tmp_path):
    """XYZ text (one point per line) reads with covariances assumed from the spacing and says so;
    the default aligns it and flags the assumption, base ICP does not weigh by covariance."""
    target = lmalign.read_map(desk_pair[1])
    xyz = tmp_path / "target.xyz"
    xyz.write_text("".join("%r %r %r\n" % tuple(p) for p in target.positions))
    cloud = lmalign.read_map(xyz)
    assert cloud.covariance_assumed and cloud.scale == "unknown"
    assert np.array_equal(cloud.positions, target.positions)
    cov = cloud.covariances
    assert np.all(cov[:, 0, 0] > 0) and np.all(cov[:, 0, 1] == 0)
    assert np.all(cov[:, 0, 0] == cov[:, 2, 2])  # isotropic
    r = lmalign.align(cloud, cloud, initial_guess=lmalign.pose_from_xyz_rpy_deg(0.05, 0, 0, 0, 0, 3))
    assert r.covariances_assumed and "covariances assumed" in r.trust_reason
    assert np.abs(r.T_target_source - np.eye(4)).max() < 1e-6
    b = lmalign.align(cloud, cloud, strategy="base")
    assert not b.covariances_assumed and b.trust_reason == "ok"
    bad = tmp_path / "bad.xyz"
    bad.write_text("1 2 3\n4 5\n")
    with pytest.raises(lmalign.ParseError) as info:
        lmalign.read_map(bad)
    assert info.value.line == 2


def test_map_formats_is_the_one_list_of_formats(tmp_path):
    """map_formats() is the registry: read_map accepts each name (and 'auto') and no other, its
    docstring and the unknown-name error list every one."""
    rows = lmalign.map_formats()
    names = [r["name"] for r in rows]
    assert names[0] == "lmalign" and "bundler" in names and "xyz" in names
    assert len(set(names)) == len(names) == 7
    assert sorted(r["name"] for r in rows if r["writes"]) == ["colmap-text", "lmalign", "ply"]
    for name in names:
        assert name in lmalign.read_map.__doc__
    missing = tmp_path / "missing.txt"
    for name in ["auto"] + names:
        with pytest.raises((lmalign.IoError, lmalign.ParseError, lmalign.InvalidArgument)) as info:
            lmalign.read_map(missing, format=name)
        assert "is not one of" not in str(info.value)
    with pytest.raises(lmalign.InvalidArgument) as info:
        lmalign.read_map(missing, format="fbx")
    for name in names:
        assert name in str(info.value)
    other = tmp_path / "other.txt"
    other.write_text("solid cube\n")
    with pytest.raises(lmalign.InvalidArgument) as info:
        lmalign.read_map(other)
    for r in rows:
        assert r["detected_by"] in str(info.value)
