#!/usr/bin/env python3
"""Align two landmark maps with lmalign and plot them before and after (matplotlib, PNG).

    /usr/bin/python3 examples/python/align_and_plot.py [SOURCE TARGET] [-o aligned.png]

Without maps, the real TUM fr1/desk pair ($LMALIGN_DATA/tum_fr1_desk/ground_truth_pair; truth:
identity), with the source displaced by the paper's Table 1 pose (x=0, y=1, z=0.4 m, roll=10,
yaw=22.5 deg), as `make demo` does. The plot is a top view (x, y) in the target frame.
"""
import argparse
import os
import pathlib

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import lmalign  # noqa: E402


def main():
    data = pathlib.Path(os.environ.get("LMALIGN_DATA", "../shared/data"))
    pair = data / "tum_fr1_desk" / "ground_truth_pair"
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source", nargs="?", default=pair / "desk_gt_a.txt")
    parser.add_argument("target", nargs="?", default=pair / "desk_gt_b.txt")
    parser.add_argument("-o", "--output", default="aligned.png", help="PNG to write")
    parser.add_argument("--strategy", default=lmalign.RECOMMENDED_STRATEGY,
                        choices=lmalign.strategies())
    args = parser.parse_args()

    source = lmalign.read_map(str(args.source))
    target = lmalign.read_map(str(args.target))
    # The paper's protocol: displace the source about the world origin, start at the identity.
    T_displace = lmalign.pose_from_xyz_rpy_deg(0, 1, 0.4, 10, 0, 22.5)
    before = lmalign.transform_points(T_displace, source.positions)
    covariances = lmalign.transform_covariances(T_displace, source.covariances)

    result = lmalign.align(before, target, strategy=args.strategy,
                           source_covariances=covariances)
    after = lmalign.transform_points(result.T_target_source, before)
    # The recovered map-to-map transform, to compare with the truth (identity on the real pair).
    T_recovered = result.T_target_source @ T_displace
    print(result)
    print("trustworthy: %s (%s)" % (result.trustworthy, result.trust_reason))
    print("recovered translation [m]:", np.round(T_recovered[:3, 3], 4))

    fig, axes = plt.subplots(1, 2, figsize=(11, 5), sharex=True, sharey=True)
    for ax, moved, title in ((axes[0], before, "before (displaced source)"),
                             (axes[1], after, "after: %s, %d iterations"
                              % (result.strategy, result.iterations))):
        ax.scatter(target.positions[:, 0], target.positions[:, 1], s=2, c="black",
                   label="target (%d landmarks)" % len(target))
        ax.scatter(moved[:, 0], moved[:, 1], s=2, c="tab:red",
                   label="source (%d landmarks)" % len(source))
        ax.set_title(title)
        ax.set_xlabel("x [m]")
        ax.set_aspect("equal")
    axes[0].set_ylabel("y [m]")
    axes[0].legend(loc="upper right", markerscale=4)
    fig.suptitle("lmalign: top view in the target frame; final score %.2e m^2"
                 % result.final_score_m2)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(args.output)), exist_ok=True)
    fig.savefig(args.output, dpi=100)
    print("plot written to", args.output)


if __name__ == "__main__":
    main()
