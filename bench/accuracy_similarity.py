"""The Sim(3) datasets of bench/run_accuracy.py (docs/scale.md, "Measured"; docs/accuracy.md,
"Multi-dataset benchmark").

Each entry of the config's `similarity:` list takes a rigid dataset of the benchmark (`of`), moves
its source by a known similarity M (`p_new = s R p_source + t`: scale, then roll about x, pitch
about y, yaw about z, R = Rz Ry Rx, then the translation, in the source's units) and marks it as
of arbitrary scale (`lmalign convert --transform M --map-scale arbitrary`), as a monocular SLAM
or structure-from-motion map would be. The truth of the new pair is T_true M^-1. The default
(`lmalign align`, `--scale auto`, hence free) aligns it from the same starts (protocol
displacements) as the rigid pair, one thread each, the two runs of a start back to back so they
see the same load. Reported: right basin, trusted, median scale, rotation and translation errors
of the right-basin results, and the time of the Sim(3) alignment against the rigid one (the
whole call, `total_time_s`): median of each and the median of the per-start ratios.
"""
import math
import os
import statistics
import subprocess

import accuracy_default


class SimilarityError(Exception):
    """A one-line error naming the config field or the failed command."""


KEYS = {"name", "of", "scale", "roll_deg", "pitch_deg", "yaw_deg", "translation", "starts"}


def check_entries(entries, dataset_names, where):
    """Checks the config's `similarity:` list; returns it with defaults filled."""
    if entries is None:
        return []
    if not isinstance(entries, list):
        raise SimilarityError("%s: expected a list" % where)
    seen = set()
    for i, e in enumerate(entries):
        at = "%s[%d]" % (where, i)
        if not isinstance(e, dict) or "name" not in e or "of" not in e:
            raise SimilarityError("%s: expected a mapping with name and of" % at)
        unknown = sorted(set(e) - KEYS)
        if unknown:
            raise SimilarityError("%s: unknown key '%s' (known: %s)"
                                  % (at, unknown[0], ", ".join(sorted(KEYS))))
        if e["name"] in seen or e["name"] in dataset_names:
            raise SimilarityError("%s.name: '%s' is used twice" % (at, e["name"]))
        seen.add(e["name"])
        if e["of"] not in dataset_names:
            raise SimilarityError("%s.of: '%s' is not a dataset of the config" % (at, e["of"]))
        s = e.get("scale")
        if not isinstance(s, (int, float)) or not math.isfinite(s) or not s > 0:
            raise SimilarityError("%s.scale: expected a number > 0, got %r" % (at, s))
        for k in ("roll_deg", "pitch_deg", "yaw_deg"):
            v = e.setdefault(k, 0.0)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise SimilarityError("%s.%s: expected a finite number (degrees)" % (at, k))
        t = e.setdefault("translation", [0.0, 0.0, 0.0])
        if (not isinstance(t, list) or len(t) != 3 or
                not all(isinstance(v, (int, float)) and math.isfinite(v) for v in t)):
            raise SimilarityError("%s.translation: expected [x, y, z] (source units)" % at)
        n = e.setdefault("starts", 8)
        if not isinstance(n, int) or n < 1:
            raise SimilarityError("%s.starts: expected an integer >= 1" % at)
    return entries


def similarity_matrix(e):
    """M = [s R t; 0 1] of an entry, R = Rz(yaw) Ry(pitch) Rx(roll)."""
    d = accuracy_default
    R = d.matmul4(d.rotation4([0, 0, 1], math.radians(e["yaw_deg"])),
                  d.matmul4(d.rotation4([0, 1, 0], math.radians(e["pitch_deg"])),
                            d.rotation4([1, 0, 0], math.radians(e["roll_deg"]))))
    M = [[e["scale"] * R[r][c] for c in range(3)] + [float(e["translation"][r])]
         for r in range(3)]
    return M + [[0.0, 0.0, 0.0, 1.0]]


def inverse_similarity(M):
    """[sR t; 0 1]^-1 = [R^T / s, -R^T t / s; 0 1]."""
    s = math.pow(abs(_det3(M)), 1.0 / 3.0)
    inv = [[M[c][r] / (s * s) for c in range(3)] for r in range(3)]  # (sR)^T / s^2 = R^T / s
    t = [-sum(inv[r][k] * M[k][3] for k in range(3)) for r in range(3)]
    return [inv[r] + [t[r]] for r in range(3)] + [[0.0, 0.0, 0.0, 1.0]]


def _det3(M):
    return (M[0][0] * (M[1][1] * M[2][2] - M[1][2] * M[2][1]) -
            M[0][1] * (M[1][0] * M[2][2] - M[1][2] * M[2][0]) +
            M[0][2] * (M[1][0] * M[2][1] - M[1][1] * M[2][0]))


