#!/usr/bin/env python3
"""The size sweep of the default's global search (issue 39, item 6; docs/accuracy.md, "Size sweep").

    make bench-sizes                                  # = python3 bench/size_sweep.py
    python3 bench/size_sweep.py --sizes 1000,3000 --seeds 1,2

Simulated streets (`lmalign simulate --scene street --overlap 0.25`) at each size (landmarks per
map), each seed and each true transform: the default (`lmalign align`, no --strategy, one thread:
OMP_NUM_THREADS=1) and its peer Open3D FPFH + RANSAC + ICP (bench/accuracy_peers.py, seed 1) on
the same pair. Per run: right basin (5 deg / 1 m, as the issue's street seeds), trusted, errors,
the gated score, and the time (the default's whole call from its JSON, the verdict and its
half-sample covariance included, as `lmalign align` spends it: total_time_s, one thread; the
alignment alone, wall_time_s, beside it; the peer's CPU seconds). Until 2026-11-28 the time was
the alignment alone, without the verdict (1.2 s of 2.3 s on a 15,000-landmark pair). Per size: right and trusted counts, median and max time, the time per 1,000
landmarks (linear growth keeps it flat), and the peer's.

A window of 30 keyframes sees about 32,000 features, so the largest size takes longer windows
(FRAMES below: 250 keyframes, about 250 m of street). Output in --output (default
build/bench-sizes): sizes.csv (one row per run), sizes.json, sizes.md; the maps and the runs'
JSON are kept there and reused by a rerun with the same binaries.
"""
import argparse
import os
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import accuracy_default  # noqa: E402
import accuracy_peers  # noqa: E402
from run_accuracy import run_main, write_csv, write_json, write_text  # noqa: E402

# Keyframes per window by size: enough features for the landmarks asked for.
FRAMES = {60000: 250}
DEFAULT_FRAMES = 30
# The true transforms (x, y, z m, roll, pitch, yaw deg): the and a second one.
TRANSFORMS = ["20,5,0,0,0,120", "-35,12,0,0,0,-75"]
THRESHOLDS = (5.0, 1.0)  # right basin: deg, m
COLUMNS = ["landmarks", "frames", "seed", "transform", "default_right", "default_trusted",
           "default_rotation_error_deg", "default_translation_error_m", "default_gated_score",
           "default_time_s", "default_alignment_time_s", "peer_right", "peer_rotation_error_deg", "peer_translation_error_m",
           "peer_cpu_s"]


class SweepError(Exception):
    """A one-line error for the user."""


