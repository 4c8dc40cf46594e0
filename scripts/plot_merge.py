#!/usr/bin/env python3
"""Plots of an `lmalign merge` output folder (docs/merge.md, "Plots").

    plot_merge.py OUTDIR [--quiet]

Reads OUTDIR/poses.json, OUTDIR/edges.csv and the merged map(s) (merged_map.txt, or
merged_map_component<k>.txt) and writes, atomically (temporary file + rename):

  OUTDIR/merge_graph.png         the pose graph: one node per map at the centre of its landmarks
                                 in the world frame (their coordinate-wise median, poses.json's
                                 landmark_centre_world; its T_world_map translation, the frame's
                                 arbitrary origin, only when it has no landmarks), over the merged
                                 landmarks in light grey; edges between maps coloured by their
                                 residual chi^2 (used edges solid, edges rejected by the graph
                                 dashed; untrusted / unused edges are not drawn); one panel per
                                 component (each is in its own frame)
  OUTDIR/merged_landmarks.png    top-down view of the merged landmarks, one colour per map (the
                                 map that added each landmark: poses.json's merged_landmarks id
                                 ranges), one panel per component

"Top-down": the view along the up axis of the merged map's frames (the mean of their -y axes,
the camera convention of docs/map-format.md) when they agree, the first axis along the landmarks'
principal direction; without frames, along the smallest principal axis of the landmarks (world z
for a map of a ground-like scene); both fitted to the landmarks inside their 2-98th percentiles
per coordinate. Axis limits: the 1st-99th percentiles of the landmarks
along each plotted axis (and every node), with a 5% margin, so that a few far landmarks (stereo
points hundreds of metres away) do not shrink the map to a smear; the panel's title says how many
lie beyond. Needs matplotlib and numpy (Debian: python3-matplotlib python3-numpy); exits with
status 3 and a one-line message without them.
"""

import argparse
import csv
import json
import os
import sys


def fail(message, status=2):
    print("plot_merge.py: " + message, file=sys.stderr)
    sys.exit(status)


def read_merged_map(path, np):
    """(landmark ids, landmark points (N, 3), the frames' up axis or None) of a map file: the
    up axis is the mean of the frames' -y axes (the camera convention of docs/map-format.md:
    x right, y down), when they agree (the mean's length above 0.5)."""
    ids, points, up, frames = [], [], np.zeros(3), 0
    with open(path) as f:
        for line in f:
            if line.startswith("LANDMARK"):
                fields = line.split()
                ids.append(int(fields[1]))
                points.append((float(fields[2]), float(fields[3]), float(fields[4])))
            elif line.startswith("FRAME"):
                frames += 1
                w, x, y, z = (float(v) for v in line.split()[5:9])
                n = np.sqrt(w * w + x * x + y * y + z * z) or 1.0
                w, x, y, z = w / n, x / n, y / n, z / n
                up -= np.array([2 * (x * y - w * z), 1 - 2 * (x * x + z * z),
                                2 * (y * z + w * x)])  # the rotation's second column
    norm = np.linalg.norm(up)
    return (np.array(ids, dtype=np.int64), np.array(points, dtype=float).reshape(-1, 3),
            up / norm if frames and norm > 0.5 * frames else None)


def principal_basis(points, up, np):
    """Rows: the view's two axes, then its 'up', and their centre: fitted to the points inside
    their 2-98th percentiles per coordinate. With the frames' up axis: up is that, the first axis
    the points' principal direction across it; without: the two largest principal axes, then
    the smallest (top-down for a ground-like scene)."""
    if len(points) < 3:
        return np.eye(3), np.zeros(3)
    lo, hi = np.percentile(points, 2, axis=0), np.percentile(points, 98, axis=0)
    inner = points[np.all((points >= lo) & (points <= hi), axis=1)]
    if len(inner) >= 3:
        points = inner
    centre = np.median(points, axis=0)
    if up is not None:
        flat = (points - centre) - np.outer((points - centre) @ up, up)
        _, vectors = np.linalg.eigh(np.cov(flat.T))
        first = vectors[:, 2] - (vectors[:, 2] @ up) * up
        first /= np.linalg.norm(first)
        basis = np.stack([first, np.cross(up, first), up])
    else:
        _, vectors = np.linalg.eigh(np.cov((points - centre).T))
        basis = np.stack([vectors[:, 2], vectors[:, 1], vectors[:, 0]])
    if np.linalg.det(basis) < 0:
        basis[1] = -basis[1]
    return basis, centre


def robust_limits(xy, extra, np):
    """(x limits, y limits, points beyond them): the 1st-99th percentiles of xy per axis, widened
    to hold every point of `extra` (the graph's nodes), with a 5% margin."""
    if len(xy) == 0 and len(extra) == 0:
        return (-1.0, 1.0), (-1.0, 1.0), 0
    both = [a for a in (xy, extra) if len(a)]
    lo = np.min([np.percentile(a, 1, axis=0) if a is xy else a.min(axis=0) for a in both], axis=0)
    hi = np.max([np.percentile(a, 99, axis=0) if a is xy else a.max(axis=0) for a in both], axis=0)
    span = np.maximum(hi - lo, 1e-3)
    lo, hi = lo - 0.05 * span, hi + 0.05 * span
    beyond = int(np.sum(np.any((xy < lo) | (xy > hi), axis=1))) if len(xy) else 0
    return (lo[0], hi[0]), (lo[1], hi[1]), beyond


