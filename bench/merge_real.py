#!/usr/bin/env python3
"""Merge benchmark on maps cut into windows (configs/merge_desk.yaml, merge_kitti.yaml,
merge_kitti_retri.yaml, merge_streets.yaml).

    merge_real.py CONFIG.yaml [--build-dir build] [--case NAME] [--resume]

For each case of the config: makes the windows, either
  - `map:` cut with `lmalign split --frames A-B` (`windows: {first, length, step, count}`; with
    `split: {retriangulate: true, min_parallax_deg, intrinsics}` each window's landmarks are
    re-estimated from its own pixels), or
  - `simulate:` `lmalign simulate --scene street --windows N` (`{windows, frames, overlap,
    landmarks, seed}`: consecutive windows of one simulated drive, each in its own first
    keyframe's frame, with the simulator's truth),
(a case may replace keys of `simulate`, `windows` and `split`, and the poses' seed with
`poses: {seed: S}`),
then moves each window by a seeded random pose (a yaw uniform in [-180, 180) deg about the maps'
up axis -- the mean of the frames' -y axes, the camera convention of docs/map-format.md -- and a
translation uniform in the ball of max_translation_m), writes manifest.yaml (with noisy priors
when the case has prior_sigma: [rot_deg, trans_m], left perturbation in the world frame as
manifest.hpp) and ground_truth.yaml, then runs `lmalign merge --ground-truth` (every edge
aligned afresh unless --resume), prints its report and a summary line, and writes the summary to
bench.json beside the manifest: the parts, the neighbouring windows' edges (found = kept by the
graph and true; else why not), false edges kept, the pairs of maps whose relative pose is within
the thresholds, and the times. Real maps are read from $LMALIGN_DATA (default ../shared/data beside the repository);
nothing is copied into the repository. Every file is written to a temporary name and renamed.
Needs numpy and PyYAML.
"""

import argparse
import csv
import json
import os
import re
import shutil
import subprocess
import sys
import time

import numpy as np
import yaml

HERE = os.path.dirname(os.path.abspath(__file__))


def data_dir():
    env = os.environ.get("LMALIGN_DATA")
    return env if env else os.path.normpath(os.path.join(HERE, "..", "..", "shared", "data"))


def write_atomic(path, text):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def quat_to_matrix(w, x, y, z):
    n = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def matrix_to_quat(R):
    w = np.sqrt(max(0.0, 1 + R[0, 0] + R[1, 1] + R[2, 2])) / 2
    x = np.copysign(np.sqrt(max(0.0, 1 + R[0, 0] - R[1, 1] - R[2, 2])) / 2, R[2, 1] - R[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1 - R[0, 0] + R[1, 1] - R[2, 2])) / 2, R[0, 2] - R[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1 - R[0, 0] - R[1, 1] + R[2, 2])) / 2, R[1, 0] - R[0, 1])
    return w, x, y, z


