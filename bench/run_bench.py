#!/usr/bin/env python3
"""`make bench`: lmalign against PCL and Open3D on the real pair, side by side, in one script run.

Each configuration runs in its own child process (one of the bench executables), so that every
peak-memory figure is that configuration's alone. The configurations run interleaved, in rounds
(every configuration once per round): a virtual machine's speed drifts by tens of percent over a
minute, so each ratio is taken within a round, where lmalign and its peer ran moments apart, and
the median over the rounds is reported with its range. Prints a table with the ratios against
each peer and writes bench/results/latest.json. With --scaling, also runs the simulator from 1k to 1M
landmarks, fits the growth of time with N, and writes bench/results/scaling.json and the plot
docs/images/performance_scaling.png (docs/performance.md explains all of it).
"""
import argparse
import datetime
import json
import math
import os
import csv
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

# (executable, config) in table order. The executables are built only when their peer is found.
CONFIGS = [
    ("lmalign_bench_core", "lmalign_weighted_k5"),
    ("lmalign_bench_core", "lmalign_base"),
    ("lmalign_bench_core", "lmalign_weighted_k5_scored"),
    ("lmalign_bench_core", "lmalign_weighted_k5_1thread"),
    ("lmalign_bench_core", "lmalign_weighted_k5_plain"),
    ("lmalign_bench_core", "lmalign_base_plain"),
    ("lmalign_bench_pcl", "pcl_paper_pipeline"),
    ("lmalign_bench_pcl", "pcl_icp_dropin_k5"),
    ("lmalign_bench_pcl", "pcl_icp"),
    ("lmalign_bench_open3d", "open3d_p2p"),
]

# The speed targets: (lmalign config, peer config, minimum ratio).
TARGETS = [
    ("lmalign_weighted_k5", "pcl_paper_pipeline", 20.0),
    ("lmalign_weighted_k5", "pcl_icp_dropin_k5", 10.0),
    ("lmalign_weighted_k5", "open3d_p2p", 5.0),
]
# Further ratios shown in the table: like against like.
EXTRA_RATIOS = [
    ("lmalign_base", "pcl_icp"),
    ("lmalign_base", "open3d_p2p"),
    ("lmalign_weighted_k5_scored", "pcl_paper_pipeline"),
    ("lmalign_weighted_k5_1thread", "pcl_icp_dropin_k5"),
]


def machine():
    info = {"platform": platform.platform(), "python": platform.python_version()}
    try:
        with open("/proc/cpuinfo") as f:
            models = [l.split(":", 1)[1].strip() for l in f if l.startswith("model name")]
        info["cpu"] = models[0] if models else "?"
        info["logical_cpus"] = len(models)
    except OSError:
        pass
    try:
        info["cpus_available"] = len(os.sched_getaffinity(0))
    except AttributeError:
        pass
    try:
        with open("/proc/meminfo") as f:
            info["mem_total_kb"] = int(f.readline().split()[1])
    except OSError:
        pass
    info["omp_num_threads"] = os.environ.get("OMP_NUM_THREADS", "(default)")
    return info


def loadavg():
    try:
        return os.getloadavg()[0]
    except OSError:
        return float("nan")


def child_env(args):
    """Every peer runs with the same OpenMP wait policy (Open3D uses OpenMP too; PCL is serial)."""
    env = dict(os.environ)
    if args.wait_policy != "default":
        env["OMP_WAIT_POLICY"] = args.wait_policy
    return env


def run_one(exe, config, args):
    cmd = [exe, "--config", config, "--reps", str(args.reps), "--iterations", str(args.iterations)]
    before = loadavg()
    out = subprocess.run(cmd, capture_output=True, text=True, env=child_env(args))
    if out.returncode != 0:
        sys.stderr.write(f"run_bench: {' '.join(cmd)} failed ({out.returncode}):\n{out.stderr}\n")
        return None
    rec = json.loads(out.stdout.strip().splitlines()[-1])
    rec["loadavg_1min_before"] = before
    rec["executable"] = os.path.basename(exe)
    return rec


def fmt_mb(b):
    return f"{b / 1e6:7.2f}"


