#!/usr/bin/env python3
"""The multi-dataset accuracy benchmark (issue 18; docs/accuracy.md, "Multi-dataset benchmark").

    make bench-accuracy                      # = python3 bench/run_accuracy.py
    python3 bench/run_accuracy.py --quick    # a fraction: 10 random starts, 8 protocol cases
    python3 bench/run_accuracy.py --strategies robust_obs,global --datasets desk_gt,kitti_overlap

For every dataset of bench/accuracy.yaml it prepares the maps (existing files as they are;
`lmalign split --retriangulate` windows and `lmalign simulate` scenes made in the output folder),
writes one experiment config (the 39 protocol displacements of method.md §5 and the seeded random
starts) and runs it with `lmalign experiment` (parallel; an interrupted run is resumed), then a
reference: the paper's base ICP started at the truth with a tight correspondence gate. From the
runs' results.csv it reports, per dataset and strategy: right-basin success (protocol, random, all),
the median rotation and translation errors of the successes, the trust verdict's precision and
recall (trustworthy against right basin), the mean and median NEES of the trusted right-basin
results (their reported 6x6 covariance against the truth; 6 when calibrated), and the time per alignment
(median, max) with the landmark counts. For the default strategy (`lmalign align` without
--strategy; bench/accuracy_default.py) it adds, per dataset, the search regret of every start
(the score refined from the truth minus the score of the answer), the basin of its refinement
alone along each axis and in yaw, and its time per alignment (--no-regret, --no-basin skip them).
Beside the default, its peer Open3D FPFH + RANSAC + ICP on the maps as given, one thread each:
right basin, errors, CPU time (bench/accuracy_peers.py; --no-peers skips it, and it is skipped
with a note when libopen3d-dev was not found).
Output in --output (default build/bench-accuracy): accuracy.csv, default.csv, peers.csv,
accuracy.json, accuracy.md (the tables as Markdown), plots/<dataset>.png (success against start
offset, random starts, one line per strategy), and per dataset its maps, configs and experiment
folders. A full run (no --quick, every dataset and every configured strategy) also writes
bench/results/accuracy.json.
"""
import argparse
import csv
import json
import math
import os
import re
import shutil
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import accuracy_default  # noqa: E402
import accuracy_peers  # noqa: E402
import accuracy_similarity  # noqa: E402
DEFAULT_CONFIG = os.path.join(ROOT, "bench", "accuracy.yaml")
RESULTS_JSON = os.path.join(ROOT, "bench", "results", "accuracy.json")

# Bins of the start offset for the plots and the binned rates (metres; the last bin is open).
OFFSET_BINS = 5


class BenchError(Exception):
    """A one-line error for the user (bad config, missing file, failed command)."""


def run_main(main, errors, prefix, status):
    """Exits with main()'s status; an exception of type `errors` becomes one line on stderr,
    "PREFIX: MESSAGE", and the exit status `status`."""
    try:
        sys.exit(main())
    except errors as e:
        print("%s: %s" % (prefix, e), file=sys.stderr)
        sys.exit(status)


# --------------------------------------------------------------------------- config

def protocol_poses():
    """The 39 distinct displacements of method.md §5 (Tables 1-4; Table 1's k values share one),
    as (label, pose dict) in the tables' order."""
    poses = [("table1", dict(x_m=0, y_m=1, z_m=0.4, roll_deg=10, pitch_deg=0, yaw_deg=22.5))]
    for yaw in range(0, 80, 10):
        poses.append(("table2 yaw=%d" % yaw, dict(yaw_deg=yaw)))
    quadrants = {"+X+Y": (1, 1), "-X+Y": (-1, 1), "-X-Y": (-1, -1), "+X-Y": (1, -1)}
    table3 = [("+X+Y", [0.25, 0.5, 0.57, 0.58]), ("-X+Y", [0.25, 0.5, 0.9]),
              ("-X-Y", [0.25, 0.5]), ("+X-Y", [0.25, 0.5, 1.25, 2.0, 3.0])]
    for q, offsets in table3:
        sx, sy = quadrants[q]
        for d in offsets:
            poses.append(("table3 %s %g" % (q, d), dict(x_m=sx * d, y_m=sy * d)))
    for q in ["+X+Y", "-X+Y", "-X-Y", "+X-Y"]:
        sx, sy = quadrants[q]
        for yaw in [10, -10, 30, -30]:
            poses.append(("table4 %s yaw=%d" % (q, yaw), dict(x_m=sx * 0.5, y_m=sy * 0.5,
                                                              yaw_deg=yaw)))
    full = []
    for label, p in poses:
        full.append((label, {k: float(p.get(k, 0.0)) for k in
                             ["x_m", "y_m", "z_m", "roll_deg", "pitch_deg", "yaw_deg"]}))
    return full


def expand_data(text, data_dir, where):
    if not isinstance(text, str) or not text:
        raise BenchError("%s: expected a path" % where)
    unknown = [v for v in re.findall(r"\$\{([^}]*)\}", text) if v != "LMALIGN_DATA"]
    if unknown:
        raise BenchError("%s: unknown variable '${%s}'" % (where, unknown[0]))
    return text.replace("${LMALIGN_DATA}", data_dir)


