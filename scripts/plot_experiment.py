#!/usr/bin/env python3
"""Plots of an `lmalign experiment` report folder (docs/experiments.md, "Plots").

    plot_experiment.py OUTDIR [--case ID] [--quiet]

Reads OUTDIR/results.csv (and, when present, history.csv and alignment_points.csv, which the
runner writes for one case) and writes PNGs into OUTDIR/plots/:

  <experiment>_violin.png   per experiment: violins of the final score and, with ground truth,
                            of the rotation and translation errors, per strategy (the paper's
                            Figs. 3-5: solid line = median, dashed = mean, points on the left)
  <experiment>_basin.png    per basin experiment: success rate per strategy vs level
  history_case<N>.png       score (and correspondence MSE) per iteration, one line per strategy
  alignment_case<N>.png     like the paper's Fig. 2: target in black, source in green, top (x-y)
                            and side (x-z) views; first row before ICP, then one row per strategy

--case ID picks the case of the history/alignment plots among those in history.csv /
alignment_points.csv (default: the one there). Needs matplotlib and numpy (Debian:
python3-matplotlib python3-numpy); exits with status 3 and a one-line message without them.
"""

import argparse
import csv
import json
import math
import os
import sys

STRATEGY_ORDER = ["base", "covariance", "observations", "distance"]
STRATEGY_LABEL = {"base": "Base", "covariance": "Cov.", "observations": "# Obs.",
                  "distance": "Mean Dist."}
STRATEGY_COLOR = {"base": "#555555", "covariance": "#1f77b4", "observations": "#ff7f0e",
                  "distance": "#2ca02c"}
# Distinct markers and line styles, so that coinciding curves stay visible.
STRATEGY_STYLE = {"base": ("o", "-", 7), "covariance": ("s", "--", 6), "observations": ("^", "-", 6),
                  "distance": ("D", ":", 4)}


# The group column of a basin case is its axis; other experiments use "" or a quadrant.
BASIN_AXES = ("yaw", "translation")


def is_basin(rows):
    return bool(rows) and all(r["group"] in BASIN_AXES for r in rows)


def fail(message, status=2):
    print(f"plot_experiment: {message}", file=sys.stderr)
    sys.exit(status)


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def number(text):
    if text is None or text == "":
        return math.nan
    try:
        return float(text)
    except ValueError:
        return math.nan


def ordered_strategies(rows):
    seen = []
    for r in rows:
        if r["strategy"] not in seen:
            seen.append(r["strategy"])
    return [s for s in STRATEGY_ORDER if s in seen] + [s for s in seen if s not in STRATEGY_ORDER]


def violin_panel(ax, np, groups, labels, colors, title, ylabel, threshold=None, log=False):
    """One panel: a violin per group, its median (solid) and mean (dashed), points on the left."""
    positions = list(range(1, len(groups) + 1))
    data = []
    for g in groups:
        v = np.asarray([x for x in g if math.isfinite(x) and (x > 0 or not log)], dtype=float)
        data.append(np.log10(v) if log else v)
    rng = np.random.default_rng(0)
    for pos, v, color in zip(positions, data, colors):
        if v.size == 0:
            continue
        if v.size >= 2 and np.ptp(v) > 1e-12:
            body = ax.violinplot([v], positions=[pos], widths=0.7, showextrema=False)
            for b in body["bodies"]:
                b.set_facecolor(color)
                b.set_edgecolor("black")
                b.set_alpha(0.45)
        ax.hlines(np.median(v), pos - 0.3, pos + 0.3, colors="black", linestyles="solid", lw=1.5)
        ax.hlines(np.mean(v), pos - 0.3, pos + 0.3, colors="black", linestyles="dashed", lw=1.0)
        jitter = rng.uniform(-0.06, 0.06, v.size)
        ax.scatter(pos - 0.42 + jitter, v, s=10, color=color, edgecolors="black", linewidths=0.3,
                   zorder=3)
    if threshold is not None and math.isfinite(threshold) and (threshold > 0 or not log):
        t = math.log10(threshold) if log else threshold
        ax.axhline(t, color="red", lw=0.8, ls=":", label=f"success threshold ({threshold:g})")
        ax.legend(loc="upper left", fontsize=7, frameon=False)
    ax.set_xticks(positions)
    ax.set_xticklabels(labels)
    ax.set_xlim(0.3, len(groups) + 0.6)
    ax.set_title(title, fontsize=10)
    ax.set_ylabel(ylabel + (" (log scale)" if log else ""))
    if log:
        # Ticks at 1, 2, 5 x 10^n (only 10^n if that gives too many), labelled in data units.
        lo, hi = ax.get_ylim()
        ticks = []
        for mantissas in ((1, 2, 5), (1,)):
            ticks = [math.log10(m) + n for n in range(math.floor(lo) - 1, math.ceil(hi) + 1)
                     for m in mantissas if lo <= math.log10(m) + n <= hi]
            if len(ticks) <= 9:
                break
        ax.set_yticks(ticks)
        ax.set_yticklabels([f"{10 ** t:.3g}" for t in ticks])
        ax.set_ylim(lo, hi)
    ax.grid(axis="y", alpha=0.3)


