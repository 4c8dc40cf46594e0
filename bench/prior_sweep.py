#!/usr/bin/env python3
"""Wrong and right priors on every real dataset (issue 41): is a trusted answer right?

    python3 bench/prior_sweep.py [--build-dir build] [--datasets a,b] [--wrong N] [--right N]
                                 [--check rivals|strict|off] [--complete-search rescue|check]
                                 [--out DIR] [--jobs N] [--baseline-runs N]

For each real dataset of bench/accuracy.yaml (the desk pair, re-triangulated desk windows, the
KITTI pairs and windows cut from the whole drive; maps prepared as `make bench-accuracy` prepares
them), `lmalign align SOURCE TARGET --initial-guess G --prior-sigma ROT_DEG,TRANS_M` with
`--set init.prior_check=CHECK` (default rivals: the global search checks the prior),
`--set init.prior_complete_search=rescue|check` (check: a merge's prior edges) and
seeded guesses G = D * T_true, D a yaw about the dataset's up axis and a translation:
- wrong guesses (outside 3 sigma): indoors (sigma 2 deg, 5 cm) offsets up to 1 m and any yaw;
  outdoors (sigma 1 deg, 0.3 m) drift-like offsets up to the target map's extent across the up
  axis and yaws up to 10 deg;
- right guesses (inside 1 sigma in rotation and translation).
An answer is right when its errors against the truth are within the dataset kind's thresholds
(`--success-rotation-deg`, `--success-translation-m` of bench/accuracy.yaml's kinds). Reports,
per dataset: trusted wrong answers from wrong guesses (the target is 0), trusted right answers
from right guesses (recall, the target is 95%), and the median time with a prior against the
default's without one (the median of --baseline-runs runs, 3 by default), for right and for
wrong guesses apart. Writes DIR/priors.csv, DIR/priors.json and prints a table; exit 1 when a
wrong guess gave a trusted wrong answer.
"""
import argparse
import csv
import json
import math
import os
import random
import statistics
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import run_accuracy  # noqa: E402

SIGMA = {"indoor": (2.0, 0.05), "outdoor": (1.0, 0.3)}
AXES = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}


def up_vector(text):
    sign = -1.0 if text.startswith("-") else 1.0
    return tuple(sign * v for v in AXES[text.lstrip("+-")])