def make_pair(lmalign, e, source, truth, folder, log):
    """Writes the moved source and the new truth into folder; returns (source, truth) paths."""
    os.makedirs(folder, exist_ok=True)
    M = similarity_matrix(e)
    T_true = (accuracy_default.identity4() if truth == "identity"
              else accuracy_default.read_transform(truth))
    new_truth = os.path.join(folder, "S_target_source.txt")
    new_source = os.path.join(folder, "source.txt")
    m_path = os.path.join(folder, "M.txt")
    accuracy_default.write_transform(m_path, M)
    if not os.path.isfile(new_source) or os.path.getmtime(new_source) < os.path.getmtime(source):
        cmd = [lmalign, "convert", source, new_source, "--transform", m_path,
               "--map-scale", "arbitrary"]
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        with open(log, "a") as f:
            f.write("$ " + " ".join(cmd) + "\n" + p.stdout + p.stderr)
        if p.returncode != 0:
            last = (p.stderr.strip().splitlines() or ["exit code %d" % p.returncode])[-1]
            raise SimilarityError("lmalign convert failed: %s (log: %s)" % (last, log))
    accuracy_default.write_transform(new_truth,
                                     accuracy_default.matmul4(T_true, inverse_similarity(M)))
    return new_source, new_truth


def _median(values):
    return statistics.median(values) if values else None


def similarity_report(lmalign, e, d, source, target, truth, starts, folder, log):
    """Aligns the rigid pair of dataset d and its moved copy from the same starts (the first
    e['starts'] of `starts`, protocol displacements as 6 numbers); returns the report."""
    sim_source, sim_truth = make_pair(lmalign, e, source, truth, os.path.join(folder, "maps"),
                                      log)
    thresholds = (float(d["rotation_deg"]), float(d["translation_m"]))
    rigid = accuracy_default.Aligner(lmalign, source, target, truth, thresholds,
                                     os.path.join(folder, "rigid"), log)
    sim = accuracy_default.Aligner(lmalign, sim_source, target, sim_truth, thresholds,
                                   os.path.join(folder, "sim3"), log)
    runs = []
    try:
        for D in starts[:e["starts"]]:
            r = rigid.run(displace=D, omp_threads=1)
            s = sim.run(displace=D, omp_threads=1)
            runs.append((r, s))
    except accuracy_default.DefaultError as err:
        raise SimilarityError("similarity %s: %s" % (e["name"], err))
    sims = [s for _, s in runs]
    right = [s for s in sims if s.get("right_basin")]
    time_of = [(float(r.get("total_time_s", r["wall_time_s"])),
                float(s.get("total_time_s", s["wall_time_s"]))) for r, s in runs]
    ratios = [ts / tr for tr, ts in time_of if tr > 0]
    return {
        "of": e["of"], "scale": e["scale"],
        "rotation_deg": [e["roll_deg"], e["pitch_deg"], e["yaw_deg"]],
        "translation": e["translation"], "starts": len(runs),
        "scale_mode": sorted({s.get("scale_mode") for s in sims}),
        "right_basin_rate": len(right) / len(sims) if sims else None,
        "trusted_rate": sum(1 for s in sims if s.get("trustworthy")) / len(sims) if sims else None,
        "trusted_wrong": sum(1 for s in sims if s.get("trustworthy") and not s.get("right_basin")),
        "median_scale_error": _median([s["scale_error"] for s in right if "scale_error" in s]),
        "median_rotation_error_deg": _median([s["rotation_error_deg"] for s in right]),
        "median_translation_error_m": _median([s["translation_error_m"] for s in right]),
        "rigid_right_basin_rate": (sum(1 for r, _ in runs if r.get("right_basin")) / len(runs)
                                   if runs else None),
        "median_time_rigid_s": _median([t for t, _ in time_of]),
        "median_time_sim3_s": _median([t for _, t in time_of]),
        "median_time_ratio": _median(ratios),
        "time_ratio_range": [min(ratios), max(ratios)] if ratios else None,
    }


COLUMNS = ["name", "of", "scale", "starts", "scale_mode", "right_basin_rate", "trusted_rate",
           "trusted_wrong", "median_scale_error", "median_rotation_error_deg",
           "median_translation_error_m", "rigid_right_basin_rate", "median_time_rigid_s",
           "median_time_sim3_s", "median_time_ratio"]


def csv_rows(reports):
    rows = []
    for name, rep in reports.items():
        row = {"name": name}
        row.update({k: rep.get(k) for k in COLUMNS if k != "name"})
        row["scale_mode"] = "/".join(rep["scale_mode"])
        rows.append(row)
    return rows


def markdown(reports):
    """The Sim(3) table of accuracy.md."""
    if not reports:
        return ""

    def num(v, f):
        return "-" if v is None else f % v

    lines = ["", "## Sim(3): the default on similarity-moved copies", "",
             "| dataset | of | scale | starts | right basin | trusted | scale error | "
             "rotation error | translation error | time rigid | time Sim(3) | ratio (range) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, r in reports.items():
        rng = r.get("time_ratio_range")
        lines.append("| %s | %s | %g | %d | %s | %s | %s | %s | %s | %s | %s | %s%s |" % (
            name, r["of"], r["scale"], r["starts"], num(100 * r["right_basin_rate"]
                                                       if r["right_basin_rate"] is not None
                                                       else None, "%.0f%%"),
            num(100 * r["trusted_rate"] if r["trusted_rate"] is not None else None, "%.0f%%"),
            num(100 * r["median_scale_error"] if r["median_scale_error"] is not None else None,
                "%.3f%%"),
            num(r["median_rotation_error_deg"], "%.3g°"),
            num(r["median_translation_error_m"], "%.3g"),
            num(r["median_time_rigid_s"], "%.2f s"), num(r["median_time_sim3_s"], "%.2f s"),
            num(r["median_time_ratio"], "%.2fx"),
            "" if not rng else " (%.2f-%.2f)" % tuple(rng)))
    return "\n".join(lines) + "\n"
