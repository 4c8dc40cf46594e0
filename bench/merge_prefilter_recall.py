#!/usr/bin/env python3
"""Recall of `lmalign merge`'s candidate pre-filter on a simulated fleet (docs/merge.md).

    merge_prefilter_recall.py SCENE_DIR MERGE_OUTDIR [--min-shared F]

SCENE_DIR is written by `lmalign simulate --scene fleet` (overlaps.csv: the truly overlapping
pairs and the fraction of the smaller map's landmarks they share; the planted look-alike pairs);
MERGE_OUTDIR by `lmalign merge --plan-only` (candidates.csv) or `lmalign merge` (edges.csv):
one row per candidate pair. Prints the recall (kept
overlapping pairs / overlapping pairs) for all overlaps and for those sharing >= F (default 0.2),
how many planted look-alike pairs became candidates, and how many candidates overlap at all.
"""

import argparse
import csv
import os


def main():
    p = argparse.ArgumentParser()
    p.add_argument("scene")
    p.add_argument("merge_out")
    p.add_argument("--min-shared", type=float, default=0.2)
    a = p.parse_args()
    overlaps, twins = {}, set()
    with open(os.path.join(a.scene, "overlaps.csv")) as f:
        for row in csv.DictReader(f):
            key = tuple(sorted((row["source"], row["target"])))
            if row["kind"] == "twin":
                twins.add(key)
            else:
                overlaps[key] = float(row["shared_fraction"])
    name = "candidates.csv"  # merge --plan-only
    if not os.path.exists(os.path.join(a.merge_out, name)):
        name = "edges.csv"
    with open(os.path.join(a.merge_out, name)) as f:
        candidates = {tuple(sorted((r["source"], r["target"]))) for r in csv.DictReader(f)}
    strong = {k for k, v in overlaps.items() if v >= a.min_shared}
    kept = len(candidates & set(overlaps))
    kept_strong = len(candidates & strong)
    print("candidates %d; truly overlapping pairs %d, kept %d: recall %.3f" %
          (len(candidates), len(overlaps), kept, kept / max(1, len(overlaps))))
    print("pairs sharing >= %.2f: %d, kept %d: recall %.3f" %
          (a.min_shared, len(strong), kept_strong, kept_strong / max(1, len(strong))))
    print("candidates that overlap: %d of %d (%.3f); planted look-alike pairs among them: %d of %d"
          % (kept, len(candidates), kept / max(1, len(candidates)), len(candidates & twins),
             len(twins)))


if __name__ == "__main__":
    main()
