"""lmalign.merge(scale=...) (docs/merge.md, "Maps without metric scale"): on the three real
monocular stella_vslam maps of one video (each of its own arbitrary scale), 'auto' aligns every
pair as a similarity and recovers SOURCE.md's scales, 'fixed' keeps every edge and pose rigid,
and a bad value is refused in one line naming the option. The Dask path's scale results are in
test_merge_dask.py."""
import subprocess
import sys

import numpy as np
import pytest

import lmalign
from conftest import write_stella_manifest

pytestmark = pytest.mark.skipif(not lmalign.HAVE_MERGE,
                                reason="lmalign built without lmalign::merge (no Ceres)")


@pytest.fixture(scope="module")
def stella(tmp_path_factory):
    """(manifest, truth) of the three stella_vslam maps (SOURCE.md's similarities)."""
    return write_stella_manifest(tmp_path_factory.mktemp("stella"))


def test_auto_estimates_each_maps_scale_against_source_md(stella, tmp_path):
    manifest, truth = stella
    maps = lmalign.load_manifest_maps(lmalign.read_manifest(manifest))
    assert all(m.scale != "metric" for m in maps)  # monocular: arbitrary scale
    run = lmalign.merge(manifest, tmp_path / "auto", ground_truth=truth, threads=2)
    assert len(run.edges) == 3
    assert all(e.scale_free and e.trusted for e in run.edges), [e.trust_reason for e in run.edges]
    assert run.num_components == 1
    ev = run.evaluation
    # SOURCE.md: 356a5a6e -> 4683e8ac 0.79165, 94eb7149 -> 4683e8ac 1.06574, so the estimated
    # scales differ from 1 by 20% and 7%, and their ratios match SOURCE.md's within 1%.
    assert ev["max_pair_scale_error"] < 0.01, ev["max_pair_scale_error"]
    assert ev["max_rotation_deg"] < 1.0
    assert np.all(ev["within"])
    s = dict(zip(run.names, run.scales))
    assert abs((s["356a5a6e"] / s["4683e8ac"]) / 0.79165 - 1) < 0.01, s
    assert abs((s["94eb7149"] / s["4683e8ac"]) / 1.06574 - 1) < 0.01, s
    assert all(p.scale_free for p in run.graph.maps if not p.is_gauge)


def test_fixed_keeps_every_edge_and_pose_rigid(stella, tmp_path):
    manifest, truth = stella
    run = lmalign.merge(manifest, tmp_path / "fixed", ground_truth=truth, threads=2,
                        scale="fixed")
    assert len(run.edges) == 3
    for e in run.edges:
        assert not e.scale_free and e.scale == 1.0 and np.isnan(e.scale_sd)
    assert np.array_equal(run.scales, np.ones(3))
    assert not any(p.scale_free for p in run.graph.maps)
    # The edge key depends on the mode: these edges are not those of 'auto'.
    pair = run.candidates[0]
    fp = lmalign.map_fingerprint(lmalign.load_manifest_maps(lmalign.read_manifest(manifest))[0])
    assert (lmalign.edge_key(fp, fp, pair, scale="fixed")
            != lmalign.edge_key(fp, fp, pair, scale="auto"))


def test_a_bad_scale_is_one_line_naming_the_option(stella, tmp_path):
    manifest, _ = stella
    with pytest.raises(lmalign.InvalidArgument) as e:
        lmalign.merge(manifest, tmp_path / "bad", scale="similarity")
    message = str(e.value)
    assert "\n" not in message
    assert message.startswith("scale: ") and "'auto', 'free' or 'fixed'" in message, message
    assert not (tmp_path / "bad").exists()  # refused before anything is read or written
    maps = lmalign.load_manifest_maps(lmalign.read_manifest(manifest))
    pair = lmalign.CandidatePair(0, 1)
    for call in (lambda: lmalign.align_edge(maps[0], maps[1], pair, scale="Fixed"),
                 lambda: lmalign.edge_key("0", "1", pair, scale=""),
                 lambda: lmalign.solve_pose_graph(3, None, [], maps=maps, scale="rigid")):
        with pytest.raises(lmalign.InvalidArgument, match=r"^scale: expected 'auto', 'free' or"):
            call()
    # The CLI's hand-over to Python (lmalign merge --dask-scheduler) refuses it too.
    done = subprocess.run([sys.executable, "-m", "lmalign.merge_cli", str(manifest), "-o",
                           str(tmp_path / "cli"), "--scale", "rigid"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "--scale" in done.stderr, done.stderr