def load_config(path, data_dir):
    """Reads and checks the benchmark config; returns it with paths expanded and each dataset's
    settings (thresholds, random radius, reference gate) resolved from its kind."""
    import yaml  # Debian's python3-yaml
    try:
        with open(path) as f:
            cfg = yaml.safe_load(f)
    except OSError as e:
        raise BenchError("%s: cannot read: %s" % (path, e.strerror))
    except yaml.YAMLError as e:
        raise BenchError("%s: YAML error: %s" % (path, str(e).splitlines()[0]))
    if not isinstance(cfg, dict):
        raise BenchError("%s: expected a mapping" % path)
    for key in ["strategies", "datasets", "kinds", "random", "reference"]:
        if key not in cfg:
            raise BenchError("%s: missing key '%s'" % (path, key))
    if not isinstance(cfg["strategies"], list) or not cfg["strategies"]:
        raise BenchError("%s: strategies: expected a non-empty list of strategy names" % path)
    names = set()
    for i, d in enumerate(cfg["datasets"]):
        where = "%s: datasets[%d]" % (path, i)
        if not isinstance(d, dict) or "name" not in d:
            raise BenchError("%s: expected a mapping with a name" % where)
        if not re.fullmatch(r"[A-Za-z0-9_.-]+", str(d["name"])):
            raise BenchError("%s.name: expected letters, digits, '_', '-' or '.'" % where)
        if d["name"] in names:
            raise BenchError("%s.name: '%s' is used twice" % (where, d["name"]))
        names.add(d["name"])
        kind = d.get("kind")
        if kind not in cfg["kinds"]:
            raise BenchError("%s.kind: expected one of %s, got '%s'"
                             % (where, ", ".join(sorted(cfg["kinds"])), kind))
        for k, v in cfg["kinds"][kind].items():
            d.setdefault(k, v)
        d.setdefault("up_axis", "z")
        prior = d.get("basin_prior_sigma", [1.0, 0.05])
        if (not isinstance(prior, list) or len(prior) != 2 or
                not all(isinstance(v, (int, float)) and v > 0 for v in prior)):
            raise BenchError("%s.basin_prior_sigma: expected [ROT_DEG, TRANS_M], both > 0" % where)
        d["basin_prior_sigma"] = [float(v) for v in prior]
        if d["up_axis"] not in ("x", "y", "z"):
            raise BenchError("%s.up_axis: expected x, y or z" % where)
        sources = [k for k in ("source", "split", "simulate") if k in d]
        if len(sources) != 1:
            raise BenchError("%s: give exactly one of source/target, split, simulate" % where)
        if "source" in d:
            if "target" not in d:
                raise BenchError("%s: source without target" % where)
            d["source"] = expand_data(d["source"], data_dir, where + ".source")
            d["target"] = expand_data(d["target"], data_dir, where + ".target")
            if d.get("truth", "identity") != "identity":
                d["truth"] = expand_data(d["truth"], data_dir, where + ".truth")
        elif "split" in d:
            s = d["split"]
            for k in ("map", "source_frames", "target_frames"):
                if k not in s:
                    raise BenchError("%s.split: missing key '%s'" % (where, k))
            s["map"] = expand_data(s["map"], data_dir, where + ".split.map")
            if "intrinsics" in s and not re.fullmatch(r"[0-9.eE+-]+(,[0-9.eE+-]+){3}",
                                                      str(s["intrinsics"])):
                raise BenchError("%s.split.intrinsics: expected FX,FY,CX,CY (pixels)" % where)
        else:
            s = d["simulate"]
            if s.get("scene") not in ("road", "street", "corridor"):
                raise BenchError("%s.simulate.scene: expected road, street or corridor" % where)
            if "frames" in s and s["scene"] != "street":
                raise BenchError("%s.simulate.frames: only for scene street" % where)
    try:
        cfg["similarity"] = accuracy_similarity.check_entries(
            cfg.get("similarity"), names, "%s: similarity" % path)
    except accuracy_similarity.SimilarityError as e:
        raise BenchError(str(e))
    dflt = cfg.setdefault("default", {})
    prior = dflt.setdefault("truth_prior_sigma", [0.05, 0.005])
    if (not isinstance(prior, list) or len(prior) != 2 or
            not all(isinstance(v, (int, float)) and v > 0 for v in prior)):
        raise BenchError("%s: default.truth_prior_sigma: expected [ROT_DEG, TRANS_M], both > 0"
                         % path)
    ref = dflt.setdefault("reference_strategy", None)
    if ref is not None and (not isinstance(ref, str) or not re.fullmatch(r"[A-Za-z0-9_.-]+", ref)):
        raise BenchError("%s: default.reference_strategy: expected a strategy name, got %r"
                         % (path, ref))
    return cfg


def select(items, wanted, what):
    """The items whose name is in `wanted` (comma list; empty: all), refusing unknown names."""
    if not wanted:
        return items
    names = [w for w in wanted.split(",") if w]
    known = [i if isinstance(i, str) else i["name"] for i in items]
    for n in names:
        if n not in known:
            raise BenchError("--%s: unknown name '%s' (known: %s)" % (what, n, ", ".join(known)))
    return [i for i, k in zip(items, known) if k in names]


# --------------------------------------------------------------------------- preparation

def run_command(cmd, log_path):
    """Runs cmd, its stdout and stderr appended to log_path; returns stdout. BenchError on a
    non-zero exit, with the command's last stderr line."""
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    with open(log_path, "a") as log:
        log.write("$ " + " ".join(cmd) + "\n" + p.stdout + p.stderr)
    if p.returncode != 0:
        last = (p.stderr.strip().splitlines() or ["exit code %d" % p.returncode])[-1]
        raise BenchError("%s failed: %s (log: %s)" % (" ".join(cmd[:2]), last, log_path))
    return p.stdout


def require_file(path, field):
    if not os.path.isfile(path):
        raise BenchError("%s: file not found: %s" % (field, path))


def prepare_maps(lmalign, d, folder, log):
    """Source, target and truth of dataset d: (source path, target path, truth) where truth is
    'identity' or a transform file. Made maps go into folder (kept when already there)."""
    where = "dataset %s" % d["name"]
    if "source" in d:
        require_file(d["source"], where + ": source")
        require_file(d["target"], where + ": target")
        truth = d.get("truth", "identity")
        if truth != "identity":
            require_file(truth, where + ": truth")
        return d["source"], d["target"], truth
    os.makedirs(folder, exist_ok=True)
    if "split" in d:
        s = d["split"]
        require_file(s["map"], where + ": split.map")
        out = []
        for role in ("source", "target"):
            path = os.path.join(folder, role + ".txt")
            if not os.path.isfile(path):
                cmd = [lmalign, "split", s["map"], "--frames", str(s[role + "_frames"]),
                       "--retriangulate", "--min-parallax", str(s.get("min_parallax_deg", 2))]
                if "intrinsics" in s:
                    cmd += ["--intrinsics", str(s["intrinsics"])]
                run_command(cmd + ["-o", path], log)
            out.append(path)
        return out[0], out[1], d.get("truth", "identity")
    s = d["simulate"]
    truth = os.path.join(folder, "T_target_source.txt")
    if not os.path.isfile(truth):  # written last by lmalign simulate
        cmd = [lmalign, "simulate", "--scene", s["scene"], "--seed", str(s.get("seed", 1)),
               "--overlap", str(s.get("overlap", 0.2)),
               "--landmarks", str(s.get("landmarks", 3000))]
        if "frames" in s:
            cmd += ["--frames", str(s["frames"])]
        run_command(cmd + ["-o", folder], log)
    return os.path.join(folder, "source.txt"), os.path.join(folder, "target.txt"), truth


