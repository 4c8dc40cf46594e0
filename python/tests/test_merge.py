"""The merge from Python (lmalign.merge and its pure steps) on real desk windows: equal to the
CLI's `lmalign merge` file for file, equal to the composition of its steps, resumable, checked
against the truth. Dask: test_merge_dask.py."""
import json
import pickle
import subprocess

import numpy as np
import pytest

import lmalign
from conftest import write_desk_windows

pytestmark = pytest.mark.skipif(not lmalign.HAVE_MERGE,
                                reason="lmalign built without lmalign::merge (no Ceres)")

OUTPUTS = ("poses.yaml", "poses.json", "edges.csv", "summary.json", "overlap_check.csv",
           "merged_map.txt")


@pytest.fixture(scope="module")
def desk(tmp_path_factory):
    """(manifest, in-process MergeOutcome) of 3 real desk windows with 3 deg / 0.1 m priors
    (each untrusted prior edge of a merge this small gets the complete search: a few seconds)."""
    d = tmp_path_factory.mktemp("desk")
    manifest = write_desk_windows(d / "maps", count=3, prior_sigma=(3.0, 0.1))
    return manifest, lmalign.merge(manifest, d / "out", ground_truth="identity", threads=2)


def outputs_of(directory):
    return {name: (directory / name).read_bytes() for name in OUTPUTS
            if (directory / name).exists()}


