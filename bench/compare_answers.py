#!/usr/bin/env python3
"""Are two builds' answers the same? For refactors that must not change results (docs/
architecture.md, "Changing the engine").

    python3 bench/compare_answers.py record DIR [--lmalign BIN] [--datasets a,b] [--starts N]
    python3 bench/compare_answers.py compare DIR [--lmalign BIN] [...]

For every dataset of bench/accuracy.yaml (its maps prepared as `make bench-accuracy` prepares
them, into DIR/maps) it runs `lmalign align SOURCE TARGET --strategy S --displace D --json` for
the default (no --strategy), the paper's four (--strategy paper) and, with --similarity, the
default on the dataset's Sim(3) variants of bench/accuracy.yaml; from the first N protocol
displacements (method.md §5; default 2). `record` writes each run's JSON into DIR; `compare`
runs the same with BIN and reports every difference of the whole JSON except the times
(wall_time_s, total_time_s, time_ms and the like): exit 0 when every run is identical, 1 when
any differs (each difference named: dataset, run, JSON path, both values). --new-keys-ok:
keys that only the new JSON has (a setting or a field added) are not differences.
"""
import argparse
import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import run_accuracy  # noqa: E402

TIME_KEYS = {"wall_time_s", "total_time_s", "time_ms", "time_s", "median_time_s"}


def strip_times(value):
    if isinstance(value, dict):
        return {k: strip_times(v) for k, v in value.items() if k not in TIME_KEYS}
    if isinstance(value, list):
        return [strip_times(v) for v in value]
    return value


def differences(a, b, path="", out=None, limit=20, new_keys_ok=False):
    out = [] if out is None else out
    if len(out) >= limit:
        return out
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a and new_keys_ok:
                continue
            if k not in a or k not in b:
                out.append("%s/%s: only in %s" % (path, k, "the reference" if k in a else "this"))
            else:
                differences(a[k], b[k], path + "/" + k, out, limit, new_keys_ok)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append("%s: %d items against %d" % (path, len(a), len(b)))
        for i, (x, y) in enumerate(zip(a, b)):
            differences(x, y, "%s[%d]" % (path, i), out, limit, new_keys_ok)
    elif a != b:
        out.append("%s: %r against %r" % (path, a, b))
    return out


def displacement_text(pose):
    return ",".join(str(pose[k]) for k in ("x_m", "y_m", "z_m", "roll_deg", "pitch_deg",
                                           "yaw_deg"))


def runs_of(cfg, dirs, lmalign, starts, similarity):
    """(name, argv) of every run."""
    runs = []
    poses = [p for _, p in run_accuracy.protocol_poses()][:starts]
    for d in cfg["datasets"]:
        folder = os.path.join(dirs, "maps", d["name"])
        log = os.path.join(dirs, "maps", d["name"] + ".log")
        os.makedirs(os.path.dirname(log), exist_ok=True)
        source, target, _ = run_accuracy.prepare_maps(lmalign, d, folder, log)
        for i, pose in enumerate(poses):
            for label, strategy in (("default", None), ("paper", "paper")):
                argv = [lmalign, "align", source, target, "--displace", displacement_text(pose)]
                if strategy:
                    argv += ["--strategy", strategy]
                runs.append(("%s.%s.start%d" % (d["name"], label, i), argv))
    if similarity:
        import accuracy_similarity
        for s in cfg.get("similarity") or []:
            base = next(d for d in cfg["datasets"] if d["name"] == s["of"])
            folder = os.path.join(dirs, "maps", base["name"])
            source, target, truth = run_accuracy.prepare_maps(lmalign, base, folder, "/dev/null")
            moved, _ = accuracy_similarity.make_pair(lmalign, s, source, truth,
                                                     os.path.join(dirs, "maps", s["name"]),
                                                     "/dev/null")
            runs.append(("%s.default" % s["name"], [lmalign, "align", moved, target]))
    return runs


def run_one(name, argv, out_json):
    p = subprocess.run(argv + ["--json", out_json], stdout=subprocess.DEVNULL,
                       stderr=subprocess.PIPE, text=True, env=dict(os.environ, OMP_NUM_THREADS="1"))
    if p.returncode != 0:
        return name, "exit %d: %s" % (p.returncode, p.stderr.strip().splitlines()[-1:])
    return name, None


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("mode", choices=("record", "compare"))
    parser.add_argument("dir")
    parser.add_argument("--lmalign", default=os.path.join(ROOT, "build", "apps", "lmalign",
                                                          "lmalign"))
    parser.add_argument("--datasets", default="")
    parser.add_argument("--starts", type=int, default=2)
    parser.add_argument("--similarity", action="store_true")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
    parser.add_argument("--new-keys-ok", action="store_true",
                        help="keys only in the new JSON (a new setting, a new field) are no "
                        "difference")
    args = parser.parse_args(argv)
    data_dir = os.environ.get("LMALIGN_DATA") or os.path.join(os.path.dirname(ROOT), "shared",
                                                              "data")
    cfg = run_accuracy.load_config(run_accuracy.DEFAULT_CONFIG, data_dir)
    cfg["datasets"] = run_accuracy.select(cfg["datasets"], args.datasets, "datasets")
    if args.datasets:
        keep = {d["name"] for d in cfg["datasets"]}
        cfg["similarity"] = [s for s in cfg.get("similarity") or [] if s["of"] in keep]
    runs = runs_of(cfg, args.dir, args.lmalign, args.starts, args.similarity)
    sub = "reference" if args.mode == "record" else "candidate"
    os.makedirs(os.path.join(args.dir, sub), exist_ok=True)
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        done = list(pool.map(lambda r: run_one(r[0], r[1], os.path.join(args.dir, sub,
                                                                         r[0] + ".json")), runs))
    failed = [(n, e) for n, e in done if e]
    for n, e in failed:
        print("%s: %s" % (n, e))
    if args.mode == "record":
        print("recorded %d runs in %s" % (len(runs) - len(failed), os.path.join(args.dir, sub)))
        return 1 if failed else 0
    changed = 0
    for name, _ in runs:
        ref = os.path.join(args.dir, "reference", name + ".json")
        new = os.path.join(args.dir, sub, name + ".json")
        if not (os.path.isfile(ref) and os.path.isfile(new)):
            continue
        with open(ref) as f:
            a = strip_times(json.load(f))
        with open(new) as f:
            b = strip_times(json.load(f))
        diff = differences(a, b, new_keys_ok=args.new_keys_ok)
        if diff:
            changed += 1
            print("%s: %d difference(s)" % (name, len(diff)))
            for line in diff[:8]:
                print("  " + line)
    print("%d of %d runs identical (whole JSON but times)" % (len(runs) - changed - len(failed),
                                                             len(runs)))
    return 1 if changed or failed else 0


if __name__ == "__main__":
    sys.exit(main())
