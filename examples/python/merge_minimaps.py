#!/usr/bin/env python3
"""Merge mini-maps with lmalign: cut a map into windows, merge them, check them, plot them.

    /usr/bin/python3 examples/python/merge_minimaps.py [MAP] [-o merged] [--windows 4]
                     [--frames 30] [--dask]

Without MAP, the real motion-capture-anchored TUM fr1/desk map
($LMALIGN_DATA/tum_fr1_desk/ground_truth_pair/map_fr1_desk_gt.txt). It is cut with lmalign.split
into --windows windows of --frames frames (mini-maps, all in the map's frame: the truth of every
T_world_map is the identity), each given a noisy odometry prior (seeded: --prior-error 1 deg /
5 cm off by default, declared as 3 deg / 0.1 m), written with a manifest into OUTPUT/maps, and merged with
lmalign.merge (in process; with --dask on a LocalCluster of 2 worker processes on loopback).
Prints each window's rotation and translation error against the truth and writes
OUTPUT/merged_topdown.png: the merged landmarks seen from above (x, y), one colour per window.
"""
import argparse
import os
import pathlib

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import lmalign  # noqa: E402


def noisy_prior(rng, rot_deg, trans_m):
    """A 4x4 odometry prior near the identity: a random rotation of rot_deg about a random axis
    and a random translation of trans_m (metres)."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    a = np.radians(rot_deg)
    T = np.eye(4)
    T[:3, :3] = np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K  # Rodrigues
    direction = rng.normal(size=3)
    T[:3, 3] = trans_m * direction / np.linalg.norm(direction)
    return T


def main():
    data = pathlib.Path(os.environ.get("LMALIGN_DATA", "../shared/data"))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("map", nargs="?",
                        default=data / "tum_fr1_desk" / "ground_truth_pair" /
                        "map_fr1_desk_gt.txt")
    parser.add_argument("-o", "--output", default="merged", help="output folder")
    parser.add_argument("--windows", type=int, default=4)
    parser.add_argument("--frames", type=int, default=30, help="frames per window")
    parser.add_argument("--prior-error", type=float, nargs=2, default=(1.0, 0.05),
                        metavar=("ROT_DEG", "TRANS_M"),
                        help="how far off each window's odometry prior is (seeded direction)")
    parser.add_argument("--dask", action="store_true",
                        help="run the pairs on a LocalCluster (2 worker processes, loopback)")
    args = parser.parse_args()
    if not lmalign.HAVE_MERGE:
        raise SystemExit("this lmalign was built without the merge (needs Ceres)")

    out = pathlib.Path(args.output)
    maps_dir = out / "maps"
    maps_dir.mkdir(parents=True, exist_ok=True)
    full = lmalign.read_map(str(args.map), min_observations=0)
    first = int(full.frame_ids.min())
    rng = np.random.default_rng(7)
    lines = ["maps:"]
    for k in range(args.windows):
        start = first + k * args.frames
        window = lmalign.split(full, start, start + args.frames - 1)
        lmalign.write_map(maps_dir / ("w%d.txt" % k), window)
        prior = noisy_prior(rng, args.prior_error[0], args.prior_error[1])
        lines += ["  - name: w%d" % k, "    path: w%d.txt" % k,
                  "    T_world_map: %s" % [[float(v) for v in row] for row in prior],
                  "    prior_sigma: [3.0, 0.1]"]
        print("window w%d: frames %d-%d, %d landmarks, prior %.1f deg / %.3f m off"
              % (k, start, start + args.frames - 1, len(window), args.prior_error[0],
                 args.prior_error[1]))
    manifest = maps_dir / "manifest.yaml"
    manifest.write_text("\n".join(lines) + "\n")

    client = cluster = None
    if args.dask:
        import distributed

        cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                           host="127.0.0.1", dashboard_address=None)
        client = distributed.Client(cluster)
    try:
        run = lmalign.merge(manifest, out / "result", ground_truth="identity",
                            dask_client=client)
    finally:
        if client is not None:
            client.close()
            cluster.close()
    print(run)
    print("edges: %.2f s (%s), graph: %.2f s" % (run.seconds_edges, run.backend,
                                                 run.seconds_graph))
    ev = run.evaluation
    for i, name in enumerate(run.names):
        print("%s: component %d, error %.3f deg, %.4f m" % (
            name, run.components[i], ev["rotation_deg"][i], ev["translation_m"][i]))
    print("within 5 deg / 10 cm: %d/%d" % (int(np.sum(ev["within"])), len(run.names)))

    # The merged landmarks from above: each window's landmarks moved by its T_world_map.
    fig, ax = plt.subplots(figsize=(7, 6))
    for i, name in enumerate(run.names):
        window = lmalign.read_map(str(maps_dir / ("%s.txt" % name)))
        p = lmalign.transform_points(run.T_world_map[i], window.positions)
        ax.scatter(p[:, 0], p[:, 1], s=2, label="%s (%d landmarks)" % (name, len(window)))
    ax.set_title("merged: %d windows, %d components" % (len(run.names), run.num_components))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.legend(markerscale=5, fontsize=8)
    fig.tight_layout()
    png = out / "merged_topdown.png"
    fig.savefig(png, dpi=100)
    print("wrote %s" % png)


if __name__ == "__main__":
    main()
