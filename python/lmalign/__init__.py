"""lmalign: align sparse landmark maps ("mini-maps") of feature-based visual SLAM / SfM.

Frames and units: T_target_source is a (4, 4) rigid transform with
p_target = T_target_source @ p_source; positions in metres, covariances in m^2, scores in m^2
(PCL's fitness score: mean squared nearest-neighbour distance). Arrays are float64 and
C-contiguous; arrays of another real dtype or layout are converted once, anything else (wrong
shape, complex, bool, object, strings) raises ValueError naming the argument and the expected
shape. See docs/python.md.

Errors: ParseError (file, line, detail; a ValueError), InvalidArgument (a ValueError),
IoError (an OSError), all subclasses of lmalign.Error.
"""

import json as _json
import os as _os

from ._lmalign import (  # noqa: F401  (re-exported)
    RECOMMENDED_STRATEGY,
    AlignmentResult,
    Error,
    InvalidArgument,
    IoError,
    Map,
    ParseError,
    evaluate_trajectory,
    map_formats,
    options,
    pose_from_xyz_rpy_deg,
    read_map,
    read_tum_trajectory,
    split,
    strategies,
    transform_covariances,
    transform_points,
    write_map,
)
from . import _lmalign

__version__ = "@PROJECT_VERSION@"

#: True when the compiled module has the merge (lmalign::merge is built when Ceres is found);
#: else the merge names below (MERGE_NAMES) are absent. docs/python.md, "Merge".
HAVE_MERGE = bool(_lmalign.HAVE_MERGE)
MERGE_NAMES = (
    "CandidatePair", "Edge", "EdgeReport", "Manifest", "ManifestEntry", "MapPose", "MapPrior",
    "MergeOutcome", "OverlapCheck", "PoseGraphResult", "align_edge", "check_overlaps",
    "edge_file_path", "edge_key",
    "evaluate_merge", "load_manifest_maps", "map_fingerprint", "merge", "plan_candidates",
    "read_edge_file", "read_ground_truth", "read_manifest", "read_manifest_map",
    "solve_pose_graph", "write_edge_file", "write_merge_outputs",
)
if HAVE_MERGE:
    from ._lmalign import (  # noqa: F401  (re-exported)
        CandidatePair,
        Edge,
        EdgeReport,
        Manifest,
        ManifestEntry,
        MapPose,
        MapPrior,
        OverlapCheck,
        PoseGraphResult,
        align_edge,
        check_overlaps,
        edge_file_path,
        edge_key,
        evaluate_merge,
        load_manifest_maps,
        map_fingerprint,
        plan_candidates,
        read_edge_file,
        read_ground_truth,
        read_manifest,
        read_manifest_map,
        solve_pose_graph,
        write_edge_file,
        write_merge_outputs,
    )
    from ._merge import MergeOutcome, merge  # noqa: F401

__all__ = [
    "AlignmentResult", "Error", "InvalidArgument", "IoError", "Map", "ParseError",
    "RECOMMENDED_STRATEGY", "align", "evaluate_trajectory", "experiment", "map_formats",
    "options",
    "pose_from_xyz_rpy_deg",
    "read_map", "read_tum_trajectory", "split", "strategies", "transform_covariances",
    "transform_points", "write_map", "HAVE_MERGE", "MERGE_NAMES",
] + (list(MERGE_NAMES) if HAVE_MERGE else [])

_ALIGN_OPTIONS = ("k", "max_iterations", "max_distance_m", "covariance_norm")