def merge_rounds(recs):
    """One record per configuration from its per-round records: the median and minimum over every
    timed run of every round, the largest peak memory, and the per-round medians."""
    rec = dict(recs[0])
    times = [t for r in recs for t in r["times_s"]]
    med = statistics.median(times)
    rec["times_s"] = times
    rec["round_total_s"] = [r["total_s"] for r in recs]
    rec["total_s"] = med
    rec["min_total_s"] = min(times)
    rec["per_iteration_s"] = med / rec["iterations"] if rec["iterations"] else 0.0
    rec["rounds"] = len(recs)
    for key in ("peak_rss_bytes", "added_peak_rss_bytes"):
        rec[key] = max(r[key] for r in recs)
    rec["loadavg_1min_before"] = max(r["loadavg_1min_before"] for r in recs)
    return rec


def paired_ratio(peer_rec, mine_rec):
    """peer time / lmalign time within each round (the two ran seconds apart, at the same machine
    speed): (median over the rounds, the per-round ratios)."""
    per = [p / m for p, m in zip(peer_rec["round_total_s"], mine_rec["round_total_s"])]
    return statistics.median(per), per


def real_pair(args):
    bindir = os.path.join(args.build_dir, "bench")
    per_round = {}  # config -> [record of each round]
    missing = []
    runnable = []
    for exe_name, config in CONFIGS:
        exe = os.path.join(bindir, exe_name)
        if os.path.exists(exe):
            runnable.append((exe, config))
        else:
            missing.append(config)
    for rnd in range(args.rounds):
        print(f"  round {rnd + 1}/{args.rounds}: ", end="", flush=True)
        for exe, config in runnable:
            print(".", end="", flush=True)
            rec = run_one(exe, config, args)
            if rec is not None:
                per_round.setdefault(config, []).append(rec)
        print(flush=True)
    # A configuration counts only if it ran in every round (the ratios pair rounds).
    results = {c: merge_rounds(recs) for c, recs in per_round.items() if len(recs) == args.rounds}

    print()
    print(f"Real pair: desk_gt_a (Table 1 displacement) onto desk_gt_b, {args.iterations} forced "
          f"iterations; median of {args.rounds} rounds x {args.reps} runs, each configuration in "
          f"its own process, interleaved")
    hdr = (f"{'configuration':30s} {'iters':>5s} {'total ms':>9s} {'ms/iter':>8s} "
           f"{'peak RSS MB':>11s} {'added MB':>9s} {'final score':>12s}")
    print(hdr)
    print("-" * len(hdr))
    for _, config in CONFIGS:
        r = results.get(config)
        if r is None:
            continue
        print(f"{config:30s} {r['iterations']:5d} {r['total_s'] * 1e3:9.2f} "
              f"{r['per_iteration_s'] * 1e3:8.3f} {fmt_mb(r['peak_rss_bytes']):>11s} "
              f"{fmt_mb(r['added_peak_rss_bytes']):>9s} {r['final_score_m2']:12.6e}")
    if missing:
        print(f"(not built, peer not found: {', '.join(missing)})")

    ratios = []
    print()
    print(f"{'ratio (peer time / lmalign time), median over rounds':56s} {'ratio':>8s} "
          f"{'rounds range':>14s} {'target':>7s}  ok")
    for mine, peer, target in TARGETS + [(a, b, None) for a, b in EXTRA_RATIOS]:
        if mine not in results or peer not in results:
            continue
        ratio, per = paired_ratio(results[peer], results[mine])
        ok = None if target is None else ratio >= target
        ratios.append({"lmalign": mine, "peer": peer, "ratio": ratio, "round_ratios": per,
                       "target": target, "met": ok})
        tgt = "" if target is None else f">={target:.0f}x"
        mark = "" if ok is None else ("yes" if ok else "NO")
        rng = f"{min(per):.1f}-{max(per):.1f}x"
        print(f"{peer + ' / ' + mine:56s} {ratio:7.1f}x {rng:>14s} {tgt:>7s}  {mark}")
    return {"results": results, "ratios": ratios, "not_built": missing}


# The protocol target: configs/paper.yaml, all tables and strategies, in under this.
PROTOCOL_TARGET_S = 5.0