def wide_range(np, values):
    v = np.asarray([x for x in values if math.isfinite(x) and x > 0], dtype=float)
    return v.size >= 2 and v.max() / v.min() > 30


def by_experiment(rows):
    """(experiment name, its rows) in the order the experiments first appear."""
    names = []
    for r in rows:
        if r["experiment"] not in names:
            names.append(r["experiment"])
    return [(name, [r for r in rows if r["experiment"] == name]) for name in names]


def save(plt, fig, plots_dir, name, dpi=110):
    """Lays out, writes plots_dir/NAME (PNG) and closes the figure; returns the path."""
    fig.tight_layout()
    path = os.path.join(plots_dir, name)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def plot_violins(plt, np, rows, summary, plots_dir):
    written = []
    for name, mine in by_experiment(rows):
        if is_basin(mine):
            continue  # basin experiment: curves instead
        strategies = ordered_strategies(mine)
        has_gt = any(r["rotation_error_deg"] != "" for r in mine)
        panels = [("final_score_m2", "Final score", "score (m²)", summary.get("success_score_m2"))]
        if has_gt:
            panels = [("final_score_m2", "Final score", "score (m²)", None),
                      ("rotation_error_deg", "Rotation error", "degrees",
                       summary.get("success_rotation_deg")),
                      ("translation_error_m", "Translation error", "metres",
                       summary.get("success_translation_m"))]
        fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 4.0), squeeze=False)
        ncases = len({r["case"] for r in mine})
        for ax, (column, title, ylabel, threshold) in zip(axes[0], panels):
            groups = [[number(r[column]) for r in mine if r["strategy"] == s] for s in strategies]
            flat = [x for g in groups for x in g]
            violin_panel(ax, np, groups, [STRATEGY_LABEL.get(s, s) for s in strategies],
                         [STRATEGY_COLOR.get(s, "#888888") for s in strategies], title, ylabel,
                         threshold, log=wide_range(np, flat))
        fig.suptitle(f"{name}: {ncases} cases per strategy", fontsize=11)
        written.append(save(plt, fig, plots_dir, f"{name}_violin.png"))
    return written


def plot_basins(plt, np, rows, plots_dir):
    written = []
    basin_rows = [r for r in rows if r["group"] in BASIN_AXES]
    for name, mine in by_experiment(basin_rows):
        axes_names = [a for a in ("yaw", "translation") if any(r["group"] == a for r in mine)]
        strategies = ordered_strategies(mine)
        fig, axes = plt.subplots(1, len(axes_names), figsize=(5.2 * len(axes_names), 3.8),
                                 squeeze=False)
        for ax, axis in zip(axes[0], axes_names):
            levels = sorted({number(r["value"]) for r in mine if r["group"] == axis})
            for s in strategies:
                rates, ns = [], []
                for lv in levels:
                    at = [r for r in mine if r["group"] == axis and r["strategy"] == s and
                          number(r["value"]) == lv]
                    ns.append(len(at))
                    rates.append(100.0 * sum(r["success"] == "true" for r in at) / len(at)
                                 if at else math.nan)
                marker, style, size = STRATEGY_STYLE.get(s, ("o", "-", 5))
                ax.plot(levels, rates, marker=marker, linestyle=style, markersize=size,
                        color=STRATEGY_COLOR.get(s, "#888888"), label=STRATEGY_LABEL.get(s, s))
            ax.set_xlabel("yaw (degrees)" if axis == "yaw" else "translation (m)")
            ax.set_ylabel("success rate (%)")
            ax.set_ylim(-5, 105)
            ax.set_title(f"{axis} basin", fontsize=10)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
        samples = max(len({r["case"] for r in mine if r["value"] == v}) for v in
                      {r["value"] for r in mine})
        fig.suptitle(f"{name}: success rate per level (up to {samples} seeded draws per level)",
                     fontsize=11)
        written.append(save(plt, fig, plots_dir, f"{name}_basin.png"))
    return written


def pick_case(rows, wanted, what):
    cases = []
    for r in rows:
        if r["case"] not in cases:
            cases.append(r["case"])
    if wanted is None:
        return cases[0] if cases else None
    for r in rows:
        if r["case"] == wanted or f"{r['experiment']}/{r['label']}" == wanted:
            return r["case"]
    fail(f"{what} holds case(s) {', '.join(cases)}, not '{wanted}'; rerun lmalign experiment "
         f"with --plot-case {wanted}")