def axis_angle(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def read_lines(path):
    with open(path) as f:
        return f.read().splitlines()


def up_axis(lines):
    up = np.zeros(3)
    for line in lines:
        if line.startswith("FRAME"):
            v = [float(t) for t in line.split()[2:9]]
            up -= quat_to_matrix(*v[3:7])[:, 1]
    return up / np.linalg.norm(up)


def transform_map(lines, T):
    """The map's records moved by T (p_new = T p_old): frames, positions, covariances."""
    R, t = T[:3, :3], T[:3, 3]
    out = []
    for line in lines:
        f = line.split()
        if f and f[0] == "FRAME":
            p = R @ np.array([float(v) for v in f[2:5]]) + t
            q = matrix_to_quat(R @ quat_to_matrix(*[float(v) for v in f[5:9]]))
            out.append(" ".join([f[0], f[1]] + ["%.17g" % v for v in (*p, *q)]))
        elif f and f[0] == "LANDMARK":
            p = R @ np.array([float(v) for v in f[2:5]]) + t
            C = R @ np.array([float(v) for v in f[5:14]]).reshape(3, 3) @ R.T
            out.append(" ".join([f[0], f[1]] + ["%.17g" % v for v in (*p, *C.reshape(-1))] + f[14:]))
        else:
            out.append(line)
    return "\n".join(out) + "\n"


def rows(M):
    return "[" + ", ".join("[" + ", ".join("%.17g" % v for v in r) + "]" for r in M) + "]"


def read_truth(path):
    """T_world_map per name of a ground_truth.yaml (as lmalign simulate writes it)."""
    with open(path) as f:
        return {n: np.array(T, dtype=float) for n, T in yaml.safe_load(f)["maps"].items()}


def make_windows(cfg, lmalign, folder):
    """(name, path of the window in its own frame, its true T_world_map) per window."""
    if "simulate" in cfg:
        s = cfg["simulate"]
        sim = os.path.join(folder, "simulated")
        if not os.path.isfile(os.path.join(sim, "manifest.yaml")):
            subprocess.run([lmalign, "simulate", "--scene", s.get("scene", "street"),
                            "--windows", str(s["windows"]), "--frames", str(s.get("frames", 30)),
                            "--overlap", str(s.get("overlap", 0.25)),
                            "--landmarks", str(s.get("landmarks", 3000)),
                            "--seed", str(s.get("seed", 1)), "-o", sim],
                           check=True, stdout=subprocess.DEVNULL)
        truth = read_truth(os.path.join(sim, "ground_truth.yaml"))
        return [(n, os.path.join(sim, "maps", n + ".txt"), truth[n]) for n in sorted(
            truth, key=lambda n: int(n[1:]))]
    path = cfg["map"].replace("${LMALIGN_DATA}", data_dir())
    if not os.path.exists(path):
        sys.exit("merge_real.py: real data not found: %s (set LMALIGN_DATA)" % path)
    w, sp = cfg["windows"], cfg.get("split", {})
    out = []
    for k in range(w["count"]):
        a = w["first"] + k * w["step"]
        cut = os.path.join(folder, "maps", "cut%d.txt" % k)
        cmd = [lmalign, "split", path, "--frames", "%d-%d" % (a, a + w["length"] - 1)]
        if sp.get("retriangulate"):
            cmd += ["--retriangulate", "--min-parallax", str(sp.get("min_parallax_deg", 2))]
            if "intrinsics" in sp:
                cmd += ["--intrinsics", str(sp["intrinsics"])]
        subprocess.run(cmd + ["-o", cut], check=True, stdout=subprocess.DEVNULL)
        out.append(("w%d" % k, cut, np.eye(4)))  # split keeps the map's frame: the truth's
    return out


def case_config(cfg, case):
    """The config as a case sees it: the case's own `simulate`, `windows`, `split` (merged key
    by key) and `seed` replace the config's."""
    out = dict(cfg)
    for key in ("simulate", "windows", "split"):
        if key in case:
            out[key] = {**cfg.get(key, {}), **case[key]}
    if "seed" in case.get("poses", {}):
        out["seed"] = case["poses"]["seed"]
    return out


def run_case(cfg, case, lmalign, out_root, name, resume):
    cfg = case_config(cfg, case)
    rng = np.random.default_rng(cfg["seed"])
    folder = os.path.join(out_root, "%s_%s" % (name, case["name"]))
    os.makedirs(os.path.join(folder, "maps"), exist_ok=True)
    windows = make_windows(cfg, lmalign, folder)
    up = up_axis(read_lines(windows[0][1]))
    if "map" in cfg:  # the whole map's frames (as before: the same seeded poses)
        up = up_axis(read_lines(cfg["map"].replace("${LMALIGN_DATA}", data_dir())))
    truth = {}
    for n, path, T_world_window in windows:
        T_map_world = np.eye(4)
        T_map_world[:3, :3] = axis_angle(up, rng.uniform(-np.pi, np.pi))
        v = rng.uniform(-1, 1, 3)
        T_map_world[:3, 3] = cfg["max_translation_m"] * v / max(1.0, np.linalg.norm(v))
        write_atomic(os.path.join(folder, "maps", n + ".txt"),
                     transform_map(read_lines(path), T_map_world))
        if "map" in cfg:
            os.remove(path)
        truth[n] = T_world_window @ np.linalg.inv(T_map_world)
    write_atomic(os.path.join(folder, "ground_truth.yaml"),
                 "maps:\n" + "".join("  %s: %s\n" % (n, rows(T)) for n, T in truth.items()))
    manifest = "maps:\n"
    prng = np.random.default_rng(case.get("seed", 0))
    for n, T in truth.items():
        manifest += "  - name: %s\n    path: maps/%s.txt\n" % (n, n)
        if "prior_sigma" in case:
            sd_deg, sd_m = case["prior_sigma"]
            phi = np.radians(sd_deg) * prng.standard_normal(3)
            D = np.eye(4)
            if np.linalg.norm(phi) > 0:
                D[:3, :3] = axis_angle(phi, np.linalg.norm(phi))
            D[:3, 3] = sd_m * prng.standard_normal(3)
            manifest += "    T_world_map: %s\n    prior_sigma: [%g, %g]\n" % (rows(D @ T), sd_deg,
                                                                              sd_m)
    write_atomic(os.path.join(folder, "manifest.yaml"), manifest)
    th = cfg["thresholds"]
    cmd = [lmalign, "merge", os.path.join(folder, "manifest.yaml"), "-o",
           os.path.join(folder, "out"), "--ground-truth", os.path.join(folder, "ground_truth.yaml"),
           "--thresholds", "%g,%g" % (th["rotation_deg"], th["translation_m"])]
    if resume:
        cmd.append("--resume")
    else:  # the folder is this script's own: an earlier run's edges would be refused
        shutil.rmtree(os.path.join(folder, "out"), ignore_errors=True)
    print("$ " + " ".join(cmd), flush=True)
    t0 = time.monotonic()
    run = subprocess.run(cmd, stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    wall_s = time.monotonic() - t0
    sys.stdout.write(run.stdout)
    if run.returncode != 0:
        sys.stdout.write("".join(run.stderr.splitlines(True)[-3:]))
        return run.returncode
    summary = summarise(os.path.join(folder, "out"), [w[0] for w in windows], truth, th)
    m = re.search(r"time: edges ([0-9.]+) s, graph ([0-9.]+) s", run.stdout)
    summary.update(edge_seconds=float(m.group(1)) if m else None,
                   graph_seconds=float(m.group(2)) if m else None, wall_seconds=wall_s,
                   resumed=resume, config=name, case=case["name"])
    write_atomic(os.path.join(folder, "bench.json"), json.dumps(summary, indent=1) + "\n")
    print("summary: %d part(s); neighbouring edges %d of %d (%s); pairs within %d of %d; "
          "false edges kept %d; edges %.1f s, wall %.1f s -> %s" % (
              summary["parts"], summary["neighbour_edges_found"], summary["neighbour_pairs"],
              ", ".join("%s-%s %s" % (e["source"], e["target"], e["status"])
                        for e in summary["neighbour_edges"]),
              summary["pairs_within"], summary["pairs"], summary["false_edges_kept"],
              summary["edge_seconds"] or float("nan"), wall_s,
              os.path.join(folder, "bench.json")), flush=True)
    return 0


def rotation_deg(R):
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))))


