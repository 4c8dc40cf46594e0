#!/usr/bin/env python3
"""Run (a small part of) the paper's protocol from Python and read its results.csv.

    /usr/bin/python3 examples/python/paper_protocol.py [-o OUTDIR]

Writes a small experiment config (the paper's Table 2: yaw displacements, on the real TUM
fr1/desk pair from $LMALIGN_DATA), runs it with lmalign.experiment() as `lmalign experiment`
would, then reads OUTDIR/results.csv with the csv module and prints the success rate and the
median errors per strategy. The full protocol is configs/paper.yaml.
"""
import argparse
import csv
import os
import pathlib
import statistics
import tempfile

import lmalign

CONFIG = """\
description: "Table 2 of the paper (yaw only), small: 4 yaws"
source: ${LMALIGN_DATA}/tum_fr1_desk/ground_truth_pair/desk_gt_a.txt
target: ${LMALIGN_DATA}/tum_fr1_desk/ground_truth_pair/desk_gt_b.txt
ground_truth: identity
strategies: [base, observations, robust_obs]
k: 5
max_iterations: 150
max_distance_m: inf
success: {rotation_deg: 5, translation_m: 0.10}
experiments:
  - name: yaw
    type: yaw
    yaw_deg: [0, 20, 40, 60]
"""


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default=None, help="report folder (default: a temp dir)")
    args = parser.parse_args()
    data_dir = os.environ.get("LMALIGN_DATA", os.path.abspath("../shared/data"))

    with tempfile.TemporaryDirectory() as tmp:
        config = pathlib.Path(tmp) / "table2_small.yaml"
        config.write_text(CONFIG)
        output = args.output or os.path.join(tmp, "report")
        report = lmalign.experiment(config, output, data_dir=data_dir)
        print("%d cases, %d runs -> %s" % (report["cases"], report["runs"], report["output_dir"]))

        per_strategy = {}
        with open(report["results_csv"], newline="") as f:
            for row in csv.DictReader(f):
                per_strategy.setdefault(row["strategy"], []).append(row)
        print("%-12s %8s %14s %14s" % ("strategy", "success", "median rot deg",
                                       "median trans m"))
        for strategy, rows in per_strategy.items():
            ok = [r for r in rows if r["success"] == "true"]
            rot = statistics.median(float(r["rotation_error_deg"]) for r in ok) if ok else float("nan")
            trans = statistics.median(float(r["translation_error_m"]) for r in ok) if ok else float("nan")
            print("%-12s %4d/%-3d %14.3f %14.4f" % (strategy, len(ok), len(rows), rot, trans))


if __name__ == "__main__":
    main()