def experiment_config(d, source, target, truth, strategies, k, random_spec, protocol):
    """The `lmalign experiment` config of dataset d: protocol displacements and random starts."""
    experiments = []
    if protocol:
        experiments.append({"name": "protocol", "type": "poses",
                            "poses": [p for _, p in protocol]})
    if random_spec["samples"] > 0:
        experiments.append({"name": "random", "type": "random",
                            "samples": int(random_spec["samples"]),
                            "seed": int(random_spec["seed"]), "yaw_deg": 180,
                            "translation_m": float(d["random_translation_m"]),
                            "roll_pitch_deg": float(random_spec["roll_pitch_deg"]),
                            "pivot": "centroid", "up_axis": d["up_axis"]})
    return {"description": "accuracy benchmark: " + d["name"], "source": source, "target": target,
            "ground_truth": truth, "strategies": list(strategies), "k": int(k),
            "success": {"rotation_deg": float(d["rotation_deg"]),
                        "translation_m": float(d["translation_m"])},
            "experiments": experiments}


def reference_config(d, source, target, truth, reference):
    """The reference: base ICP started at the truth, correspondences within the dataset's gate.
    The runner displaces the source by D and compares T * D with the truth, so D = truth starts
    the ICP at the truth; with a transform file the driver passes its pose."""
    return {"description": "accuracy benchmark reference: " + d["name"], "source": source,
            "target": target, "ground_truth": truth, "strategies": [reference["strategy"]],
            "k": 5, "max_iterations": int(reference.get("max_iterations", 150)),
            "max_distance_m": float(d["reference_max_distance_m"]),
            "success": {"rotation_deg": float(d["rotation_deg"]),
                        "translation_m": float(d["translation_m"])},
            "experiments": [{"name": "reference", "type": "poses", "poses": [{}]}]}


def write_yaml(path, data):
    import yaml
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        yaml.safe_dump(data, f, sort_keys=False, default_flow_style=None)
    os.replace(tmp, path)


def run_experiment(lmalign, config_path, out_dir, threads, log):
    """Runs (or resumes, or reuses) one experiment; returns (rows of results.csv, landmark counts
    (source, target) or None when reused)."""
    done = os.path.join(out_dir, "summary.json")
    same = os.path.isfile(os.path.join(out_dir, "config.yaml")) and os.path.isfile(done) and \
        os.path.getmtime(done) >= os.path.getmtime(config_path)
    counts = None
    if not same:
        cmd = [lmalign, "experiment", config_path, "-o", out_dir, "--no-plots",
               "--threads", str(threads)]
        if os.path.isfile(os.path.join(out_dir, "results.csv")):
            try:
                stdout = run_command([lmalign, "experiment", config_path, "--resume", out_dir, "--no-plots",
                                      "--threads", str(threads)], log)
            except BenchError:
                shutil.rmtree(out_dir)
                stdout = run_command(cmd, log)
        else:
            stdout = run_command(cmd, log)
        counts = landmark_counts(stdout)
    return read_rows(os.path.join(out_dir, "results.csv")), counts


def landmark_counts(stdout):
    """(source, target) landmark counts from `lmalign experiment`'s opening lines."""
    m = re.search(r"\((\d+) landmarks\), target .*\((\d+) landmarks\)", stdout)
    return (int(m.group(1)), int(m.group(2))) if m else None


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


# --------------------------------------------------------------------------- metrics

def _median(values):
    return statistics.median(values) if values else None


def strategy_metrics(rows):
    """Metrics of one strategy's runs (results.csv rows as dicts)."""
    ok = [r for r in rows if r["success"] == "true"]
    trusted = [r for r in rows if r.get("trustworthy") == "true"]
    true_pos = [r for r in trusted if r["success"] == "true"]
    times = [float(r["time_s"]) for r in rows]
    # NEES of the trusted right-basin results (6 when the reported covariance is calibrated):
    # the covariance a user acts on. An untrusted answer of the default carries the estimator's
    # covariance alone, without the half samples (since 2026-11-27, docs/accuracy.md, "The half
    # samples only where the verdict weighs them"). Rows without a covariance (or written
    # before the column existed) have none.
    nees = [float(r["nees"]) for r in true_pos if r.get("nees")]
    by_exp = {}
    for r in rows:
        e = by_exp.setdefault(r["experiment"], [0, 0])
        e[0] += r["success"] == "true"
        e[1] += 1
    return {
        "runs": len(rows),
        "successes": len(ok),
        "success_rate": len(ok) / len(rows) if rows else None,
        "success_rate_by_experiment": {k: v[0] / v[1] for k, v in sorted(by_exp.items())},
        "median_rotation_error_deg": _median([float(r["rotation_error_deg"]) for r in ok]),
        "median_translation_error_m": _median([float(r["translation_error_m"]) for r in ok]),
        "trusted": len(trusted),
        # Precision: of the runs called trustworthy, the share in the right basin (None when
        # none was trusted). Recall: of the runs in the right basin, the share called trustworthy.
        "trust_precision": len(true_pos) / len(trusted) if trusted else None,
        "trust_recall": len(true_pos) / len(ok) if ok else None,
        "median_time_s": _median(times),
        "max_time_s": max(times) if times else None,
        "nees_runs": len(nees),
        "mean_nees": statistics.fmean(nees) if nees else None,
        "median_nees": _median(nees),
    }


def offset_bins(max_offset_m, bins=OFFSET_BINS):
    """Bin edges [0, max/b, ..., max]."""
    return [max_offset_m * i / bins for i in range(bins + 1)]


def binned_success(rows, edges):
    """Per bin of the random starts' offset (the `value` column): (runs, successes)."""
    out = [[0, 0] for _ in range(len(edges) - 1)]
    for r in rows:
        if r["experiment"] != "random":
            continue
        v = float(r["value"])
        i = min(len(out) - 1, max(0, int(math.floor(v / edges[-1] * len(out))))) \
            if edges[-1] > 0 else 0
        out[i][0] += 1
        out[i][1] += r["success"] == "true"
    return out