def align(source, target, strategy=RECOMMENDED_STRATEGY, initial_guess=None, threads=0, *,
          prior_sigma=None, source_covariances=None, target_covariances=None,
          target_weights=None, settings=None, scale="auto", **options):
    """Align `source` onto `target`; returns an AlignmentResult.

    Equals `lmalign align SOURCE TARGET --strategy STRATEGY [--set KEY=VALUE ...]` bit for bit
    (same options, same trust verdict). The GIL is released while it runs.

    source, target: a Map, or an (N, 3) array of landmark positions (metres; source frame and
        target frame). With an array source, source_covariances (N, 3, 3) m^2; with an array
        target, target_covariances (M, 3, 3) m^2 and target_weights (M,) >= 0, the landmark
        confidence every weighted stage uses (a Map target computes its own weights and
        covariances). Bare arrays carry no confidence: a strategy whose stages weigh by one
        raises InvalidArgument unless target_weights is given. The recommended strategy uses the
        covariances when given, and a Map's frames for its up axis (else +z).
    strategy: one of lmalign.strategies() (the presets, configs/presets/), or a preset file
        NAME.yaml; lmalign.options(strategy) lists its settings.
    initial_guess: (4, 4) rigid T_target_source to start from (default identity). For a
        searching strategy, one more hypothesis of its search, or with prior_sigma the centre of
        the prior's window.
    prior_sigma: (rot_deg, trans_m), each > 0: the standard deviations of initial_guess;
        searching strategies only (the CLI's --prior-sigma). A hint, checked against the maps:
        the default's global search runs too, and an answer that a pose outside 3 sigma
        outscores or nearly matches is not trusted (settings={'init.prior_check': 'off'}: the
        search within 3 sigma alone; docs/accuracy.md, "Priors are hints").
    threads: OpenMP threads for this call (0: every core). The result does not depend on it.
    settings: {key: value} of the strategy's settings (the CLI's --set; bool, int, float, a name
        or a list of floats, or text as the CLI reads it). An unknown key raises InvalidArgument
        naming the nearest known one; a value outside its bound names the key, value and bound.
    scale: 'auto', 'free' or 'fixed' (the CLI's --scale): with 'free' the scale is estimated too,
        a similarity p_target = scale * R @ p_source + t for maps without a common metric scale
        (docs/scale.md); 'auto' is free when either Map's header says its scale is not metric
        (arbitrary or unknown); arrays count as metric.
    options (as the CLI's): k (neighbourhood of the weighted kNN strategies, default 5),
        max_iterations (replaces each strategy's budget), max_distance_m (the paper's maximum
        distance, a cap on the shrinking schedules), covariance_norm ('spectral' or 'frobenius',
        for a Map target's covariance weight).

    Result: T_target_source (4, 4), converged, termination, iterations, num_correspondences,
    initial_score_m2, final_score_m2, wall_time_s, started_s, finished_s (time.monotonic()
    clock), usable, trustworthy, trust_reason, inlier_fraction and overlap_fraction (judge
    'inliers', else None), gated_inlier_ratio, ambiguity and mean_nis (judge 'gated', else None),
    translation_sd_m, rotation_sd_deg, covariance (6, 6) or None, scale (target units per
    source unit, 1.0 when fixed), scale_sd (None when fixed), scale_mode, S_target_source (4, 4)
    (the similarity [scale * R, t; 0 1]; T_target_source is its rotation and translation), source_landmarks_left_out and
    target_landmarks_left_out, covariances_assumed (a Map's covariances were assumed from its
    landmark spacing, Map.covariance_assumed, and the strategy uses covariances: also named at
    the end of trust_reason); brief_report(), full_report(), to_json() (the CLI's JSON entry).
    Supported range (docs/robustness.md): landmarks with a coordinate beyond 1e15 m are left out
    of the alignment, counted in *_landmarks_left_out and named at the end of trust_reason; an
    initial_guess translation or a prior_sigma beyond it raises InvalidArgument.
    Raises InvalidArgument (unknown strategy, setting or option, empty or non-finite input, a
    weight or covariance the strategy needs is missing, a value beyond the supported range),
    ValueError (wrong shape or dtype).
    """
    unknown = sorted(set(options) - set(_ALIGN_OPTIONS))
    if unknown:
        raise InvalidArgument("align: unknown option(s) %s; options: %s"
                              % (", ".join(unknown), ", ".join(_ALIGN_OPTIONS)))
    try:
        return _lmalign._align(
            source, target, strategy, initial_guess, prior_sigma, int(threads),
            source_covariances,
            target_covariances, target_weights, int(options.get("k", 5)),
            options.get("max_iterations"), options.get("max_distance_m"),
            options.get("covariance_norm", "spectral"), settings, str(scale))
    except InvalidArgument as e:
        if "built from bare points" not in str(e):
            raise
        raise InvalidArgument(
            "%s: strategy '%s' needs landmark confidences (or covariances) of the target: pass "
            "target_weights (M,) (e.g. observation counts) or target_covariances (M, 3, 3), a Map "
            "target, or a strategy that weighs by none (lmalign.options(NAME) shows its "
            "match.confidence and kernel.confidence)" % (e, strategy)) from None


def _data_dir():
    """$LMALIGN_DATA, else empty (then a config that uses ${LMALIGN_DATA} is refused)."""
    return _os.environ.get("LMALIGN_DATA", "")


def experiment(config, output_dir, only=None, threads=0, data_dir=None, plots=False):
    """Run an experiment protocol (YAML, docs/experiments.md), as `lmalign experiment`.

    Writes config.yaml (resolved), results.csv, summary.json and tables.md into output_dir (the
    same files as the CLI's, without --resume or history files) and returns a dict:
    output_dir, results_csv, summary_json, tables_md (paths), cases, runs (counts), plots (the
    PNG paths), and summary (summary.json, parsed). only: experiment names to run (default
    all). threads: worker threads (0: every core). data_dir: what ${LMALIGN_DATA} in the config
    expands to (default $LMALIGN_DATA). plots: also draw the CLI's violin and basin plots into
    output_dir/plots with the script shipped in the package (needs matplotlib; without it a
    RuntimeWarning and no plots). The GIL is released while the cases run.
    Raises ParseError (config file, line), InvalidArgument, IoError.
    """
    output_dir = _os.fspath(output_dir)
    cases, runs = _lmalign._experiment(config, output_dir, list(only or []), int(threads),
                                       _data_dir() if data_dir is None else _os.fspath(data_dir))
    paths = {name: _os.path.join(output_dir, name + "." + ext)
             for name, ext in (("results", "csv"), ("summary", "json"), ("tables", "md"))}
    with open(paths["summary"], encoding="utf-8") as f:
        summary = _json.load(f)
    drawn = []
    if plots:
        from . import _plots
        drawn = _plots.draw("plot_experiment.py", [output_dir],
                            _os.path.join(output_dir, "plots"))
    return {"output_dir": output_dir, "results_csv": paths["results"],
            "summary_json": paths["summary"], "tables_md": paths["tables"], "cases": cases,
            "runs": runs, "plots": drawn, "summary": summary}