def test_python_merge_equals_the_cli_file_for_file(desk, cli, tmp_path):
    manifest, run = desk
    done = subprocess.run([cli, "merge", str(manifest), "-o", str(tmp_path / "cli"),
                           "--ground-truth", "identity", "--threads", "2"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    cli_files = outputs_of(tmp_path / "cli")
    py_files = outputs_of(__import__("pathlib").Path(run.output_dir))
    assert set(cli_files) >= {"poses.json", "edges.csv", "summary.json"}
    assert cli_files == py_files
    poses = json.loads(cli_files["poses.json"])["maps"]
    assert np.array_equal(np.array([p["T_world_map"] for p in poses]), run.T_world_map)
    assert f"merged {len(run.names)} maps: {len(run.edges)} candidate pairs" in done.stdout


def test_the_pure_steps_compose_to_the_same_merge(desk):
    manifest_path, run = desk
    manifest = lmalign.read_manifest(manifest_path)
    assert manifest.names == ["w0", "w1", "w2"] and manifest.priors[0] is not None
    maps = lmalign.load_manifest_maps(manifest)
    pairs = lmalign.plan_candidates(maps, manifest.priors)
    assert [(p.source, p.target) for p in pairs] == [(c.source, c.target) for c in run.candidates]
    fp = [lmalign.map_fingerprint(m) for m in maps]
    edges = [lmalign.align_edge(maps[p.source], maps[p.target], p).with_key(
        lmalign.edge_key(fp[p.source], fp[p.target], p)) for p in pairs]
    assert edges == run.edges  # bit for bit, keys included
    # An Edge survives pickling (what a Dask worker sends back) bit for bit.
    assert pickle.loads(pickle.dumps(edges)) == edges
    assert [(p.source, p.target, p.prior_sigma, p.prior_complete_search)
            for p in pickle.loads(pickle.dumps(pairs))] == \
        [(p.source, p.target, p.prior_sigma, p.prior_complete_search) for p in pairs]
    # Three maps: an untrusted prior edge is rescued by the complete search too (issue 37).
    assert {p.prior_complete_search for p in pairs} == {"rescue"}
    graph = lmalign.solve_pose_graph(len(maps), manifest.priors, edges)
    assert np.array_equal(np.array([p.T_world_map for p in graph.maps]), run.T_world_map)
    assert graph.final_chi2 == run.final_chi2
    # The merged real windows agree with themselves (docs/merge.md, "Maps the graph puts on top
    # of each other"): every pair judged, none contradicted, as overlap_check.csv says.
    check = lmalign.check_overlaps(maps, graph, edges)
    assert check.reference_agreement > 0 and check.num_contradicted() == 0
    rows = (__import__("pathlib").Path(run.output_dir) / "overlap_check.csv").read_text()
    assert len(rows.splitlines()) == 1 + len(check.pairs) and len(check.pairs) >= 2


def test_retrieval_verifies_its_pairs_geometrically(desk):
    # Beyond all_pairs_max_maps maps without priors the pairs are retrieved, and each map's
    # shortlist verified by the correspondence search (docs/merge.md, "Candidates"): the desk
    # windows overlap, so each kept pair shares a clique; without verification none is counted.
    manifest_path, _ = desk
    maps = lmalign.load_manifest_maps(lmalign.read_manifest(manifest_path))
    pairs = lmalign.plan_candidates(maps, all_pairs_max_maps=2, keep_per_map=1, verify_per_map=2)
    assert pairs and all(p.verified_matches >= 5 for p in pairs)
    assert [(p.source, p.target, p.verified_matches, p.rank, p.complete_search)
            for p in pickle.loads(pickle.dumps(pairs))] == \
        [(p.source, p.target, p.verified_matches, p.rank, p.complete_search) for p in pairs]
    # A fleet's pairs without priors: the complete search only checks (docs/merge.md, "Pairs
    # without priors"); every pair of a small merge gets it in full.
    assert {p.complete_search for p in pairs} == {"check"}
    assert {p.complete_search for p in lmalign.plan_candidates(maps)} == {"rescue"}
    words = lmalign.plan_candidates(maps, all_pairs_max_maps=2, keep_per_map=1, verify_per_map=0)
    assert all(p.verified_matches == 0 for p in words)


def test_the_merge_places_every_window_at_its_truth(desk):
    _, run = desk
    ev = run.evaluation
    assert run.T_world_map.shape == (3, 4, 4) and run.covariances.shape == (3, 6, 6)
    assert run.T_world_map.dtype == np.float64 and run.T_world_map.flags.c_contiguous
    assert run.num_components == 1 and run.used.sum() >= 1  # priors hold it together
    # The windows were never moved: truth = identity (docs/merge.md, the desk target).
    assert ev["max_rotation_deg"] < 2.0 and ev["max_translation_m"] < 0.05, ev  # issue 21
    assert ev["false_kept_edges"] == 0, ev


def test_resume_reuses_every_edge_and_a_rerun_without_it_is_refused(desk, tmp_path):
    manifest, run = desk
    with pytest.raises(lmalign.InvalidArgument, match="resume"):
        lmalign.merge(manifest, run.output_dir)
    again = lmalign.merge(manifest, run.output_dir, resume=True)
    assert again.edges_reused == len(run.edges)
    assert np.array_equal(again.T_world_map, run.T_world_map)


def test_overlap_check_off_and_check_alone(desk, tmp_path):
    # overlap_check (as `lmalign merge --overlap-check`): 'off' runs no check and writes no
    # overlap_check.csv; 'check' checks without repairing; the desk windows agree, so the poses
    # are the default's either way. The edges are reused from the fixture's run.
    import pathlib
    import shutil
    manifest, run = desk
    for mode in ("off", "check"):
        out = tmp_path / mode
        shutil.copytree(pathlib.Path(run.output_dir) / "edges", out / "edges")
        again = lmalign.merge(manifest, out, resume=True, overlap_check=mode)
        assert again.edges_reused == len(run.edges)
        assert np.array_equal(again.T_world_map, run.T_world_map)
        summary = json.loads((out / "summary.json").read_text())
        assert (out / "overlap_check.csv").exists() == (mode == "check")
        assert (summary["overlap_check"] is None) == (mode == "off")
    with pytest.raises(lmalign.InvalidArgument, match="overlap_check"):
        lmalign.merge(manifest, tmp_path / "bad", overlap_check="sometimes")
    with pytest.raises(lmalign.InvalidArgument, match="overlap_check"):
        lmalign.solve_pose_graph(1, None, [], overlap_check="sometimes")


def test_bad_merge_arguments_raise_the_documented_errors(tmp_path):
    empty = tmp_path / "empty.yaml"
    empty.write_text("maps: []\n")
    with pytest.raises(lmalign.ParseError) as e:
        lmalign.read_manifest(empty)
    assert e.value.file == str(empty)
    with pytest.raises(lmalign.InvalidArgument, match="covariance"):
        lmalign.MapPrior(np.eye(4), -np.eye(6))
    with pytest.raises(ValueError, match=r"\(6, 6\)"):
        lmalign.MapPrior(np.eye(4), np.eye(5))
    with pytest.raises(lmalign.InvalidArgument, match="prior_sigma"):
        lmalign.CandidatePair(0, 1, np.eye(4), (0.0, 1.0))
    with pytest.raises(lmalign.InvalidArgument, match="max_pairs"):
        lmalign.merge(empty, tmp_path / "out", max_pairs=-1)
