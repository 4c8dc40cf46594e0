#!/usr/bin/env python3
"""Summarises lmalign_eval_trust's JSON (stdin): per method, right-basin count, the NEES of the
right-basin results (mean, median; 6 if calibrated) and the precision and recall of the trust
verdict at telling right-basin results from wrong ones (docs/accuracy.md)."""
import json
import statistics
import sys

d = json.load(sys.stdin)
for method in sorted({r["method"] for r in d["runs"]}):
    runs = [r for r in d["runs"] if r["method"] == method]
    right = [r for r in runs if r["right_basin"]]
    trusted = [r for r in runs if r["trustworthy"]]
    tp = sum(1 for r in trusted if r["right_basin"])
    nees = [r["nees"] for r in right if r["nees"] >= 0]
    prec = tp / len(trusted) if trusted else float("nan")
    rec = tp / len(right) if right else float("nan")
    print(f"{method}: {len(right)}/{len(runs)} right basin; trusted {len(trusted)}: "
          f"precision {prec:.3f} recall {rec:.3f}; NEES of right-basin results: "
          f"mean {statistics.mean(nees) if nees else float('nan'):.1f} "
          f"median {statistics.median(nees) if nees else float('nan'):.1f} (6 if calibrated)")