def node_positions(maps, np):
    """Each map's node (N, 3): the centre of its landmarks in the world frame (poses.json's
    landmark_centre_world); its T_world_map translation (the frame's arbitrary origin) only when
    it has none."""
    return np.array([m["landmark_centre_world"] if m.get("landmark_centre_world") is not None
                     else [row[3] for row in m["T_world_map"][:3]] for m in maps], dtype=float)


def landmark_owners(ids, maps, component, np):
    """Per merged landmark id of `component`, the index of the map that added it (poses.json's
    merged_landmarks [begin, end)); -1 when unknown (an output written without the ranges)."""
    own = np.full(len(ids), -1, dtype=np.int64)
    for i, m in enumerate(maps):
        r = m.get("merged_landmarks")
        if m["component"] == component and r:
            own[(ids >= r[0]) & (ids < r[1])] = i
    return own


def save(fig, path):
    tmp = path + ".tmp.png"
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, path)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("outdir")
    parser.add_argument("--quiet", action="store_true")
    parser.add_argument("--plots-dir", help="where the PNGs go (default OUTDIR)")
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
    centres = node_positions(maps, np)

    landmarks, owner, ups = {}, {}, {}
    for c in components:
        name = ("merged_map.txt" if len(components) == 1
                else "merged_map_component%d.txt" % c)
        path = os.path.join(out, name)
        ids, points, ups[c] = (read_merged_map(path, np) if os.path.exists(path)
                               else (np.zeros(0, dtype=np.int64), np.zeros((0, 3)), None))
        landmarks[c] = points
        owner[c] = landmark_owners(ids, maps, c, np)
    bases = {c: principal_basis(landmarks[c] if len(landmarks[c]) >= 3
                                else centres[[m["component"] == c for m in maps]], ups[c], np)
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
        xy = project(c, centres[members])
        back = project(c, landmarks[c])[:, :2] if len(landmarks[c]) else np.zeros((0, 2))
        if len(back):
            ax.scatter(back[:, 0], back[:, 1], s=0.3, c="0.8", linewidths=0, zorder=0)
        for e in edges:
            if e["used"] != "1":
                continue
            i, j = index.get(e["source"]), index.get(e["target"])
            if i is None or j is None or maps[i]["component"] != c or maps[j]["component"] != c:
                continue
            a, b = project(c, centres[[i, j]])
            colour = cmap(norm(max(float(e["chi2"]), norm.vmin)))
            ax.plot([a[0], b[0]], [a[1], b[1]], color=colour,
                    linestyle="--" if e["rejected"] == "1" else "-",
                    linewidth=1.0 if e["rejected"] == "1" else 1.6, zorder=1)
        ax.scatter(xy[:, 0], xy[:, 1], s=28, c="black", zorder=2)
        if len(members) <= 40:
            for i, p in zip(members, xy):
                ax.annotate(maps[i]["name"], (p[0], p[1]), fontsize=6, xytext=(3, 3),
                            textcoords="offset points")
        xlim, ylim, _ = robust_limits(back, xy[:, :2], np)
        ax.set_xlim(*xlim)
        ax.set_ylim(*ylim)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title("component %d: %d maps (nodes at their landmarks' centre)"
                     % (c, len(members)), fontsize=9)
        ax.set_xlabel("m (principal axis 1)")
        ax.set_ylabel("m (principal axis 2)")
    if norm is not None:
        sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
        fig.colorbar(sm, ax=axes[0].tolist(), label="edge residual chi^2 (dashed: rejected)")
    plots = args.plots_dir or out
    save(fig, os.path.join(plots, "merge_graph.png"))
    plt.close(fig)

    # The merged landmarks, top-down, one colour per map: ten distinct hues, then their light
    # shades (tab20 in its own order pairs a hue with its shade, and neighbouring windows of a
    # drive came out as two blues).
    tab10, tab20 = plt.get_cmap("tab10"), plt.get_cmap("tab20")

    def colours(n):
        return tab10(n % 10) if n < 10 else tab20((2 * n) % 20 + 1)
    fig, axes = plt.subplots(1, ncol, figsize=size, squeeze=False)
    for k, c in enumerate(components):
        ax = axes[0][k]
        p = project(c, landmarks[c])
        members = [i for i, m in enumerate(maps) if m["component"] == c]
        beyond = 0
        if len(p):
            for n, i in enumerate(members + [-1]):
                sel = owner[c] == i
                if not np.any(sel):
                    continue
                ax.scatter(p[sel, 0], p[sel, 1], s=0.6, linewidths=0,
                           color="0.5" if i < 0 else colours(n % 20),
                           label="?" if i < 0 else maps[i]["name"])
            xlim, ylim, beyond = robust_limits(p[:, :2], np.zeros((0, 2)), np)
            ax.set_xlim(*xlim)
            ax.set_ylim(*ylim)
            if len(members) <= 20:
                ax.legend(fontsize=6, markerscale=8, loc="upper right", ncol=2)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title("component %d: %d landmarks%s" % (
            c, len(p), ", %d beyond the 1st-99th percentiles not shown" % beyond if beyond
            else ""), fontsize=9)
        ax.set_xlabel("m (principal axis 1)")
        ax.set_ylabel("m (principal axis 2)")
    save(fig, os.path.join(plots, "merged_landmarks.png"))
    plt.close(fig)
    if not args.quiet:
        print("wrote %s, %s" % (os.path.join(plots, "merge_graph.png"),
                                os.path.join(plots, "merged_landmarks.png")))


if __name__ == "__main__":
    main()