def within(T_est, T_true, th):
    D = T_est @ np.linalg.inv(T_true)
    return (rotation_deg(D[:3, :3]) <= th["rotation_deg"] and
            float(np.linalg.norm(D[:3, 3])) <= th["translation_m"])


def summarise(out, names, truth, th):
    """What the issue's target asks of a merge of consecutive windows: its parts, which
    neighbouring pairs (windows k and k+1) got an edge that the graph kept and that agrees with
    the truth (at the frame origins, the thresholds of the config, as `lmalign merge
    --ground-truth`), and every pair's relative pose within the thresholds."""
    with open(os.path.join(out, "poses.json")) as f:
        poses = {m["name"]: m for m in json.load(f)["maps"]}
    with open(os.path.join(out, "edges.csv")) as f:
        rows_ = list(csv.DictReader(f))
    edges = {(r["source"], r["target"]): r for r in rows_}
    est = {n: np.array(poses[n]["T_world_map"]) for n in names}
    comp = {n: poses[n]["component"] for n in names}

    def edge_true(s, t):
        with open(os.path.join(out, "edges", "%s__%s.json" % (s, t))) as f:
            T = np.array(json.load(f)["T_target_source"])
        return within(T, np.linalg.inv(truth[t]) @ truth[s], th)

    neighbours = []
    for s, t in zip(names, names[1:]):
        r = edges.get((s, t))
        if r is None:
            status = "not a candidate"
        else:
            true = edge_true(s, t)
            kept = r["used"] == "1" and r["rejected"] == "0"
            status = ("found" if kept and true else "kept but false" if kept else
                      ("right, refused: " if true else "wrong, refused: ") + r["reason"])
        neighbours.append({"source": s, "target": t, "status": status})
    false_kept = sum(1 for (s, t), r in edges.items()
                     if r["used"] == "1" and r["rejected"] == "0" and not edge_true(s, t))
    pairs = pairs_within = 0
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            pairs += 1
            if comp[a] == comp[b] and within(np.linalg.inv(est[a]) @ est[b],
                                             np.linalg.inv(truth[a]) @ truth[b], th):
                pairs_within += 1
    return {"maps": len(names), "parts": len(set(comp.values())), "candidates": len(rows_),
            "trusted": sum(r["trusted"] == "1" for r in rows_),
            "neighbour_pairs": len(neighbours),
            "neighbour_edges_found": sum(e["status"] == "found" for e in neighbours),
            "neighbour_edges": neighbours, "false_edges_kept": false_kept, "pairs": pairs,
            "pairs_within": pairs_within}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("config")
    p.add_argument("--build-dir", default=os.path.join(HERE, "..", "build"))
    p.add_argument("--case", default=None)
    p.add_argument("--resume", action="store_true",
                   help="reuse the edges of an earlier run (their cache key does not know the "
                        "library's code: only after an interruption of the same build)")
    a = p.parse_args()
    with open(a.config) as f:
        cfg = yaml.safe_load(f)
    lmalign = os.path.join(a.build_dir, "apps", "lmalign", "lmalign")
    name = os.path.splitext(os.path.basename(a.config))[0].replace("merge_", "")
    out_root = os.path.join(a.build_dir, "bench-merge")
    rc = 0
    for case in cfg["cases"]:
        if a.case is None or case["name"] == a.case:
            rc |= run_case(cfg, case, lmalign, out_root, name, a.resume)
    sys.exit(rc)


if __name__ == "__main__":
    main()
