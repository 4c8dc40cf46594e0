"""lmalign.merge(): merge mini-maps in process (C++ / OpenMP) or with the pairs on Dask.

docs/merge.md ("Scale-out on Dask") and docs/python.md. Only present when the compiled module
has the merge (lmalign.HAVE_MERGE: lmalign::merge is built when Ceres is found).
"""

import os
import time

import numpy as np

from . import _lmalign as _c


class MergeOutcome:
    """What lmalign.merge() returns (the outputs are also written to output_dir).

    Per map (N maps, manifest order): names (list of str), T_world_map (N, 4, 4) float64
    (p_world = T @ p_map, metres; the world of the map's component), covariances (N, 6, 6)
    float64 (marginal, xi = (rho m, phi rad), left perturbation in the world frame; zero for a
    gauge map), scales (N,) float64 (world units per map unit: p_world = scale * R @ p_map + t
    with (R, t) = T_world_map; 1 for a map with metric scale or with scale='fixed'), components (N,) int64 (0-based; parts never forced together), is_gauge (N,) bool.
    Per candidate edge (E, candidate order): candidates (list of CandidatePair), edges (list of
    Edge: T_target_source, covariance, trusted, ...), trusted, used, rejected (E,) bool, chi2 (E,)
    float64 (whitened, 0 if unused). Graph: num_components, final_chi2, edge_covariance_scale,
    graph (the PoseGraphResult). evaluation: evaluate_merge()'s dict with ground truth, else None.
    Run: backend ('in-process' or 'dask'), edges_reused (from output_dir/edges with resume),
    seconds_edges, seconds_graph, output_dir.
    """

    def __init__(self, names, candidates, edges, graph, evaluation, backend, edges_reused,
                 seconds_edges, seconds_graph, output_dir):
        self.names = list(names)
        self.candidates = list(candidates)
        self.edges = list(edges)
        self.graph = graph
        self.T_world_map = np.array([p.T_world_map for p in graph.maps]).reshape(-1, 4, 4)
        self.covariances = np.array([p.covariance for p in graph.maps]).reshape(-1, 6, 6)
        self.scales = np.array([p.scale for p in graph.maps], dtype=np.float64)
        self.components = np.array([p.component for p in graph.maps], dtype=np.int64)
        self.is_gauge = np.array([p.is_gauge for p in graph.maps], dtype=bool)
        self.trusted = np.array([e.trusted for e in self.edges], dtype=bool)
        self.used = np.array([r.used for r in graph.edges], dtype=bool)
        self.rejected = np.array([r.rejected for r in graph.edges], dtype=bool)
        self.chi2 = np.array([r.chi2 for r in graph.edges], dtype=np.float64)
        self.num_components = graph.num_components
        self.final_chi2 = graph.final_chi2
        self.edge_covariance_scale = graph.edge_covariance_scale
        self.evaluation = evaluation
        self.backend = backend
        self.edges_reused = edges_reused
        self.seconds_edges = seconds_edges
        self.seconds_graph = seconds_graph
        self.output_dir = output_dir

    def __repr__(self):
        return ("<lmalign.MergeOutcome %d maps, %d candidate pairs, %d trusted, %d used, "
                "%d rejected, %d component(s), final chi2 %.3f (%s)>"
                % (len(self.names), len(self.edges), self.trusted.sum(), self.used.sum(),
                   self.rejected.sum(), self.num_components, self.final_chi2, self.backend))


# ------------------------------------------------------------------ the Dask task

_WORKER_MAPS = {}


def _worker_map(entry):
    """The map of a manifest entry, read once per worker process (keyed by path and mtime)."""
    st = os.stat(entry.path)
    key = (entry.path, entry.format, st.st_mtime_ns, st.st_size)
    m = _WORKER_MAPS.get(key)
    if m is None:
        if len(_WORKER_MAPS) >= 64:
            _WORKER_MAPS.clear()
        m = _WORKER_MAPS[key] = _c.read_manifest_map(entry)
    return m