def protocol(args):
    """Times `lmalign experiment configs/paper.yaml --no-plots` (45 cases x 4 strategies), wall and
    CPU, into a temporary folder; returns what latest.json records, or None if it failed."""
    exe = os.path.join(args.build_dir, "apps", "lmalign", "lmalign")
    config = os.path.join(ROOT, "configs", "paper.yaml")
    if not os.path.exists(exe):
        print(f"(protocol not timed: {exe} not built)")
        return None
    out_dir = tempfile.mkdtemp(prefix="lmalign_bench_protocol_")
    try:
        print("  running the paper protocol (configs/paper.yaml) ...", flush=True)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        load = loadavg()
        t0 = time.monotonic()
        out = subprocess.run([exe, "experiment", config, "-o", os.path.join(out_dir, "paper"),
                              "--no-plots"], capture_output=True, text=True, env=child_env(args))
        wall = time.monotonic() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if out.returncode != 0:
            sys.stderr.write(f"run_bench: the paper protocol failed ({out.returncode}):\n"
                             f"{out.stderr}\n")
            return None
        with open(os.path.join(out_dir, "paper", "results.csv"), newline="") as f:
            rows = list(csv.DictReader(f))
    finally:
        shutil.rmtree(out_dir, ignore_errors=True)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    iterations = sum(int(r["iterations"]) for r in rows)
    rec = {"config": "configs/paper.yaml", "runs": len(rows), "iterations": iterations,
           "wall_s": wall, "cpu_s": cpu, "target_s": PROTOCOL_TARGET_S,
           "met": wall < PROTOCOL_TARGET_S, "loadavg_1min_before": load}
    print()
    print(f"Paper protocol (configs/paper.yaml, --no-plots): {len(rows)} runs, {iterations} ICP "
          f"iterations: {wall:.1f} s wall, {cpu:.1f} s CPU "
          f"(target < {PROTOCOL_TARGET_S:.0f} s wall: {'yes' if rec['met'] else 'NO'})")
    return rec


def scaling(args):
    exe = os.path.join(args.build_dir, "bench", "lmalign_bench_scaling")
    sizes = [int(s) for s in args.sizes.split(",")]
    rows = []
    for n in sizes:
        print(f"  scaling N={n} ...", flush=True)
        out = subprocess.run([exe, "--n", str(n), "--reps", str(args.scaling_reps),
                              "--iterations", str(args.iterations)],
                             capture_output=True, text=True, env=child_env(args))
        if out.returncode != 0:
            sys.stderr.write(f"run_bench: scaling N={n} failed:\n{out.stderr}\n")
            continue
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))

    def fit(key):  # least squares of log t = a + alpha log N
        xs = [math.log(r["n"]) for r in rows]
        ys = [math.log(r[key]) for r in rows]
        n = len(xs)
        mx, my = sum(xs) / n, sum(ys) / n
        sxx = sum((x - mx) ** 2 for x in xs)
        return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx

    def nlogn_exponent():  # the exponent N log N itself shows over the same range
        xs = [math.log(r["n"]) for r in rows]
        ys = [math.log(r["n"] * math.log(r["n"])) for r in rows]
        n = len(xs)
        mx, my = sum(xs) / n, sum(ys) / n
        return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)

    print()
    print("Scaling (simulated SLAM map pairs, weighted k=5, N landmarks per map)")
    hdr = (f"{'N':>9s} {'plain ms/iter':>13s} {'reuse ms/iter':>13s} {'heap B/N':>9s} "
           f"{'RSS B/N':>8s} {'kd-tree B/pt':>12s}")
    print(hdr)
    print("-" * len(hdr))
    for r in rows:
        print(f"{r['n']:9d} {r['plain_per_iteration_s'] * 1e3:13.3f} "
              f"{r['reuse_per_iteration_s'] * 1e3:13.3f} "
              f"{r['added_heap_peak_bytes'] / r['n']:9.1f} "
              f"{r['added_rss_peak_bytes'] / r['n']:8.1f} {r['kdtree_bytes'] / r['n']:12.1f}")
    summary = {}
    if len(rows) >= 3:
        summary = {
            "plain_exponent": fit("plain_per_iteration_s"),
            "reuse_exponent": fit("reuse_per_iteration_s"),
            "nlogn_exponent_over_range": nlogn_exponent(),
            "max_added_heap_bytes_per_landmark": max(r["added_heap_peak_bytes"] / r["n"]
                                                     for r in rows),
            "max_added_rss_bytes_per_landmark": max(r["added_rss_peak_bytes"] / r["n"]
                                                    for r in rows),
        }
        print(f"fitted exponent of time per iteration vs N: plain {summary['plain_exponent']:.3f}, "
              f"with reuse {summary['reuse_exponent']:.3f} "
              f"(N log N over this range: {summary['nlogn_exponent_over_range']:.3f})")
    try:
        plot(rows, summary, os.path.join(ROOT, "docs", "images", "performance_scaling.png"))
    except Exception as e:  # matplotlib missing: the numbers still stand
        print(f"(no plot: {e})")
    return {"rows": rows, "summary": summary}


