"""`python3 -m lmalign.merge_cli MANIFEST -o OUTDIR --dask-scheduler ADDRESS [...]`: the merge
with its pairs on an existing Dask cluster (docs/merge.md, "Scale-out on Dask").

`lmalign merge --dask-scheduler ADDRESS` runs this module (the CLI's C++ side has no Dask
client); without --dask-scheduler it runs in process, as `lmalign merge`. Options as the CLI's.
"""

import argparse
import json
import os
import sys


def _parser():
    p = argparse.ArgumentParser(prog="lmalign merge", description=__doc__.split("\n\n")[0])
    p.add_argument("manifest", metavar="MANIFEST")
    p.add_argument("-o", "--output", required=True, metavar="OUTDIR")
    p.add_argument("--ground-truth", default=None)
    p.add_argument("--thresholds", default="5,0.1", metavar="ROT_DEG,TRANS_M")
    p.add_argument("--max-pairs", type=int, default=0)
    p.add_argument("--resume", action="store_true")
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--no-fuse", action="store_true")
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--scale", choices=("auto", "free", "fixed"), default="auto",
                   help="as `lmalign merge --scale` (docs/scale.md)")
    p.add_argument("--overlap-check", choices=("repair", "check", "off"), default="repair",
                   help="compare the pairs of maps the graph places overlapping: repair a part "
                        "they contradict, only report it, or neither")
    p.add_argument("--dask-scheduler", default=None, metavar="ADDRESS",
                   help="e.g. tcp://10.0.0.5:8786 (a running `dask scheduler`)")
    return p


def main(argv=None):
    args = _parser().parse_args(argv)
    import lmalign

    if not lmalign.HAVE_MERGE:
        sys.exit("lmalign merge: this lmalign was built without lmalign::merge (needs Ceres)")
    try:
        thresholds = tuple(float(v) for v in args.thresholds.split(","))
    except ValueError:
        thresholds = ()
    if len(thresholds) != 2:
        sys.exit("lmalign merge: --thresholds: expected ROT_DEG,TRANS_M, e.g. 5,0.1")
    client = None
    try:
        if args.dask_scheduler:
            try:
                from distributed import Client
            except ImportError as e:
                sys.exit("lmalign merge --dask-scheduler: needs Dask distributed "
                         "(apt-get install python3-distributed): %s" % e)
            try:
                client = Client(args.dask_scheduler, timeout="30s")
            except (OSError, TimeoutError, ValueError) as e:
                sys.exit("lmalign merge --dask-scheduler %s: cannot reach the Dask scheduler: %s"
                         % (args.dask_scheduler, e))
        run = lmalign.merge(args.manifest, args.output, ground_truth=args.ground_truth,
                            max_pairs=args.max_pairs, threads=args.threads, dask_client=client,
                            resume=args.resume, thresholds=thresholds,
                            fuse_landmarks=not args.no_fuse, scale=args.scale,
                            plots=not args.no_plots, overlap_check=args.overlap_check)
    except lmalign.Error as e:
        sys.exit("lmalign merge: %s" % e)
    finally:
        if client is not None:
            client.close()
    print("merged %d maps: %d candidate pairs (%d reused), %d trusted, %d in the graph, %d "
          "rejected by it; %d component(s); final chi2 %.3f (edge covariance scale %.3g)"
          % (len(run.names), len(run.edges), run.edges_reused, run.trusted.sum(), run.used.sum(),
             run.rejected.sum(), run.num_components, run.final_chi2, run.edge_covariance_scale))
    print("time: edges %.2f s, graph %.2f s (%s)" % (run.seconds_edges, run.seconds_graph,
                                                     run.backend))
    for name, p in zip(run.names, run.graph.maps):  # as the CLI prints them
        if p.scale_free or p.scale != 1.0:
            print("scale of %s: %.6g world units per map unit (sd %.2g)%s"
                  % (name, p.scale, p.scale_sd, "" if p.scale_free else " (held)"))
    for e, report in zip(run.edges, run.graph.edges):
        if report.rejected:
            why = report.reject_reason or "chi2 %.1f after optimisation" % report.chi2
            print("rejected edge: %s -> %s (%s)" % (run.names[e.source], run.names[e.target], why))
    # Which maps hold the same landmarks and why a map stands alone: summary.json's (map_notes).
    with open(os.path.join(args.output, "summary.json")) as f:
        summary = json.load(f)
    for later, earlier in summary.get("same_landmarks", []):
        print("same landmarks: %s and %s (one map listed twice, or one map in two files)"
              % (earlier, later))
    for m in summary.get("maps_alone", []):
        print("alone: %s: %s" % (m["name"], m["reason"]))
    # Folds the merge could not rule out (merge/folds.hpp), as the CLI prints them.
    for f in summary.get("suspected_folds", []):
        print("suspected fold: %d trusted edges that the graph rejected agree on moving part of "
              "component %d by %.3g m / %.3g deg (maps %s): a look-alike place, or a wrong prior, "
              "may have put those maps in the wrong place; see suspected_folds in summary.json "
              "(docs/merge.md)"
              % (len(f["edges"]), f["component"], f["motion_m"], f["motion_deg"],
                 ", ".join(f["maps"])))
    if run.evaluation is not None:
        ev = run.evaluation
        print("ground truth (within %g deg / %g m): %d part(s), the largest of %d map(s); the "
              "kept edges join the maps into %d piece(s)"
              % (thresholds + (ev["num_parts"], ev["largest_part"], ev["num_edge_parts"])))
        for i, name in enumerate(run.names):
            if ev["rotation_deg"][i] != ev["rotation_deg"][i]:  # NaN: alone without priors
                print("  %-20s component %d  not placed: alone in its part"
                      % (name, run.components[i]))
                continue
            note = ("  (not placed: in a part apart from the others)" if not ev["placed"][i]
                    else "" if ev["within"][i] else "  (outside)")
            print("  %-20s component %d  rotation %.3f deg  translation %.4f m%s"
                  % (name, run.components[i], ev["rotation_deg"][i], ev["translation_m"][i],
                     note))
        n = len(run.names)
        pairs = ("not computed (over 2000 maps)"
                 if ev["pair_fraction_within"] != ev["pair_fraction_within"] else
                 "%d of %d (%.1f%%)" % (ev["pairs_within"], n * (n - 1) // 2,
                                        100.0 * ev["pair_fraction_within"]))
        print("  within: %.1f%% of the maps (placed: %d of %d); pairs within: %s; edges kept %d, "
              "false kept %d, precision %.3f, recall %.3f"
              % (100.0 * ev["fraction_within"], ev["num_placed"], n, pairs, ev["kept_edges"],
                 ev["false_kept_edges"], ev["edge_precision"], ev["edge_recall"]))
    print("wrote: %s (poses.yaml, poses.json, edges.csv, summary.json, merged map, edges/)"
          % args.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