def dataset_report(d, rows, reference_rows, counts, strategies):
    """The report of one dataset: per strategy metrics, the reference, the binned success."""
    edges = offset_bins(float(d["random_translation_m"]))
    per = {}
    for s in strategies:
        rs = [r for r in rows if r["strategy"] == s]
        m = strategy_metrics(rs)
        m["success_by_offset"] = [{"offset_lo_m": edges[i], "offset_hi_m": edges[i + 1],
                                   "runs": b[0], "successes": b[1]}
                                  for i, b in enumerate(binned_success(rs, edges))]
        per[s] = m
    ref = None
    if reference_rows:
        r = reference_rows[0]
        ref = {"strategy": r["strategy"], "max_distance_m": float(d["reference_max_distance_m"]),
               "rotation_error_deg": float(r["rotation_error_deg"]),
               "translation_error_m": float(r["translation_error_m"]),
               "iterations": int(r["iterations"]), "trustworthy": r.get("trustworthy") == "true"}
    return {"kind": d["kind"], "up_axis": d["up_axis"],
            "thresholds": {"rotation_deg": float(d["rotation_deg"]),
                           "translation_m": float(d["translation_m"]),
                           "random_translation_m": float(d["random_translation_m"])},
            "landmarks": {"source": counts[0], "target": counts[1]} if counts else None,
            "reference": ref, "strategies": per}


def overall_report(datasets):
    """Per strategy across datasets: pooled success rate, and the worst dataset's rate."""
    out = {}
    for name, rep in datasets.items():
        for s, m in rep["strategies"].items():
            o = out.setdefault(s, {"runs": 0, "successes": 0, "worst_dataset": None,
                                   "worst_success_rate": None, "trusted": 0, "true_trusted": 0})
            o["runs"] += m["runs"]
            o["successes"] += m["successes"]
            o["trusted"] += m["trusted"]
            if m["trust_precision"] is not None:
                o["true_trusted"] += round(m["trust_precision"] * m["trusted"])
            if m["success_rate"] is not None and (o["worst_success_rate"] is None or
                                                  m["success_rate"] < o["worst_success_rate"]):
                o["worst_success_rate"] = m["success_rate"]
                o["worst_dataset"] = name
    for o in out.values():
        o["success_rate"] = o["successes"] / o["runs"] if o["runs"] else None
        o["trust_precision"] = o["true_trusted"] / o["trusted"] if o["trusted"] else None
        o["trust_recall"] = o["true_trusted"] / o["successes"] if o["successes"] else None
        del o["true_trusted"]
    return out


CSV_COLUMNS = ["dataset", "kind", "source_landmarks", "target_landmarks", "strategy", "runs",
               "success_rate", "protocol_success_rate", "random_success_rate",
               "median_rotation_error_deg", "median_translation_error_m", "trust_precision",
               "trust_recall", "median_time_s", "max_time_s", "reference_rotation_error_deg",
               "reference_translation_error_m", "mean_nees", "median_nees"]


def csv_rows(report):
    out = []
    for name, rep in report["datasets"].items():
        lm = rep["landmarks"] or {"source": None, "target": None}
        ref = rep["reference"] or {}
        for s, m in rep["strategies"].items():
            byx = m["success_rate_by_experiment"]
            out.append({"dataset": name, "kind": rep["kind"], "source_landmarks": lm["source"],
                        "target_landmarks": lm["target"], "strategy": s, "runs": m["runs"],
                        "success_rate": m["success_rate"],
                        "protocol_success_rate": byx.get("protocol"),
                        "random_success_rate": byx.get("random"),
                        "median_rotation_error_deg": m["median_rotation_error_deg"],
                        "median_translation_error_m": m["median_translation_error_m"],
                        "trust_precision": m["trust_precision"], "trust_recall": m["trust_recall"],
                        "median_time_s": m["median_time_s"], "max_time_s": m["max_time_s"],
                        "reference_rotation_error_deg": ref.get("rotation_error_deg"),
                        "reference_translation_error_m": ref.get("translation_error_m"),
                        "mean_nees": m["mean_nees"], "median_nees": m["median_nees"]})
    return out


def write_csv(path, rows, columns=None):
    tmp = path + ".tmp"
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns or CSV_COLUMNS)
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if v is None else (round(v, 6) if isinstance(v, float) else v))
                        for k, v in r.items()})
    os.replace(tmp, path)


def _pct(v):
    return "–" if v is None else "%.0f%%" % (100.0 * v)


def _num(v, fmt):
    return "–" if v is None else fmt % v