def align_edge_task(source_entry, target_entry, pair, fingerprints, key, max_iterations=None,
                    scale="auto"):
    """One Dask task: reads the pair's two maps by path (a shared filesystem), checks that they
    are the maps the client planned with (fingerprints), aligns them (align_edge, with the
    merge's scale mode: 'auto', 'free' or 'fixed') and returns the Edge (picklable, bit for bit)
    with its resume key. Raises InvalidArgument if a map differs from the client's (e.g. a stale
    copy on the worker's filesystem)."""
    source = _worker_map(source_entry)
    target = _worker_map(target_entry)
    for entry, m, fp in ((source_entry, source, fingerprints[0]),
                         (target_entry, target, fingerprints[1])):
        if _c.map_fingerprint(m) != fp:
            raise _c.InvalidArgument(
                "map '%s' (%s) on this worker differs from the client's (fingerprint %s, "
                "expected %s): the maps must be on a filesystem shared by every worker"
                % (entry.name, entry.path, _c.map_fingerprint(m), fp))
    return _c.align_edge(source, target, pair, max_iterations, scale=scale).with_key(key)


# ------------------------------------------------------------------ the merge


def _check_output_dir(out_dir, resume):
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise _c.InvalidArgument("output_dir %s: exists and is not a folder" % out_dir)
    edges_dir = os.path.join(out_dir, "edges")
    if not resume and os.path.isdir(edges_dir) and os.listdir(edges_dir):
        raise _c.InvalidArgument("output_dir %s: holds edges/ of an earlier run; pass resume=True "
                                 "to reuse them, or choose another folder" % out_dir)
    os.makedirs(edges_dir, exist_ok=True)
    return edges_dir


def _dask_edges(client, manifest, maps, candidates, edges_dir, max_iterations, scale):
    """Edges of `candidates` on the Dask cluster of `client`, in candidate order; cached edges
    (same key) are reused, every new edge is written to edges_dir as it arrives."""
    from distributed import as_completed

    names = manifest.names
    fingerprints = [_c.map_fingerprint(m) for m in maps]
    slots = [None] * len(candidates)
    futures = {}
    reused = 0
    for k, c in enumerate(candidates):
        key = _c.edge_key(fingerprints[c.source], fingerprints[c.target], c, max_iterations,
                          scale=scale)
        path = _c.edge_file_path(edges_dir, names[c.source], names[c.target])
        cached = _c.read_edge_file(path)
        if (cached is not None and cached.key == key and cached.source == c.source
                and cached.target == c.target):
            slots[k] = cached
            reused += 1
            continue
        future = client.submit(
            align_edge_task, manifest.maps[c.source], manifest.maps[c.target], c,
            (fingerprints[c.source], fingerprints[c.target]), key, max_iterations, scale,
            key="lmalign-edge-%s-%d-%d" % (key, c.source, c.target), pure=False)
        futures[future] = (k, path)
    for future in as_completed(list(futures)):
        k, path = futures[future]
        edge = future.result()
        _c.write_edge_file(path, edge)
        slots[k] = edge
    return slots, reused