def plot(rows, summary, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ns = [r["n"] for r in rows]
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for key, label in (("plain_per_iteration_s", "plain search (no reuse)"),
                       ("reuse_per_iteration_s", "with exact reuse, 150 iterations")):
        ax[0].loglog(ns, [r[key] * 1e3 for r in rows], "o-", label=label)
    ref = rows[0]["plain_per_iteration_s"] * 1e3 / (ns[0] * math.log(ns[0]))
    ax[0].loglog(ns, [ref * n * math.log(n) for n in ns], "k--", lw=0.8, label="N log N")
    ax[0].set_xlabel("landmarks per map N")
    ax[0].set_ylabel("time per iteration (ms)")
    if summary:
        ax[0].set_title(f"slope: plain {summary['plain_exponent']:.2f}, "
                        f"reuse {summary['reuse_exponent']:.2f}")
    ax[0].legend(fontsize=8)
    ax[0].grid(True, which="both", lw=0.3)
    ax[1].semilogx(ns, [r["added_heap_peak_bytes"] / r["n"] for r in rows], "o-",
                   label="heap peak")
    ax[1].semilogx(ns, [r["added_rss_peak_bytes"] / r["n"] for r in rows], "s-",
                   label="RSS peak")
    ax[1].axhline(200, color="r", lw=0.8, ls="--", label="200 B")
    ax[1].set_xlabel("landmarks per map N")
    ax[1].set_ylabel("memory added by registration (bytes per landmark)")
    ax[1].set_ylim(0, 260)
    ax[1].legend(fontsize=8)
    ax[1].grid(True, which="both", lw=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"plot: {os.path.relpath(path, ROOT)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build"))
    ap.add_argument("--rounds", type=int, default=5,
                    help="interleaved rounds: every configuration runs once per round")
    ap.add_argument("--reps", type=int, default=2, help="timed runs per configuration per round")
    ap.add_argument("--iterations", type=int, default=150)
    ap.add_argument("--scaling", action="store_true", help="also run the 1k..1M scaling")
    ap.add_argument("--scaling-only", action="store_true")
    ap.add_argument("--sizes", default="1000,3000,10000,30000,100000,300000,1000000")
    ap.add_argument("--scaling-reps", type=int, default=3)
    ap.add_argument("--out", default=os.path.join(HERE, "results"))
    ap.add_argument("--no-protocol", action="store_true",
                    help="do not time the paper protocol (configs/paper.yaml)")
    ap.add_argument("--wait-policy", default="passive", choices=["passive", "active", "default"],
                    help="OMP_WAIT_POLICY of every child (passive: idle threads sleep instead of "
                         "spinning, which keeps 2 threads useful on a busy 2-core machine)")
    args = ap.parse_args()
    if args.rounds < 1 or args.reps < 1:
        ap.error("--rounds and --reps must be >= 1")
    os.makedirs(args.out, exist_ok=True)
    stamp = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    print(f"lmalign bench: {stamp}, load average {loadavg():.2f}")
    if not args.scaling_only:
        doc = {"date_utc": stamp, "machine": machine(), "iterations": args.iterations,
               "rounds": args.rounds, "reps": args.reps, "omp_wait_policy": args.wait_policy,
               **real_pair(args)}
        if not args.no_protocol:
            doc["protocol"] = protocol(args)
        with open(os.path.join(args.out, "latest.json"), "w") as f:
            json.dump(doc, f, indent=2)
        print(f"\nwritten: {os.path.relpath(os.path.join(args.out, 'latest.json'), ROOT)}")
    if args.scaling or args.scaling_only:
        doc = {"date_utc": stamp, "machine": machine(), "omp_wait_policy": args.wait_policy,
               **scaling(args)}
        with open(os.path.join(args.out, "scaling.json"), "w") as f:
            json.dump(doc, f, indent=2)
        print(f"written: {os.path.relpath(os.path.join(args.out, 'scaling.json'), ROOT)}")


if __name__ == "__main__":
    main()