def plot_history(plt, np, path, wanted, plots_dir):
    rows = read_csv(path)
    if not rows:
        # Only the paper's strategies record a per-iteration history (lmalign's own, e.g. the
        # adaptive default, have none): nothing to plot.
        return []
    case = pick_case(rows, wanted, "history.csv")
    if case is None:
        return []
    mine = [r for r in rows if r["case"] == case]
    label = mine[0]["label"]
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for s in ordered_strategies(mine):
        rs = [r for r in mine if r["strategy"] == s]
        it = [int(r["iteration"]) for r in rs]
        color = STRATEGY_COLOR.get(s, "#888888")
        axes[0].plot(it, [number(r["score_m2"]) for r in rs], color=color,
                     label=STRATEGY_LABEL.get(s, s))
        axes[1].plot(it, [number(r["mse_m2"]) for r in rs], color=color,
                     label=STRATEGY_LABEL.get(s, s))
    for ax, title in zip(axes, ["fitness score (m²)", "correspondence MSE (m²)"]):
        ax.set_yscale("log")
        ax.set_xlabel("iteration")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.suptitle(f"case {case} ({label}): per-iteration history", fontsize=11)
    return [save(plt, fig, plots_dir, f"history_case{case}.png")]


def plot_alignment(plt, np, path, wanted, plots_dir, results):
    rows = read_csv(path)
    case = pick_case(rows, wanted, "alignment_points.csv")
    if case is None:
        return []
    mine = [r for r in rows if r["case"] == case]
    label = mine[0]["label"]
    clouds = []
    for r in mine:
        if r["cloud"] not in clouds:
            clouds.append(r["cloud"])
    pts = {c: np.array([[float(r["x"]), float(r["y"]), float(r["z"])] for r in mine
                        if r["cloud"] == c]) for c in clouds}
    sources = [c for c in clouds if c != "target"]
    verdict = {r["strategy"]: r for r in results if r["case"] == case}
    fig, axes = plt.subplots(len(sources), 2, figsize=(9, 3.1 * len(sources)), squeeze=False)
    tgt = pts["target"]
    for row, c in enumerate(sources):
        src = pts[c]
        for col, (i, j, names) in enumerate([(0, 1, ("x", "y")), (0, 2, ("x", "z"))]):
            ax = axes[row][col]
            ax.scatter(tgt[:, i], tgt[:, j], s=1.2, c="black", linewidths=0, label="target")
            ax.scatter(src[:, i], src[:, j], s=1.2, c="#22aa22", linewidths=0,
                       label="source" if c == "initial" else "aligned source")
            ax.set_aspect("equal", adjustable="datalim")
            ax.set_xlabel(f"{names[0]} (m)")
            ax.set_ylabel(f"{names[1]} (m)")
            if c == "initial":
                title = "before ICP (displaced source)"
            else:
                v = verdict.get(c)
                title = STRATEGY_LABEL.get(c, c)
                if v is not None:
                    title += f": score {number(v['final_score_m2']):.4g} m²"
                    if v["rotation_error_deg"] != "":
                        title += (f", {number(v['rotation_error_deg']):.2f}° / "
                                  f"{100 * number(v['translation_error_m']):.1f} cm")
                    title += ", success" if v["success"] == "true" else ", FAILED"
            ax.set_title(("top: " if col == 0 else "side: ") + title, fontsize=9)
            if row == 0 and col == 0:
                ax.legend(fontsize=7, markerscale=6, loc="upper right")
    fig.suptitle(f"case {case} ({label}): target black, source green", fontsize=11)
    return [save(plt, fig, plots_dir, f"alignment_case{case}.png", dpi=100)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("outdir", help="report folder written by lmalign experiment")
    parser.add_argument("--case", help="case of the history/alignment plots (index or "
                        "<experiment>/<label>)")
    parser.add_argument("--quiet", action="store_true", help="print only the plots folder")
    parser.add_argument("--plots-dir", help="where the PNGs go (default OUTDIR/plots; lmalign "
                        "draws into a temporary folder and writes each PNG through its output "
                        "writer)")
    args = parser.parse_args()

    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import numpy as np
    except ImportError as e:
        fail(f"needs matplotlib and numpy ({e}); on Debian: apt-get install python3-matplotlib "
             "python3-numpy, or set LMALIGN_PYTHON to an interpreter that has them", 3)

    results_path = os.path.join(args.outdir, "results.csv")
    if not os.path.isfile(results_path):
        fail(f"no results.csv in {args.outdir}")
    rows = read_csv(results_path)
    summary = {}
    summary_path = os.path.join(args.outdir, "summary.json")
    if os.path.isfile(summary_path):
        with open(summary_path) as f:
            summary = json.load(f)
    plots_dir = args.plots_dir or os.path.join(args.outdir, "plots")
    os.makedirs(plots_dir, exist_ok=True)

    written = []
    if rows:
        written += plot_violins(plt, np, rows, summary, plots_dir)
        written += plot_basins(plt, np, rows, plots_dir)
    history = os.path.join(args.outdir, "history.csv")
    if os.path.isfile(history):
        written += plot_history(plt, np, history, args.case, plots_dir)
    points = os.path.join(args.outdir, "alignment_points.csv")
    if os.path.isfile(points):
        written += plot_alignment(plt, np, points, args.case, plots_dir, rows)
    if not args.quiet:
        for w in written:
            print(f"wrote {w}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