def markdown_tables(report):
    """The report as Markdown: a success-rate matrix (strategy x dataset), then per dataset its
    table (success all / protocol / random, medians of the successes, trust precision and recall,
    time per alignment) with the landmark counts and the reference row."""
    names = list(report["datasets"])
    strategies = report["strategies"]
    lines = ["Right-basin success over all starts (protocol + random), per dataset:", "",
             "| strategy | " + " | ".join(names) + " |",
             "|---|" + "---|" * len(names)]
    for s in strategies:
        cells = [_pct(report["datasets"][n]["strategies"][s]["success_rate"]) for n in names]
        lines.append("| %s | %s |" % (s, " | ".join(cells)))
    for n in names:
        rep = report["datasets"][n]
        lm = rep["landmarks"] or {"source": "?", "target": "?"}
        th = rep["thresholds"]
        ref = rep["reference"]
        lines += ["", "**%s** (%s; %s source / %s target landmarks; right basin %g° and %g m; "
                  "random offsets up to %g m)" % (n, rep["kind"], lm["source"], lm["target"],
                                                  th["rotation_deg"], th["translation_m"],
                                                  th["random_translation_m"]), ""]
        if ref:
            lines += ["Reference (%s started at the truth, gate %g m): %.3f°, %.4f m." % (
                ref["strategy"], ref["max_distance_m"], ref["rotation_error_deg"],
                ref["translation_error_m"]), ""]
        lines += ["| strategy | success | protocol | random | median rot. (°) | median trans. (m) "
                  "| trust precision | trust recall | time median / max (s) "
                  "| NEES mean / median |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for s in strategies:
            m = rep["strategies"][s]
            byx = m["success_rate_by_experiment"]
            lines.append("| %s | %s | %s | %s | %s | %s | %s | %s | %s / %s | %s / %s |" % (
                s, _pct(m["success_rate"]), _pct(byx.get("protocol")), _pct(byx.get("random")),
                _num(m["median_rotation_error_deg"], "%.2f"),
                _num(m["median_translation_error_m"], "%.3f"),
                _num(m["trust_precision"], "%.2f"), _num(m["trust_recall"], "%.2f"),
                _num(m["median_time_s"], "%.3f"), _num(m["max_time_s"], "%.2f"),
                _num(m["mean_nees"], "%.3g"), _num(m["median_nees"], "%.3g")))
    lines += default_markdown(report)
    return "\n".join(lines) + "\n"


def write_json(path, data):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(data, f, indent=1, sort_keys=False)
        f.write("\n")
    os.replace(tmp, path)


def plot_dataset(path, name, rep):
    """Success rate of the random starts against their offset, one line per strategy."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 4.8))
    colours = plt.get_cmap("tab20")
    markers = "osD^v<>phX*"
    for i, (s, m) in enumerate(rep["strategies"].items()):
        bins = [b for b in m["success_by_offset"] if b["runs"] > 0]
        if not bins:
            continue
        x = [(b["offset_lo_m"] + b["offset_hi_m"]) / 2 for b in bins]
        y = [100.0 * b["successes"] / b["runs"] for b in bins]
        # Lines that coincide stay visible: a small vertical shift per strategy, distinct
        # colours and markers.
        y = [v + 0.6 * (i - len(rep["strategies"]) / 2) for v in y]
        ax.plot(x, y, marker=markers[i % len(markers)], color=colours(i % 20),
                linestyle="-" if i % 2 == 0 else "--", label=s, alpha=0.9)
    ax.set_xlabel("start offset across the vertical (m), random starts, yaw in [-180, 180] deg")
    ax.set_ylabel("right-basin success (%; lines shifted apart by 0.6)")
    th = rep["thresholds"]
    ax.set_title("%s (%s): right basin = %g deg and %g m" % (name, rep["kind"], th["rotation_deg"],
                                                            th["translation_m"]))
    ax.set_ylim(-8, 108)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncol=1, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.tight_layout()
    tmp = path + ".tmp.png"
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)


# --------------------------------------------------------------------------- the default

def default_report(lmalign, d, source, target, truth, rows, folder, log, spec, a):
    """The default strategy's regret, basin and time on dataset d (bench/accuracy_default.py),
    and the reference search's (default.reference_strategy) from the same starts."""
    aligner = accuracy_default.Aligner(lmalign, source, target, truth,
                                       (float(d["rotation_deg"]), float(d["translation_m"])),
                                       os.path.join(folder, "default"), log)
    try:
        out = {}
        if not a.no_regret:
            refined = accuracy_default.truth_refined(
                aligner, [spec["truth_prior_sigma"], d["basin_prior_sigma"]])
            out = accuracy_default.regret_report(aligner, rows, None, truth=refined)
            if spec.get("reference_strategy") and not a.no_reference:
                # The reference search from the same starts (issue 39, item 2): its answers,
                # regrets and times beside the default's, against the same truth-refined score.
                reference = accuracy_default.Aligner(
                    lmalign, source, target, truth,
                    (float(d["rotation_deg"]), float(d["translation_m"])),
                    os.path.join(folder, "default"), log, strategy=spec["reference_strategy"])
                out["reference"] = accuracy_default.reference_report(reference, aligner, rows,
                                                                     refined)
        if not a.no_basin:
            out["basin"] = accuracy_default.basin_report(
                aligner, d, source, target, d["basin_prior_sigma"], 2 if a.quick else 4,
                a.threads)
    except accuracy_default.DefaultError as e:
        raise BenchError("dataset %s: %s" % (d["name"], e))
    return out


def peers_report(peer, lmalign, d, source, target, truth, folder, log):
    """Open3D's global registration beside the default on dataset d (bench/accuracy_peers.py)."""
    thresholds = (float(d["rotation_deg"]), float(d["translation_m"]))
    aligner = accuracy_default.Aligner(lmalign, source, target, truth, thresholds,
                                       os.path.join(folder, "default"), log)
    try:
        return accuracy_peers.peer_report(peer, aligner, source, target, thresholds, folder, log)
    except (accuracy_peers.PeerError, accuracy_default.DefaultError) as e:
        raise BenchError("dataset %s: %s" % (d["name"], e))


def default_line(dflt):
    """One line of the default's numbers for the progress output."""
    parts = []
    if "starts" in dflt:
        parts.append("%s: right basin %s, regret %s" % (
            dflt["strategy"], _pct(dflt["right_basin_rate"]),
            "-" if not dflt.get("regret") else "max %.3g (%.1f%%), %s of starts > 1%%" % (
                dflt["regret"]["max"], 100 * dflt["regret"]["max_relative"],
                _pct(dflt["regret"]["fraction_above_tolerance"]))))
    ref = dflt.get("reference")
    if ref and "starts" in ref:
        parts.append("%s: right basin %s, regret max %s, the same answer %s, time ratio %s" % (
            ref["strategy"], _pct(ref["right_basin_rate"]),
            "-" if not ref.get("regret") else "%.3g" % ref["regret"]["max"],
            _pct(ref["same_answer_rate"]),
            "-" if ref["median_time_ratio_default_over_reference"] is None
            else "%.2fx" % ref["median_time_ratio_default_over_reference"]))
    b = dflt.get("basin")
    if b and b.get("directions"):
        parts.append("basin " + ", ".join("%s %s" % (k, _basin_cell(v))
                                          for k, v in b["directions"].items()))
    return "; ".join(parts)


def _basin_cell(v):
    """'-a / +b' of a basin direction, '>=' where the search limit was reached."""
    def one(sign):
        return "%s%.3g" % (">=" if v.get("at_limit" + sign) else "", v[sign])
    return "-%s / +%s" % (one("-"), one("+"))


DEFAULT_COLUMNS = ["dataset", "kind", "source_landmarks", "target_landmarks", "strategy",
                   "starts", "right_basin_rate", "trust_precision", "trust_recall",
                   "truth_gated_score", "truth_rotation_error_deg", "truth_translation_error_m",
                   "truth_trustworthy", "regret_max", "regret_median", "regret_max_relative",
                   "fraction_regret_above_1pct", "search_failures", "score_failures",
                   "median_time_s", "max_time_s", "basin_prior_rotation_deg",
                   "basin_prior_translation_m"] + [
    "basin_%s_%s" % (k, s) for k in ("x_m", "y_m", "z_m", "forward_m", "yaw_deg")
    for s in ("minus", "plus")] + [
    "reference_strategy", "reference_right_basin_rate", "reference_trust_precision",
    "reference_trust_recall", "reference_regret_max", "reference_search_failures",
    "reference_score_failures", "reference_median_time_s", "reference_max_time_s",
    "same_answer_rate", "default_scores_higher", "reference_scores_higher",
    "median_time_ratio_default_over_reference"]


def default_csv_rows(report):
    out = []
    for name, rep in report["datasets"].items():
        dflt = rep.get("default")
        if not dflt:
            continue
        lm = rep["landmarks"] or {"source": None, "target": None}
        tr = dflt.get("truth_refined") or {}
        rg = dflt.get("regret") or {}
        b = dflt.get("basin") or {}
        prior = b.get("prior_sigma") or [None, None]
        row = {"dataset": name, "kind": rep["kind"], "source_landmarks": lm["source"],
               "target_landmarks": lm["target"], "strategy": dflt.get("strategy"),
               "starts": dflt.get("starts"), "right_basin_rate": dflt.get("right_basin_rate"),
               "trust_precision": dflt.get("trust_precision"),
               "trust_recall": dflt.get("trust_recall"),
               "truth_gated_score": tr.get("gated_score"),
               "truth_rotation_error_deg": tr.get("rotation_error_deg"),
               "truth_translation_error_m": tr.get("translation_error_m"),
               "truth_trustworthy": tr.get("trustworthy"),
               "regret_max": rg.get("max"), "regret_median": rg.get("median"),
               "regret_max_relative": rg.get("max_relative"),
               "fraction_regret_above_1pct": rg.get("fraction_above_tolerance"),
               "search_failures": rg.get("search_failures"),
               "score_failures": rg.get("score_failures"),
               "median_time_s": dflt.get("median_time_s"), "max_time_s": dflt.get("max_time_s"),
               "basin_prior_rotation_deg": prior[0], "basin_prior_translation_m": prior[1]}
        for k, v in (b.get("directions") or {}).items():
            row["basin_%s_minus" % k] = v["-"]
            row["basin_%s_plus" % k] = v["+"]
        ref = dflt.get("reference")
        if ref:
            rrg = ref.get("regret") or {}
            row.update({
                "reference_strategy": ref.get("strategy"),
                "reference_right_basin_rate": ref.get("right_basin_rate"),
                "reference_trust_precision": ref.get("trust_precision"),
                "reference_trust_recall": ref.get("trust_recall"),
                "reference_regret_max": rrg.get("max"),
                "reference_search_failures": rrg.get("search_failures"),
                "reference_score_failures": rrg.get("score_failures"),
                "reference_median_time_s": ref.get("median_time_s"),
                "reference_max_time_s": ref.get("max_time_s"),
                "same_answer_rate": ref.get("same_answer_rate"),
                "default_scores_higher": ref.get("default_scores_higher"),
                "reference_scores_higher": ref.get("reference_scores_higher"),
                "median_time_ratio_default_over_reference":
                    ref.get("median_time_ratio_default_over_reference")})
        out.append(row)
    return out


def default_markdown(report):
    """The default's table: right basin, trust, regret, time and basin per dataset."""
    rows = [(n, r) for n, r in report["datasets"].items() if r.get("default")]
    if not rows:
        return []
    strategy = next((r["default"].get("strategy") for _, r in rows
                     if r["default"].get("strategy")), "the default")
    lines = ["", "The default (%s, `lmalign align` without --strategy), from the same starts: "
             "right basin, trust precision / recall, the covariance-gated score refined from "
             "the truth, the search regret (that score minus the answer's: max, and the share of "
             "starts above 1%% of it; search failures = wrong basin with regret > 1%%, score "
             "failures = wrong basin, regret <= 1%%), time per alignment:" % strategy, "",
             "| dataset | landmarks | right basin | trust P / R | truth score | regret max "
             "| starts > 1% | search / score failures | time median / max (s) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for n, rep in rows:
        dflt = rep["default"]
        if "starts" not in dflt:
            continue
        lm = rep["landmarks"] or {"source": "?", "target": "?"}
        rg = dflt.get("regret")
        tr = dflt.get("truth_refined") or {}
        lines.append("| %s | %s / %s | %s | %s / %s | %s | %s | %s | %s | %s / %s |" % (
            n, lm["source"], lm["target"], _pct(dflt["right_basin_rate"]),
            _num(dflt["trust_precision"], "%.2f"), _num(dflt["trust_recall"], "%.2f"),
            _num(tr.get("gated_score"), "%.4g"),
            "–" if not rg else "%.4g (%.1f%%)" % (rg["max"], 100 * rg["max_relative"]),
            "–" if not rg else _pct(rg["fraction_above_tolerance"]),
            "–" if not rg else "%d / %d" % (rg["search_failures"], rg["score_failures"]),
            _num(dflt["median_time_s"], "%.3f"), _num(dflt["max_time_s"], "%.2f")))
    refs = [(n, rep) for n, rep in rows if (rep["default"].get("reference") or {}).get("starts")]
    if refs:
        lines += ["", "The reference search (%s: the complete search at once, issue 39 item 2) "
                  "from the same starts, against the same truth-refined score: right basin, "
                  "trust, regret, time; the share of starts where the two answers agree (within "
                  "the right-basin thresholds of each other), how often each scores higher by "
                  "more than 1%% of the truth-refined score, and the median ratio of the "
                  "default's time to the reference's:" % refs[0][1]["default"]["reference"]
                  ["strategy"], "",
                  "| dataset | right basin | trust P / R | regret max | search / score failures "
                  "| time median / max (s) | same answer | default / reference higher "
                  "| time default / reference |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for n, rep in refs:
            ref = rep["default"]["reference"]
            rg = ref.get("regret")
            lines.append("| %s | %s | %s / %s | %s | %s | %s / %s | %s | %d / %d | %s |" % (
                n, _pct(ref["right_basin_rate"]), _num(ref["trust_precision"], "%.2f"),
                _num(ref["trust_recall"], "%.2f"),
                "–" if not rg else "%.4g (%.1f%%)" % (rg["max"], 100 * rg["max_relative"]),
                "–" if not rg else "%d / %d" % (rg["search_failures"], rg["score_failures"]),
                _num(ref["median_time_s"], "%.3f"), _num(ref["max_time_s"], "%.2f"),
                _pct(ref["same_answer_rate"]), ref["default_scores_higher"],
                ref["reference_scores_higher"],
                _num(ref["median_time_ratio_default_over_reference"], "%.2fx")))
    basins = [(n, rep["default"]["basin"]) for n, rep in rows if rep["default"].get("basin")]
    if basins:
        lines += ["", "Basin of the default's refinement alone (`--initial-guess` at an offset "
                  "from the truth, `--prior-sigma` as given, initialisation \"given\"): the "
                  "largest offset, each sign, that still ends in the right basin (m, deg; >= : "
                  "the search's limit):", "",
                  "| dataset | prior (deg, m) | x | y | z | forward | yaw |",
                  "|---|---|---|---|---|---|---|"]
        for n, b in basins:
            dirs = b.get("directions") or {}
            prior = b.get("prior_sigma")
            lines.append("| %s | %s | %s |" % (
                n, "–" if not prior else "%g, %g" % tuple(prior),
                " | ".join(_basin_cell(dirs[k]) if k in dirs else "–"
                           for k in ("x_m", "y_m", "z_m", "forward_m", "yaw_deg"))))
    return lines


# --------------------------------------------------------------------------- main

def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--config", default=DEFAULT_CONFIG)
    p.add_argument("--build-dir", default=os.path.join(ROOT, "build"))
    p.add_argument("--lmalign", help="the lmalign binary (default: BUILD_DIR/apps/lmalign/lmalign)")
    p.add_argument("--output", help="output folder (default: BUILD_DIR/bench-accuracy)")
    p.add_argument("--strategies", default="", help="comma list (default: the config's)")
    p.add_argument("--datasets", default="", help="comma list (default: every dataset)")
    p.add_argument("--quick", action="store_true",
                   help="a fraction for developers: 10 random starts and 8 of the 39 protocol "
                        "displacements per dataset (not written to bench/results)")
    p.add_argument("--samples", type=int, help="random starts per dataset (default: config's)")
    p.add_argument("--threads", type=int, default=os.cpu_count() or 2)
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--no-regret", action="store_true",
                   help="skip the default's search regret (and its own alignment per start)")
    p.add_argument("--no-reference", action="store_true",
                   help="skip the reference search (default.reference_strategy of the config: "
                        "the exhaustive preset) from the default's starts")
    p.add_argument("--no-basin", action="store_true",
                   help="skip the default's refinement basin (bisection along each axis)")
    p.add_argument("--peer", help="Open3D's peer binary (default: "
                   "BUILD_DIR/bench/lmalign_peer_open3d_global when built)")
    p.add_argument("--no-peers", action="store_true",
                   help="skip the peers (Open3D FPFH + RANSAC + ICP beside the default)")
    p.add_argument("--no-similarity", action="store_true",
                   help="skip the Sim(3) datasets (the config's similarity: list)")
    return p.parse_args(argv)


def main(argv=None):
    a = parse_args(sys.argv[1:] if argv is None else argv)
    data_dir = os.environ.get("LMALIGN_DATA") or os.path.abspath(
        os.path.join(ROOT, "..", "shared", "data"))
    cfg = load_config(a.config, data_dir)
    lmalign = a.lmalign or os.path.join(a.build_dir, "apps", "lmalign", "lmalign")
    if not os.access(lmalign, os.X_OK):
        raise BenchError("lmalign binary not found: %s (build it, or pass --lmalign)" % lmalign)
    out = os.path.abspath(a.output or os.path.join(a.build_dir, "bench-accuracy"))
    os.makedirs(os.path.join(out, "plots"), exist_ok=True)
    strategies = select(cfg["strategies"], a.strategies, "strategies")
    datasets = select(cfg["datasets"], a.datasets, "datasets")
    random_spec = dict(cfg["random"])
    protocol = protocol_poses()
    if a.quick:
        random_spec["samples"] = 10
        protocol = protocol[::5]
    if a.samples is not None:
        if a.samples < 0:
            raise BenchError("--samples %d: must be >= 0" % a.samples)
        random_spec["samples"] = a.samples
    full = not a.quick and a.samples is None and not a.strategies and not a.datasets

    report = {"date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
              "host": os.uname().nodename, "cores": os.cpu_count(), "threads": a.threads,
              "quick": a.quick, "random": random_spec, "protocol_cases": len(protocol),
              "strategies": strategies, "datasets": {}}
    peer = None if a.no_peers else (a.peer or accuracy_peers.peer_binary(a.build_dir))
    if peer is not None and not os.access(peer, os.X_OK):
        raise BenchError("--peer: not an executable: %s" % peer)
    if peer is None and not a.no_peers:
        print("accuracy benchmark: Open3D's peer (build/bench/lmalign_peer_open3d_global) was "
              "not built (libopen3d-dev missing?): no peers table", flush=True)
    started = time.time()
    prepared = {}
    for d in datasets:
        name = d["name"]
        folder = os.path.join(out, name)
        os.makedirs(folder, exist_ok=True)
        log = os.path.join(folder, "log.txt")
        t0 = time.time()
        source, target, truth = prepare_maps(lmalign, d, os.path.join(folder, "maps"), log)
        prepared[name] = (d, source, target, truth)
        tag = "quick" if a.quick else "full"
        cfg_path = os.path.join(folder, "experiment_%s.yaml" % tag)
        exp = experiment_config(d, source, target, truth, strategies, cfg.get("k", 5),
                                random_spec, protocol)
        write_if_changed(cfg_path, exp)
        rows, counts = run_experiment(lmalign, cfg_path, os.path.join(folder, "runs_" + tag),
                                      a.threads, log)
        rows = [r for r in rows if r["strategy"] in strategies]
        ref_path = os.path.join(folder, "reference.yaml")
        ref_cfg = reference_config(d, source, target, truth, cfg["reference"])
        if truth != "identity":  # start at the truth: D = T_target_source
            ref_cfg["experiments"][0]["poses"] = [truth_pose(truth)]
        write_if_changed(ref_path, ref_cfg)
        ref_rows, ref_counts = run_experiment(lmalign, ref_path, os.path.join(folder, "reference"),
                                              1, log)
        counts = counts or ref_counts or read_counts(folder)
        if counts:
            write_json(os.path.join(folder, "landmarks.json"), list(counts))
        rep = dataset_report(d, rows, ref_rows, counts, strategies)
        if not (a.no_regret and a.no_basin):
            rep["default"] = default_report(lmalign, d, source, target, truth, rows, folder, log,
                                            cfg["default"], a)
        if peer is not None:
            rep["peers"] = peers_report(peer, lmalign, d, source, target, truth, folder, log)
        rep["wall_time_s"] = time.time() - t0
        report["datasets"][name] = rep
        if not a.no_plots:
            plot_dataset(os.path.join(out, "plots", name + ".png"), name, rep)
        print("%-16s %5.0f s  %s" % (name, rep["wall_time_s"], "  ".join(
            "%s %.0f%%" % (s, 100 * m["success_rate"]) for s, m in rep["strategies"].items()
            if m["success_rate"] is not None)), flush=True)
        if rep.get("default"):
            print("%-16s         %s" % ("", default_line(rep["default"])), flush=True)
        if rep.get("peers"):
            p = rep["peers"]
            print("%-16s         Open3D FPFH+RANSAC+ICP: right %d of %d, CPU %.2f s (%s the "
                  "default's)" % ("", p["peer_right_basin"], len(p["peer_runs"]),
                                  p["peer_median_cpu_s"],
                                  "-" if p["cpu_ratio_peer_over_default"] is None
                                  else "%.2fx" % p["cpu_ratio_peer_over_default"]), flush=True)
    # Sim(3): each entry whose rigid dataset ran, on a similarity-moved copy of its source.
    report["similarity"] = {}
    keys = ["x_m", "y_m", "z_m", "roll_deg", "pitch_deg", "yaw_deg"]
    starts = [[p[k] for k in keys] for _, p in protocol_poses()[::5]]
    for e in [] if a.no_similarity else cfg["similarity"]:
        if e["of"] not in prepared:
            continue
        d, source, target, truth = prepared[e["of"]]
        if a.quick:
            e = dict(e, starts=min(e["starts"], 3))
        folder = os.path.join(out, e["name"])
        t0 = time.time()
        try:
            rep = accuracy_similarity.similarity_report(
                lmalign, e, d, source, target, truth, starts, folder,
                os.path.join(folder, "log.txt"))
        except accuracy_similarity.SimilarityError as err:
            raise BenchError(str(err))
        rep["wall_time_s"] = time.time() - t0
        report["similarity"][e["name"]] = rep
        print("%-16s %5.0f s  Sim(3) of %s, scale %g: right basin %s, scale error %s, time "
              "ratio %s" % (e["name"], rep["wall_time_s"], e["of"], e["scale"],
                            _pct(rep["right_basin_rate"]),
                            "-" if rep["median_scale_error"] is None
                            else "%.3f%%" % (100 * rep["median_scale_error"]),
                            "-" if rep["median_time_ratio"] is None
                            else "%.2fx" % rep["median_time_ratio"]), flush=True)
    report["overall"] = overall_report(report["datasets"])
    report["wall_time_s"] = time.time() - started
    write_csv(os.path.join(out, "accuracy.csv"), csv_rows(report))
    write_csv(os.path.join(out, "default.csv"), default_csv_rows(report), DEFAULT_COLUMNS)
    write_csv(os.path.join(out, "similarity.csv"),
              accuracy_similarity.csv_rows(report["similarity"]), accuracy_similarity.COLUMNS)
    write_csv(os.path.join(out, "peers.csv"), accuracy_peers.csv_rows(report["datasets"]),
              accuracy_peers.COLUMNS)
    write_json(os.path.join(out, "accuracy.json"), report)
    write_text(os.path.join(out, "accuracy.md"),
               markdown_tables(report) + accuracy_peers.markdown(report["datasets"]) +
               accuracy_similarity.markdown(report["similarity"]))
    if full:
        write_json(RESULTS_JSON, report)
    print("accuracy benchmark: %s/accuracy.csv, default.csv, peers.csv, similarity.csv, "
          "accuracy.json, "
          "accuracy.md, plots/ "
          "(%.0f s)%s"
          % (out, report["wall_time_s"], "; bench/results/accuracy.json" if full else ""))
    return 0


def truth_pose(path):
    """The 6 pose parameters (x, y, z m; roll, pitch, yaw deg; R = Rz Ry Rx) of a 4x4 file."""
    try:
        rows = accuracy_default.read_transform(path)
    except accuracy_default.DefaultError as e:
        raise BenchError(str(e))
    R = [r[:3] for r in rows[:3]]
    pitch = math.asin(max(-1.0, min(1.0, -R[2][0])))
    roll = math.atan2(R[2][1], R[2][2])
    yaw = math.atan2(R[1][0], R[0][0])
    return {"x_m": rows[0][3], "y_m": rows[1][3], "z_m": rows[2][3],
            "roll_deg": math.degrees(roll), "pitch_deg": math.degrees(pitch),
            "yaw_deg": math.degrees(yaw)}


def write_text(path, text):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def write_if_changed(path, data):
    """Writes the YAML only if its content changed (an unchanged config keeps its results)."""
    import yaml
    text = yaml.safe_dump(data, sort_keys=False, default_flow_style=None)
    if os.path.isfile(path):
        with open(path) as f:
            if f.read() == text:
                return
    write_yaml(path, data)


def read_counts(folder):
    path = os.path.join(folder, "landmarks.json")
    if os.path.isfile(path):
        with open(path) as f:
            return tuple(json.load(f))
    return None


if __name__ == "__main__":
    run_main(main, BenchError, "run_accuracy: error", 2)