def rotation_about(axis, angle_rad):
    """Rodrigues: the 3x3 rotation by angle_rad about the unit axis."""
    x, y, z = axis
    c, s, C = math.cos(angle_rad), math.sin(angle_rad), 1.0 - math.cos(angle_rad)
    return [[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
            [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
            [z * x * C - y * s, z * y * C + x * s, c + z * z * C]]


def compose(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def read_matrix(path):
    if path == "identity":
        return [[float(i == j) for j in range(4)] for i in range(4)]
    rows = [[float(v) for v in line.split()] for line in open(path) if line.strip()
            and not line.startswith("#")]
    return rows[:4]


def extent_across(path, up):
    """The target's extent across the up axis (metres): the larger side of its bounding box."""
    lo, hi = [math.inf] * 3, [-math.inf] * 3
    with open(path) as f:
        for line in f:
            if line.startswith("LANDMARK"):
                p = [float(v) for v in line.split()[2:5]]
                lo = [min(a, b) for a, b in zip(lo, p)]
                hi = [max(a, b) for a, b in zip(hi, p)]
    sides = [h - l for h, l, u in zip(hi, lo, up) if u == 0]
    return max(sides) if sides else 1.0


def horizontal_direction(rng, up):
    """A random unit vector across the up axis."""
    a = rng.uniform(0.0, 2.0 * math.pi)
    helper = (1, 0, 0) if abs(up[0]) < 0.9 else (0, 1, 0)
    e1 = [helper[1] * up[2] - helper[2] * up[1], helper[2] * up[0] - helper[0] * up[2],
          helper[0] * up[1] - helper[1] * up[0]]
    n = math.sqrt(sum(v * v for v in e1))
    e1 = [v / n for v in e1]
    e2 = [up[1] * e1[2] - up[2] * e1[1], up[2] * e1[0] - up[0] * e1[2],
          up[0] * e1[1] - up[1] * e1[0]]
    return [math.cos(a) * x + math.sin(a) * y for x, y in zip(e1, e2)]


def guesses(kind, up, extent_m, truth, wrong, right, seed):
    """(label, 4x4 guess, yaw_deg, offset_m) of each seeded guess."""
    rng = random.Random(seed)
    rot_sd, trans_sd = SIGMA[kind]
    out = []
    for i in range(wrong):
        while True:
            if kind == "indoor":
                yaw, off = rng.uniform(-180.0, 180.0), rng.uniform(0.0, 1.0)
            else:
                yaw, off = rng.uniform(-10.0, 10.0), rng.uniform(0.0, extent_m)
            if abs(yaw) > 3.0 * rot_sd or off > 3.0 * trans_sd:
                break
        out.append(("wrong%d" % i, yaw, off))
    for i in range(right):
        out.append(("right%d" % i, rng.uniform(-rot_sd, rot_sd), rng.uniform(0.0, trans_sd)))
    result = []
    for label, yaw, off in out:
        d = horizontal_direction(rng, up)
        R = rotation_about(up, math.radians(yaw))
        D = [R[0] + [off * d[0]], R[1] + [off * d[1]], R[2] + [off * d[2]], [0, 0, 0, 1]]
        result.append((label, compose(D, truth), yaw, off))
    return result


def run_align(lmalign, source, target, truth_path, guess_path, sigma, thresholds, out_json,
              check, complete_search):
    argv = [lmalign, "align", source, target, "--ground-truth", truth_path,
            "--success-rotation-deg", str(thresholds[0]),
            "--success-translation-m", str(thresholds[1]), "--json", out_json]
    if guess_path:
        argv += ["--initial-guess", guess_path, "--prior-sigma", "%g,%g" % sigma, "--set",
                 "init.prior_check=" + check, "--set",
                 "init.prior_complete_search=" + complete_search]
    p = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                       env=dict(os.environ, OMP_NUM_THREADS="1"))
    if p.returncode != 0:
        raise RuntimeError("%s: exit %d: %s" % (" ".join(argv), p.returncode, p.stderr.strip()))
    with open(out_json) as f:
        r = json.load(f)["results"][0]
    return {"right": bool(r["right_basin"]), "trusted": bool(r["trustworthy"]),
            "rotation_error_deg": r["rotation_error_deg"],
            "translation_error_m": r["translation_error_m"], "time_s": r["total_time_s"],
            "reason": r["trust_reason"]}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--build-dir", default=os.path.join(ROOT, "build"))
    parser.add_argument("--datasets", default="", help="comma-separated names (default: every "
                        "real dataset)")
    parser.add_argument("--wrong", type=int, default=20, help="wrong guesses per dataset")
    parser.add_argument("--right", type=int, default=10, help="right guesses per dataset")
    parser.add_argument("--seed", type=int, default=20261125)
    parser.add_argument("--check", default="rivals", choices=["rivals", "strict", "off"],
                        help="init.prior_check of the runs with a prior")
    parser.add_argument("--complete-search", default="rescue", choices=["rescue", "check"],
                        help="init.prior_complete_search of the runs with a prior (check: a "
                        "merge's prior edges)")
    parser.add_argument("--out", default=None, help="output folder (default BUILD/bench-priors)")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
    parser.add_argument("--baseline-runs", type=int, default=3,
                        help="runs without a prior per dataset; the time ratios are against "
                             "their median (one run's time is too noisy for a few per cent)")
    args = parser.parse_args(argv)
    lmalign = os.path.join(args.build_dir, "apps", "lmalign", "lmalign")
    out = args.out or os.path.join(args.build_dir, "bench-priors")
    os.makedirs(out, exist_ok=True)
    data_dir = os.environ.get("LMALIGN_DATA") or os.path.join(os.path.dirname(ROOT), "shared",
                                                              "data")
    cfg = run_accuracy.load_config(run_accuracy.DEFAULT_CONFIG, data_dir)
    real = [d for d in cfg["datasets"] if "simulate" not in d]
    real = run_accuracy.select(real, args.datasets, "datasets")
    jobs = []
    for n, d in enumerate(real):
        folder = os.path.join(out, "maps", d["name"])
        source, target, truth_path = run_accuracy.prepare_maps(
            lmalign, d, folder, os.path.join(out, d["name"] + ".log"))
        kind = d["kind"]
        spec = cfg["kinds"][kind]
        thresholds = (spec["rotation_deg"], spec["translation_m"])
        up = up_vector(d.get("up_axis", "z"))
        truth = read_matrix(truth_path)
        extent = extent_across(target, up)
        os.makedirs(os.path.join(out, "runs", d["name"]), exist_ok=True)
        for b in range(max(1, args.baseline_runs)):
            jobs.append((d["name"], kind, "none" if b == 0 else "none%d" % b, None, 0.0, 0.0,
                         source, target, truth_path, thresholds))
        for label, G, yaw, off in guesses(kind, up, extent, truth, args.wrong, args.right,
                                          args.seed + n):
            path = os.path.join(out, "runs", d["name"], label + ".guess.txt")
            with open(path, "w") as f:
                f.write("\n".join(" ".join(repr(v) for v in row) for row in G) + "\n")
            jobs.append((d["name"], kind, label, path, yaw, off, source, target, truth_path,
                         thresholds))

    def one(job):
        name, kind, label, path, yaw, off, source, target, truth_path, thresholds = job
        r = run_align(lmalign, source, target, truth_path, path, SIGMA[kind], thresholds,
                      os.path.join(out, "runs", name, label + ".json"), args.check,
                      args.complete_search)
        r.update({"dataset": name, "kind": kind, "guess": label, "guess_yaw_deg": yaw,
                  "guess_offset_m": off})
        return r

    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(one, jobs))
    fields = ["dataset", "kind", "guess", "guess_yaw_deg", "guess_offset_m", "right", "trusted",
              "rotation_error_deg", "translation_error_m", "time_s", "reason"]
    with open(os.path.join(out, "priors.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in fields})
    summary = []
    print("%-28s %14s %14s %10s %10s %10s %10s %10s" % (
        "dataset", "trusted wrong", "right trusted", "prior s", "none s", "right/none",
        "wrong/none", "wrong guesses right"))
    bad = 0
    for d in real:
        mine = [r for r in rows if r["dataset"] == d["name"]]
        wrong = [r for r in mine if r["guess"].startswith("wrong")]
        right = [r for r in mine if r["guess"].startswith("right")]
        none = [r for r in mine if r["guess"].startswith("none")]
        tw = sum(1 for r in wrong + right if r["trusted"] and not r["right"])
        rt = sum(1 for r in right if r["trusted"] and r["right"])
        s = {"dataset": d["name"], "trusted_wrong": tw, "wrong_guesses": len(wrong),
             "right_trusted": rt, "right_guesses": len(right),
             "median_time_prior_s": statistics.median(r["time_s"] for r in wrong + right),
             "time_without_prior_s": statistics.median(r["time_s"] for r in none)
             if none else None,
             "time_without_prior_runs_s": [r["time_s"] for r in none],
             "median_time_right_prior_s": statistics.median(r["time_s"] for r in right)
             if right else None,
             "median_time_wrong_prior_s": statistics.median(r["time_s"] for r in wrong)
             if wrong else None,
             "wrong_guesses_answered_right": sum(1 for r in wrong if r["right"])}
        summary.append(s)
        bad += tw
        base = s["time_without_prior_s"] or float("nan")
        for key, t in (("ratio_right_prior", s["median_time_right_prior_s"]),
                       ("ratio_wrong_prior", s["median_time_wrong_prior_s"])):
            s[key] = t / base if t is not None else float("nan")
        print("%-28s %8d of %-3d %8d of %-3d %10.2f %10.2f %9.2fx %9.2fx %10d" % (
            d["name"], tw, len(wrong) + len(right), rt, len(right), s["median_time_prior_s"],
            base, s["ratio_right_prior"], s["ratio_wrong_prior"],
            s["wrong_guesses_answered_right"]))
    with open(os.path.join(out, "priors.json"), "w") as f:
        json.dump({"seed": args.seed, "sigma": SIGMA, "check": args.check, "datasets": summary, "runs": rows}, f,
                  indent=1)
    print("written: %s" % os.path.join(out, "priors.csv"))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
