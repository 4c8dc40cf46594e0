"""Peers of the default's global search, for bench/run_accuracy.py and bench/size_sweep.py
(issue 39, item 5; docs/accuracy.md, "Peers").

Open3D's global registration (FPFH features, RANSAC on feature matches, ICP: the recipe of its
tutorial, bench/peer_open3d_global.cpp, built when CMake finds libopen3d-dev) runs on the same
map pair as the default, one thread each:

- the peer from `PEER_SEEDS` RANSAC seeds on the maps as given (it is global: its answer does not
  depend on a start), each classified right basin or not by the dataset's thresholds, its
  rotation and translation errors and the CPU seconds of its registration (not reading the maps);
- the default (`lmalign align`, no --strategy) once on the maps as given, OMP_NUM_THREADS=1, its
  alignment time from the JSON (`wall_time_s`; one thread, so CPU time), answer and verdict.

The ratio is the peer's median CPU time over the default's: above 1, the default is cheaper.
"""
import hashlib
import json
import os
import statistics
import subprocess

import accuracy_default

# RANSAC seeds per dataset: the peer's spread, not one lucky draw.
PEER_SEEDS = (1, 2, 3)
PEER_NAME = "open3d_fpfh_ransac_icp"
COLUMNS = ["dataset", "landmarks", "default_right", "default_trusted", "default_rotation_error_deg",
           "default_translation_error_m", "default_time_s", "peer", "peer_right",
           "peer_runs", "peer_rotation_error_deg", "peer_translation_error_m",
           "peer_median_cpu_s", "cpu_ratio_peer_over_default"]


class PeerError(Exception):
    """A one-line error (a failed peer command)."""


def peer_binary(build_dir):
    """The Open3D peer's executable under build_dir, or None when it was not built."""
    path = os.path.join(build_dir, "bench", "lmalign_peer_open3d_global")
    return path if os.access(path, os.X_OK) else None


def run_peer(binary, source, target, seed, cache_dir, log):
    """One peer run (its JSON as a dict), cached in cache_dir by its arguments and binary."""
    st = os.stat(binary)
    key = hashlib.sha1("\n".join([os.path.abspath(binary), str(st.st_size), str(st.st_mtime_ns),
                                   source, target, str(seed)]).encode()).hexdigest()[:20]
    out = os.path.join(cache_dir, key + ".json")
    if os.path.isfile(out):
        with open(out) as f:
            return json.load(f)
    os.makedirs(cache_dir, exist_ok=True)
    cmd = [binary, "--source", source, "--target", target, "--seed", str(seed)]
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    with open(log, "a") as f:
        f.write("$ " + " ".join(cmd) + "\n" + p.stderr)
    if p.returncode != 0:
        last = (p.stderr.strip().splitlines() or ["exit code %d" % p.returncode])[-1]
        raise PeerError("%s failed: %s (log: %s)" % (os.path.basename(binary), last, log))
    result = json.loads(p.stdout)
    tmp = out + ".tmp"
    with open(tmp, "w") as f:
        json.dump(result, f)
    os.replace(tmp, out)
    return result


def peer_report(binary, aligner, source, target, thresholds, folder, log):
    """The peer and the default on one map pair: a dict for accuracy.json (see the module's
    docstring). `aligner` is the dataset's accuracy_default.Aligner (its truth and its cache)."""
    rot_max, trans_max = thresholds
    runs = []
    for seed in PEER_SEEDS:
        r = run_peer(binary, source, target, seed, os.path.join(folder, "peers"), log)
        rot, trans = accuracy_default.pose_errors(r["T_target_source"], aligner.T_true)
        runs.append({"seed": seed, "right_basin": rot <= rot_max and trans <= trans_max,
                     "rotation_error_deg": rot, "translation_error_m": trans,
                     "cpu_s": r["cpu_s"], "voxel_m": r["voxel_m"]})
    d = aligner.run(displace=[0.0] * 6, omp_threads=1)
    peer_cpu = statistics.median(r["cpu_s"] for r in runs)
    default_time = d.get("wall_time_s")
    right = [r for r in runs if r["right_basin"]]
    return {
        "peer": PEER_NAME,
        "peer_runs": runs,
        "peer_right_basin": len(right),
        "peer_median_cpu_s": peer_cpu,
        "peer_median_rotation_error_deg": statistics.median(r["rotation_error_deg"] for r in runs),
        "peer_median_translation_error_m": statistics.median(
            r["translation_error_m"] for r in runs),
        "default": {"right_basin": bool(d.get("right_basin")),
                    "trustworthy": bool(d.get("trustworthy")),
                    "rotation_error_deg": d.get("rotation_error_deg"),
                    "translation_error_m": d.get("translation_error_m"),
                    "time_s": default_time},
        "cpu_ratio_peer_over_default": (peer_cpu / default_time
                                        if default_time and default_time > 0 else None),
    }


def csv_rows(datasets):
    """Rows of peers.csv from report["datasets"] (those with a "peers" entry)."""
    out = []
    for name, rep in datasets.items():
        p = rep.get("peers")
        if not p:
            continue
        lm = rep.get("landmarks") or {}
        d = p["default"]
        out.append({"dataset": name,
                    "landmarks": "%s / %s" % (lm.get("source"), lm.get("target")),
                    "default_right": d["right_basin"], "default_trusted": d["trustworthy"],
                    "default_rotation_error_deg": d["rotation_error_deg"],
                    "default_translation_error_m": d["translation_error_m"],
                    "default_time_s": d["time_s"], "peer": p["peer"],
                    "peer_right": p["peer_right_basin"], "peer_runs": len(p["peer_runs"]),
                    "peer_rotation_error_deg": p["peer_median_rotation_error_deg"],
                    "peer_translation_error_m": p["peer_median_translation_error_m"],
                    "peer_median_cpu_s": p["peer_median_cpu_s"],
                    "cpu_ratio_peer_over_default": p["cpu_ratio_peer_over_default"]})
    return out


def _err(rot, trans):
    return "-" if rot is None else "%.2f° / %.3g m" % (rot, trans)


def markdown(datasets):
    """The peers' table of accuracy.md (Markdown text), empty when no dataset has one."""
    rows = csv_rows(datasets)
    if not rows:
        return ""
    lines = ["", "Peers on the maps as given, one thread each (bench/accuracy_peers.py): the "
             "default once (right basin, trusted, errors, alignment time) and Open3D FPFH + "
             "RANSAC + ICP from %d RANSAC seeds (right basin of them, median errors, median CPU "
             "of its registration); ratio = the peer's CPU over the default's:" % len(PEER_SEEDS),
             "", "| dataset | landmarks | default | default time (s) | Open3D right | Open3D "
             "median error | Open3D CPU (s) | ratio |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append("| %s | %s | %s, %s, %s | %s | %d of %d | %s | %.2f | %s |" % (
            r["dataset"], r["landmarks"], "right" if r["default_right"] else "wrong",
            "trusted" if r["default_trusted"] else "refused",
            _err(r["default_rotation_error_deg"], r["default_translation_error_m"]),
            "-" if r["default_time_s"] is None else "%.2f" % r["default_time_s"],
            r["peer_right"], r["peer_runs"],
            _err(r["peer_rotation_error_deg"], r["peer_translation_error_m"]),
            r["peer_median_cpu_s"],
            "-" if r["cpu_ratio_peer_over_default"] is None
            else "%.2fx" % r["cpu_ratio_peer_over_default"]))
    return "\n".join(lines) + "\n"
