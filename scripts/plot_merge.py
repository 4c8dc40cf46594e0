#!/usr/bin/env python3
"""Plots of an `lmalign merge` output folder (docs/merge.md, "Plots").

    plot_merge.py OUTDIR [--quiet]

Reads OUTDIR/poses.json, OUTDIR/edges.csv and the merged map(s) (merged_map.txt, or
merged_map_component<k>.txt) and writes, atomically (temporary file + rename):

  OUTDIR/merge_graph.png         the pose graph: one node per map at its T_world_map
                                 translation, edges between maps coloured by their residual
                                 chi^2 (used edges solid, edges rejected by the graph dashed;
                                 untrusted / unused edges are not drawn); one panel per
                                 component (each is in its own frame)
  OUTDIR/merged_landmarks.png    top-down view of the merged landmarks, one panel per component

"Top-down": the view along the smallest principal axis of the component's landmarks (world z
for a map of a ground-like scene; it needs no up axis), coloured by the height along that axis.
Needs matplotlib and numpy (Debian: python3-matplotlib python3-numpy); exits with status 3 and a
one-line message without them.
"""

import argparse
import csv
import json
import os
import sys


def fail(message, status=2):
    print("plot_merge.py: " + message, file=sys.stderr)
    sys.exit(status)


def read_landmarks(path, np):
    points = []
    with open(path) as f:
        for line in f:
            if line.startswith("LANDMARK"):
                fields = line.split()
                points.append((float(fields[2]), float(fields[3]), float(fields[4])))
    return np.array(points, dtype=float).reshape(-1, 3)


def principal_basis(points, np):
    """Rows: the two largest principal axes, then the smallest (the 'up' of the top-down view)."""
    if len(points) < 3:
        return np.eye(3), np.zeros(3)
    centre = points.mean(axis=0)
    _, vectors = np.linalg.eigh(np.cov((points - centre).T))
    basis = np.stack([vectors[:, 2], vectors[:, 1], vectors[:, 0]])
    if np.linalg.det(basis) < 0:
        basis[1] = -basis[1]
    return basis, centre


def save(fig, path):
    tmp = path + ".tmp.png"
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, path)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("outdir")
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args()
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import numpy as np
    except ImportError as e:
        fail("needs matplotlib and numpy (apt-get install python3-matplotlib python3-numpy): %s"
             % e, 3)

    out = args.outdir
    try:
        with open(os.path.join(out, "poses.json")) as f:
            poses = json.load(f)
        with open(os.path.join(out, "edges.csv")) as f:
            edges = list(csv.DictReader(f))
    except (OSError, ValueError) as e:
        fail("cannot read the merge outputs in %s: %s" % (out, e))
    maps = poses["maps"]
    index = {m["name"]: i for i, m in enumerate(maps)}
    components = sorted({m["component"] for m in maps})
    positions = np.array([[row[3] for row in m["T_world_map"][:3]] for m in maps], dtype=float)

    landmarks = {}
    for c in components:
        name = ("merged_map.txt" if len(components) == 1
                else "merged_map_component%d.txt" % c)
        path = os.path.join(out, name)
        landmarks[c] = read_landmarks(path, np) if os.path.exists(path) else np.zeros((0, 3))
    bases = {c: principal_basis(landmarks[c] if len(landmarks[c]) >= 3
                                else positions[[m["component"] == c for m in maps]], np)
             for c in components}

    def project(c, points):
        basis, centre = bases[c]
        return (points - centre) @ basis.T

    ncol = len(components)
    size = (6.0 * ncol, 5.5)
    # The graph.
    fig, axes = plt.subplots(1, ncol, figsize=size, squeeze=False)
    chi2 = [float(e["chi2"]) for e in edges if e["used"] == "1"]
    vmax = max([1.0] + chi2)
    norm = matplotlib.colors.LogNorm(vmin=min([x for x in chi2 if x > 0] + [vmax / 1e3]),
                                     vmax=vmax) if chi2 else None
    cmap = plt.get_cmap("viridis")
    for k, c in enumerate(components):
        ax = axes[0][k]
        members = [i for i, m in enumerate(maps) if m["component"] == c]
        xy = project(c, positions[members])
        for e in edges:
            if e["used"] != "1":
                continue
            i, j = index.get(e["source"]), index.get(e["target"])
            if i is None or j is None or maps[i]["component"] != c or maps[j]["component"] != c:
                continue
            a, b = project(c, positions[[i, j]])
            colour = cmap(norm(max(float(e["chi2"]), norm.vmin)))
            ax.plot([a[0], b[0]], [a[1], b[1]], color=colour,
                    linestyle="--" if e["rejected"] == "1" else "-",
                    linewidth=1.0 if e["rejected"] == "1" else 1.6, zorder=1)
        ax.scatter(xy[:, 0], xy[:, 1], s=28, c="black", zorder=2)
        if len(members) <= 40:
            for i, p in zip(members, xy):
                ax.annotate(maps[i]["name"], (p[0], p[1]), fontsize=6, xytext=(3, 3),
                            textcoords="offset points")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title("component %d: %d maps" % (c, len(members)))
        ax.set_xlabel("m (principal axis 1)")
        ax.set_ylabel("m (principal axis 2)")
    if norm is not None:
        sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
        fig.colorbar(sm, ax=axes[0].tolist(), label="edge residual chi^2 (dashed: rejected)")
    save(fig, os.path.join(out, "merge_graph.png"))
    plt.close(fig)

    # The merged landmarks, top-down.
    fig, axes = plt.subplots(1, ncol, figsize=size, squeeze=False)
    for k, c in enumerate(components):
        ax = axes[0][k]
        p = project(c, landmarks[c])
        if len(p):
            sc = ax.scatter(p[:, 0], p[:, 1], s=0.5, c=p[:, 2], cmap="viridis", linewidths=0)
            fig.colorbar(sc, ax=ax, label="height along the smallest principal axis (m)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title("component %d: %d landmarks" % (c, len(p)))
        ax.set_xlabel("m (principal axis 1)")
        ax.set_ylabel("m (principal axis 2)")
    save(fig, os.path.join(out, "merged_landmarks.png"))
    plt.close(fig)
    if not args.quiet:
        print("wrote %s, %s" % (os.path.join(out, "merge_graph.png"),
                                os.path.join(out, "merged_landmarks.png")))


if __name__ == "__main__":
    main()