def merge(manifest_path, output_dir, *, ground_truth=None, max_pairs=None, threads=None,
          dask_client=None, resume=False, thresholds=(5.0, 0.10), fuse_landmarks=True,
          scale="auto", plots=False, overlap_check="repair"):
    """Merge the mini-maps of a manifest into one frame, as `lmalign merge` (docs/merge.md).

    manifest_path: YAML manifest (maps with name, path, format, session, optional prior
        T_world_map + prior_sigma / prior_covariance).
    output_dir: poses.yaml, poses.json, edges.csv, summary.json, merged map(s) and edges/ (one
        JSON per finished edge, the resume cache) are written there, each atomically.
    ground_truth: None, 'identity' (every map's true T_world_map is the identity), or a YAML
        file 'maps: {name: 4x4 rows}'; then `evaluation` holds per-map errors (deg, m) and the
        edge precision / recall within thresholds (rot_deg, trans_m): (5, 0.1) indoors, (5, 1)
        outdoors.
    max_pairs: at most this many candidate pairs (None: no limit).
    threads: OpenMP threads over the pairs in process (None: every core); unused with Dask.
    dask_client: a distributed.Client: one task per candidate pair (align_edge_task: reads the
        two maps by path, so the maps must be on a filesystem every worker sees), gathered in
        candidate order; a lost worker's tasks are re-run by Dask (its
        distributed.scheduler.allowed-failures). The pose graph and the outputs stay here.
        None: everything in process with OpenMP. The poses are bit-identical either way.
    resume: reuse the edges in output_dir/edges whose key matches (else an output_dir holding
        edges of an earlier run is refused).
    fuse_landmarks: fuse landmarks with the same id in maps of the same session.
    scale: as `lmalign merge --scale` (docs/scale.md). 'auto': a pair where either map's header
        says its lengths are not metres (COLMAP, Bundler, monocular stella_vslam) is aligned as
        a similarity (Edge.scale = target units per source unit) and such a map gets a scale of
        its own in the pose graph (MapPose.scale = world units per map unit); maps with metric
        scale and priors hold the scale. 'free': every pair's scale is estimated too. 'fixed':
        rigid (SE(3)) edges and poses for every map (every scale exactly 1). The same in
        process and with Dask, bit for bit; the resume key depends on it.
    plots: also draw merge_graph.png and merged_landmarks.png into output_dir, as `lmalign
        merge` does, with the script shipped in the package (needs matplotlib; without it a
        RuntimeWarning and no plots).
    overlap_check: as `lmalign merge --overlap-check` (docs/merge.md, "Maps the graph puts on
        top of each other"): after the pose graph, the pairs of maps it places overlapping are
        compared landmark by landmark (overlap_check.csv); 'repair': a part they contradict is
        repaired by dropping the edges that fold it; 'check': reported only; 'off': neither (no
        overlap_check.csv). The same in process and with Dask.
    Returns a MergeOutcome. Raises ParseError (manifest, ground truth), IoError, InvalidArgument
    (bad option, an unreadable or empty map, output_dir holding an earlier run's edges), and
    with Dask what a task raised.
    """
    # Absolute, so that the map paths sent to Dask workers do not depend on this process's cwd.
    manifest_path = os.path.abspath(os.fspath(manifest_path))
    output_dir = os.fspath(output_dir)
    if max_pairs is not None and int(max_pairs) < 0:
        raise _c.InvalidArgument("max_pairs must be >= 0 (None or 0 = no limit)")
    if threads is not None and int(threads) < 0:
        raise _c.InvalidArgument("threads must be >= 0 (None or 0 = every core)")
    if scale not in ("auto", "free", "fixed"):
        raise _c.InvalidArgument("scale: expected 'auto', 'free' or 'fixed', got %r" % (scale,))
    if overlap_check not in ("repair", "check", "off"):
        raise _c.InvalidArgument("overlap_check: expected 'repair', 'check' or 'off', got %r"
                                 % (overlap_check,))
    thresholds = tuple(float(v) for v in thresholds)
    if len(thresholds) != 2:
        raise _c.InvalidArgument("thresholds: expected (rot_deg, trans_m)")
    manifest = _c.read_manifest(manifest_path)
    names = manifest.names
    priors = manifest.priors
    maps = _c.load_manifest_maps(manifest)
    truth = None
    if ground_truth is not None:
        if isinstance(ground_truth, str) and ground_truth == "identity":
            truth = np.broadcast_to(np.eye(4), (len(maps), 4, 4)).copy()
        else:
            truth = _c.read_ground_truth(os.fspath(ground_truth), names)
    edges_dir = _check_output_dir(output_dir, resume)
    if dask_client is None:
        candidates, edges, graph, reused, s_edges, s_graph = _c._run_merge(
            maps, names, priors, int(max_pairs or 0), int(threads or 0), edges_dir, scale,
            overlap_check)
        backend = "in-process"
    else:
        t0 = time.monotonic()
        candidates = _c.plan_candidates(maps, priors, max_pairs=int(max_pairs or 0))
        edges, reused = _dask_edges(dask_client, manifest, maps, candidates, edges_dir, None,
                                    scale)
        t1 = time.monotonic()
        graph = _c.solve_pose_graph(len(maps), priors, edges, maps=maps, scale=scale,
                                    overlap_check=overlap_check)
        s_edges, s_graph = t1 - t0, time.monotonic() - t1
        backend = "dask"
    overlaps = _c.check_overlaps(maps, graph, edges) if overlap_check != "off" else None
    _c.write_merge_outputs(output_dir, names, [e.session for e in manifest.maps], maps, edges,
                           graph, fuse_landmarks, overlaps)
    if plots:
        from . import _plots
        _plots.draw("plot_merge.py", [output_dir], output_dir)
    evaluation = None
    if truth is not None:
        evaluation = _c.evaluate_merge(graph, edges, truth, *thresholds)
    return MergeOutcome(names, candidates, edges, graph, evaluation, backend, reused, s_edges,
                        s_graph, output_dir)