def parse_list(text, cast, what):
    try:
        out = [cast(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise SweepError("%s: expected a comma list of numbers, got %r" % (what, text))
    if not out:
        raise SweepError("%s: empty" % what)
    return out


def simulate(lmalign, size, seed, transform, folder, log):
    truth = os.path.join(folder, "T_target_source.txt")
    if not os.path.isfile(truth):  # written last by lmalign simulate
        cmd = [lmalign, "simulate", "--scene", "street", "--overlap", "0.25", "--frames",
               str(FRAMES.get(size, DEFAULT_FRAMES)), "--landmarks", str(size), "--transform",
               transform, "--seed", str(seed), "--output", folder]
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        with open(log, "a") as f:
            f.write("$ " + " ".join(cmd) + "\n" + p.stderr)
        if p.returncode != 0:
            raise SweepError("lmalign simulate failed: %s" % p.stderr.strip().splitlines()[-1:])
    return os.path.join(folder, "source.txt"), os.path.join(folder, "target.txt"), truth


def one_run(lmalign, peer, size, seed, transform, folder, log):
    source, target, truth = simulate(lmalign, size, seed, transform, folder, log)
    aligner = accuracy_default.Aligner(lmalign, source, target, truth, THRESHOLDS,
                                       os.path.join(folder, "default"), log)
    d = aligner.run(displace=[0.0] * 6, omp_threads=1)
    row = {"landmarks": size, "frames": FRAMES.get(size, DEFAULT_FRAMES), "seed": seed,
           "transform": transform, "default_right": bool(d.get("right_basin")),
           "default_trusted": bool(d.get("trustworthy")),
           "default_rotation_error_deg": d.get("rotation_error_deg"),
           "default_translation_error_m": d.get("translation_error_m"),
           "default_gated_score": d.get("gated_score"), "default_time_s": d.get("total_time_s"),
           "default_alignment_time_s": d.get("wall_time_s")}
    if peer is not None:
        r = accuracy_peers.run_peer(peer, source, target, 1, os.path.join(folder, "peers"), log)
        rot, trans = accuracy_default.pose_errors(r["T_target_source"], aligner.T_true)
        row.update({"peer_right": rot <= THRESHOLDS[0] and trans <= THRESHOLDS[1],
                    "peer_rotation_error_deg": rot, "peer_translation_error_m": trans,
                    "peer_cpu_s": r["cpu_s"]})
    return row


def summary(rows):
    """Per size: counts, times and the time per 1,000 landmarks."""
    out = {}
    for size in sorted({r["landmarks"] for r in rows}):
        rs = [r for r in rows if r["landmarks"] == size]
        times = [r["default_time_s"] for r in rs if r["default_time_s"] is not None]
        peer = [r["peer_cpu_s"] for r in rs if r.get("peer_cpu_s") is not None]
        out[size] = {
            "runs": len(rs),
            "default_right": sum(1 for r in rs if r["default_right"]),
            "default_trusted": sum(1 for r in rs if r["default_trusted"]),
            "default_trusted_wrong": sum(1 for r in rs
                                         if r["default_trusted"] and not r["default_right"]),
            "default_median_time_s": statistics.median(times) if times else None,
            "default_max_time_s": max(times) if times else None,
            "default_median_time_per_1000_s": (statistics.median(times) * 1000.0 / size
                                               if times else None),
            "peer_right": sum(1 for r in rs if r.get("peer_right")) if peer else None,
            "peer_median_cpu_s": statistics.median(peer) if peer else None,
        }
    return out


def markdown(report):
    s = report["sizes"]
    lines = ["Size sweep (bench/size_sweep.py), %s, %s, %d cores: simulated streets, overlap 0.25, "
             "seeds %s, transforms %s; one thread each; right = within %g deg / %g m." % (
                 report["date_utc"], report["host"], report["cores"],
                 ",".join(str(v) for v in report["seeds"]), " and ".join(report["transforms"]),
                 THRESHOLDS[0], THRESHOLDS[1]), "",
             "| landmarks per map | runs | default right | trusted (wrong) | default time "
             "median / max (s) | per 1,000 landmarks (s) | Open3D right | Open3D CPU median (s) |",
             "|---|---|---|---|---|---|---|---|"]

    def num(v, fmt):
        return "-" if v is None else fmt % v

    for size, m in s.items():
        lines.append("| %s | %d | %d | %d (%d) | %s / %s | %s | %s | %s |" % (
            "{:,}".format(int(size)), m["runs"], m["default_right"], m["default_trusted"],
            m["default_trusted_wrong"], num(m["default_median_time_s"], "%.2f"),
            num(m["default_max_time_s"], "%.2f"),
            num(m["default_median_time_per_1000_s"], "%.3f"),
            num(m["peer_right"], "%d"), num(m["peer_median_cpu_s"], "%.2f")))
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--build-dir", default=os.path.join(ROOT, "build"))
    p.add_argument("--output", help="output folder (default: BUILD_DIR/bench-sizes)")
    p.add_argument("--sizes", default="1000,3000,15000,60000", help="landmarks per map")
    p.add_argument("--seeds", default="1,2,3", help="simulator seeds")
    p.add_argument("--transforms", default=";".join(TRANSFORMS),
                   help="true transforms x,y,z,roll,pitch,yaw (m, deg), separated by ';'")
    p.add_argument("--no-peers", action="store_true", help="skip Open3D's FPFH + RANSAC + ICP")
    a = p.parse_args(sys.argv[1:] if argv is None else argv)
    sizes = parse_list(a.sizes, int, "--sizes")
    seeds = parse_list(a.seeds, int, "--seeds")
    transforms = [t for t in a.transforms.split(";") if t.strip()]
    for t in transforms:
        if len(parse_list(t, float, "--transforms")) != 6:
            raise SweepError("--transforms: %r is not six numbers" % t)
    lmalign = os.path.join(a.build_dir, "apps", "lmalign", "lmalign")
    if not os.access(lmalign, os.X_OK):
        raise SweepError("lmalign binary not found: %s (build it first)" % lmalign)
    peer = None if a.no_peers else accuracy_peers.peer_binary(a.build_dir)
    if peer is None and not a.no_peers:
        print("size sweep: Open3D's peer was not built (libopen3d-dev missing?): no peer columns")
    out = os.path.abspath(a.output or os.path.join(a.build_dir, "bench-sizes"))
    os.makedirs(out, exist_ok=True)
    log = os.path.join(out, "log.txt")
    report = {"date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
              "host": os.uname().nodename, "cores": os.cpu_count(), "seeds": seeds,
              "transforms": transforms, "thresholds": list(THRESHOLDS), "runs": []}
    started = time.time()
    for size in sizes:
        for seed in seeds:
            for i, transform in enumerate(transforms):
                folder = os.path.join(out, "n%d_seed%d_t%d" % (size, seed, i))
                try:
                    row = one_run(lmalign, peer, size, seed, transform, folder, log)
                except (accuracy_default.DefaultError, accuracy_peers.PeerError) as e:
                    raise SweepError(str(e))
                report["runs"].append(row)
                print("%6d landmarks, seed %d, transform %d: default %s%s in %.2f s%s" % (
                    size, seed, i, "right" if row["default_right"] else "wrong",
                    ", trusted" if row["default_trusted"] else "", row["default_time_s"] or 0,
                    "" if peer is None else "; Open3D %s in %.2f s" % (
                        "right" if row["peer_right"] else "wrong", row["peer_cpu_s"])),
                    flush=True)
    report["sizes"] = summary(report["runs"])
    report["wall_time_s"] = time.time() - started
    # Each file written whole (a temporary file renamed), never half.
    write_csv(os.path.join(out, "sizes.csv"), report["runs"], COLUMNS)
    write_json(os.path.join(out, "sizes.json"), report)
    write_text(os.path.join(out, "sizes.md"), markdown(report))
    print(markdown(report))
    print("size sweep: %s/sizes.csv, sizes.json, sizes.md (%.0f s)" % (out, report["wall_time_s"]))
    return 0


if __name__ == "__main__":
    run_main(main, SweepError, "size sweep", 1)
