"""The default strategy's search regret, refinement basin and time, for bench/run_accuracy.py
(docs/accuracy.md, "Multi-dataset benchmark").

Everything is read from `lmalign align --json` (no --strategy: whatever the default is), so it
measures the default as the binary has it:

- truth-refined score: the default started at the truth with a prior smaller than its search
  resolution (`--initial-guess TRUTH --prior-sigma S`, S halved until the JSON says
  initialisation "given", i.e. no search), its covariance-gated score `gated_score`: the best
  right-basin one over the truth prior and the basin prior (a tight gate can stop short of the
  truth's optimum);
- search regret per start: the truth-refined score minus the score of the default's answer from
  that start (`--displace D`, the experiment's own displacements); > 0 means the score prefers the
  truth but the search did not return it. Each start is classified: right basin; search failure
  (wrong basin, regret > 1% of the truth-refined score); score failure (wrong basin, the answer
  scores within 1% of the truth or better: the score itself prefers or ties the wrong pose);
- basin: the largest offset from the truth, along the target frame's x, y, z, the road's
  forward direction (outdoor) and in yaw about the up axis through the source's centroid placed by
  the truth, both signs, from which the refinement alone (`--initial-guess` at the offset, the
  basin prior, initialisation "given") ends in the right basin: offsets doubled from a first step
  until one fails, then bisected;
- time per alignment of the starts (median, max) beside the landmark counts.

Each `lmalign align` result is cached as JSON under the dataset's folder, keyed by its arguments
and the binary's size and modification time, so a rerun with the same binary reuses it.
"""
import hashlib
import json
import math
import os
import statistics
import subprocess
from concurrent.futures import ThreadPoolExecutor

# Relative regret above which a start counts as a search failure (the "within 1%").
REGRET_TOLERANCE = 0.01


class DefaultError(Exception):
    """A one-line error (a failed alignment command)."""


# --------------------------------------------------------------------------- small geometry

def identity4():
    return [[1.0 if r == c else 0.0 for c in range(4)] for r in range(4)]


def matmul4(A, B):
    return [[sum(A[r][k] * B[k][c] for k in range(4)) for c in range(4)] for r in range(4)]


def apply4(T, p):
    return [sum(T[r][k] * p[k] for k in range(3)) + T[r][3] for r in range(3)]


def translation4(t):
    T = identity4()
    for r in range(3):
        T[r][3] = t[r]
    return T


def rotation4(axis, angle_rad):
    """Rotation about a unit axis through the origin (Rodrigues)."""
    n = math.sqrt(sum(a * a for a in axis))
    x, y, z = (a / n for a in axis)
    c, s, C = math.cos(angle_rad), math.sin(angle_rad), 1.0 - math.cos(angle_rad)
    T = identity4()
    T[0][:3] = [c + x * x * C, x * y * C - z * s, x * z * C + y * s]
    T[1][:3] = [y * x * C + z * s, c + y * y * C, y * z * C - x * s]
    T[2][:3] = [z * x * C - y * s, z * y * C + x * s, c + z * z * C]
    return T


def read_transform(path):
    rows = []
    with open(path) as f:
        for line in f:
            line = line.split("#")[0].strip()
            if line:
                rows.append([float(v) for v in line.split()])
    if len(rows) != 4 or any(len(r) != 4 for r in rows):
        raise DefaultError("%s: expected a 4x4 transform" % path)
    return rows


def write_transform(path, T):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        for r in T:
            f.write(" ".join("%.17g" % v for v in r) + "\n")
    os.replace(tmp, path)


def read_map_summary(path):
    """(centroid of the landmarks with >= 2 observations, list of frame positions) of a map in
    lmalign's text format (docs/map-format.md); malformed lines are skipped, so any file gives an
    answer (the centroid None when no landmark was read)."""
    total, count, frames = [0.0, 0.0, 0.0], 0, []
    try:
        with open(path) as f:
            for line in f:
                fields = line.split()
                try:
                    if fields and fields[0] == "LANDMARK" and len(fields) >= 15:
                        if int(fields[14]) >= 2:
                            for i in range(3):
                                total[i] += float(fields[2 + i])
                            count += 1
                    elif fields and fields[0] == "FRAME" and len(fields) >= 5:
                        frames.append([float(v) for v in fields[2:5]])
                except ValueError:
                    continue
    except OSError:
        return None, []
    return ([v / count for v in total] if count else None), frames


def forward_direction(frames, up):
    """The principal direction of the frame positions, across the up axis (unit), or None."""
    if len(frames) < 2:
        return None
    n = len(frames)
    mean = [sum(p[i] for p in frames) / n for i in range(3)]
    C = [[sum((p[i] - mean[i]) * (p[j] - mean[j]) for p in frames) for j in range(3)]
         for i in range(3)]
    v = [frames[-1][i] - frames[0][i] for i in range(3)]  # start the power iteration on the drive
    for _ in range(50):
        w = [sum(C[i][j] * v[j] for j in range(3)) for i in range(3)]
        norm = math.sqrt(sum(x * x for x in w))
        if norm == 0.0:
            break
        v = [x / norm for x in w]
    d = sum(v[i] * up[i] for i in range(3))
    v = [v[i] - d * up[i] for i in range(3)]
    norm = math.sqrt(sum(x * x for x in v))
    if norm < 1e-9:
        return None
    v = [x / norm for x in v]
    if sum(v[i] * (frames[-1][i] - frames[0][i]) for i in range(3)) < 0:
        v = [-x for x in v]
    return v


# --------------------------------------------------------------------------- alignment runs

class Aligner:
    """Runs `lmalign align --json` for one dataset, each result cached under `folder`."""

    def __init__(self, lmalign, source, target, truth, thresholds, folder, log, strategy=None):
        """strategy: a preset name for `--strategy` (None: the binary's default)."""
        self.lmalign, self.source, self.target = lmalign, source, target
        self.strategy = strategy
        self.truth_arg = truth  # 'identity' or a 4x4 file
        self.thresholds = thresholds
        self.folder = folder
        self.log = log
        os.makedirs(os.path.join(folder, "runs"), exist_ok=True)
        st = os.stat(lmalign)
        self.binary_key = "%s:%d:%d" % (os.path.abspath(lmalign), st.st_size, st.st_mtime_ns)
        self.T_true = identity4() if truth == "identity" else read_transform(truth)

    def run(self, displace=None, guess=None, prior=None, omp_threads=None):
        """The first result of `lmalign align` (a dict of the JSON's results[0]) for a start:
        displace (6 numbers, the --displace of method.md §5) or guess (4x4) with prior
        (ROT_DEG, TRANS_M)."""
        args = [self.source, self.target, "--ground-truth", self.truth_arg,
                "--success-rotation-deg", "%g" % self.thresholds[0],
                "--success-translation-m", "%g" % self.thresholds[1]]
        if self.strategy is not None:
            args += ["--strategy", self.strategy]
        key_parts = list(args)
        if displace is not None:
            args += ["--displace", ",".join("%.17g" % v for v in displace)]
            key_parts += args[-2:]
        if guess is not None:
            key_parts += ["guess"] + ["%.17g" % v for r in guess for v in r]
        if prior is not None:
            # The refinement from a guess is measured here (its basin, the score refined from the
            # truth), not the prior check's verdict: the prior's search alone (issue 41).
            args += ["--prior-sigma", "%.17g,%.17g" % tuple(prior), "--set",
                     "init.prior_check=off"]
            key_parts += args[-4:]
        if omp_threads is not None:  # a time measured on that many threads
            key_parts += ["omp_threads", str(omp_threads)]
        key = hashlib.sha1("\n".join([self.binary_key] + key_parts).encode()).hexdigest()[:20]
        out = os.path.join(self.folder, "runs", key + ".json")
        if os.path.isfile(out):
            try:
                with open(out) as f:
                    return json.load(f)["results"][0]
            except (OSError, ValueError, KeyError, IndexError):
                os.remove(out)
        if guess is not None:
            guess_path = os.path.join(self.folder, "runs", key + "_guess.txt")
            write_transform(guess_path, guess)
            args += ["--initial-guess", guess_path]
        env = dict(os.environ)
        if omp_threads is not None:
            env["OMP_NUM_THREADS"] = str(omp_threads)
        cmd = [self.lmalign, "align"] + args + ["--json", out]
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        with open(self.log, "a") as f:
            f.write("$ " + " ".join(cmd) + "\n" + p.stderr)
        if p.returncode != 0 or not os.path.isfile(out):
            last = (p.stderr.strip().splitlines() or ["exit code %d" % p.returncode])[-1]
            raise DefaultError("lmalign align failed: %s (log: %s)" % (last, self.log))
        with open(out) as f:
            return json.load(f)["results"][0]

    def given(self, guess, prior):
        """Refinement alone from `guess`: the prior halved (at most 8 times) until the run says
        initialisation "given"; returns (result, prior used) or (result, None) if it never does."""
        for _ in range(9):
            r = self.run(guess=guess, prior=prior, omp_threads=1)
            if r.get("initialisation") == "given":
                return r, prior
            prior = [prior[0] / 2.0, prior[1] / 2.0]
        return r, None


def right_basin(r):
    return bool(r.get("right_basin"))


# --------------------------------------------------------------------------- regret

def starts_of(rows):
    """The distinct starts of an experiment's results.csv rows, in order: (experiment, value,
    displacement x, y, z m, roll, pitch, yaw deg)."""
    seen, out = set(), []
    for r in rows:
        key = (r["experiment"], r["case"])
        if key in seen:
            continue
        seen.add(key)
        out.append((r["experiment"], float(r["value"] or 0.0),
                    [float(r[k]) for k in ("x_m", "y_m", "z_m", "roll_deg", "pitch_deg",
                                           "yaw_deg")]))
    return out


def truth_refined(aligner, priors):
    """The default refined from the truth alone, with each prior of `priors` (each halved until
    "given"): the run with the highest gated score among those in the right basin (the first run
    when none is). A tight gate can stop short of the truth's own optimum, a wider one can slide
    away from it: the best right-basin result stands for "the score at the truth". Returns (run,
    prior used, every (prior asked, prior used, gated score, right basin) tried)."""
    tried, best = [], None
    for prior in priors:
        r, used = aligner.given(aligner.T_true, list(prior))
        tried.append({"prior_sigma": list(prior), "prior_sigma_used": used,
                      "gated_score": r.get("gated_score"), "right_basin": right_basin(r)})
        score = r.get("gated_score")
        if best is None or (right_basin(r) and score is not None and
                            (not right_basin(best[0]) or best[0].get("gated_score") is None or
                             score > best[0]["gated_score"])):
            best = (r, used)
    return best[0], best[1], tried


def regret_report(aligner, rows, truth_priors, truth=None):
    """The default (or the aligner's strategy) from every start of rows, against its
    truth-refined score: truth_refined() over `truth_priors`, or `truth`, a result of it."""
    truth_run, used, tried = truth if truth is not None else truth_refined(aligner, truth_priors)
    truth_score = truth_run.get("gated_score")
    runs = []
    for experiment, value, D in starts_of(rows):
        r = aligner.run(displace=D)
        runs.append((experiment, value, r))
    strategy = runs[0][2].get("strategy") if runs else truth_run.get("strategy")
    times = [r.get("wall_time_s") for _, _, r in runs if r.get("wall_time_s") is not None]
    ok = [r for _, _, r in runs if right_basin(r)]
    trusted = [r for _, _, r in runs if r.get("trustworthy")]
    out = {
        "strategy": strategy,
        "truth_refined": {
            "gated_score": truth_score,
            "prior_sigma": used,
            "tried": tried,
            "initialisation": truth_run.get("initialisation"),
            "rotation_error_deg": truth_run.get("rotation_error_deg"),
            "translation_error_m": truth_run.get("translation_error_m"),
            "trustworthy": truth_run.get("trustworthy"),
            "trust_reason": truth_run.get("trust_reason"),
        },
        "starts": len(runs),
        "right_basin_rate": len(ok) / len(runs) if runs else None,
        "trust_precision": (sum(1 for r in trusted if right_basin(r)) / len(trusted)
                            if trusted else None),
        "trust_recall": (sum(1 for r in ok if r.get("trustworthy")) / len(ok) if ok else None),
        "median_time_s": statistics.median(times) if times else None,
        "max_time_s": max(times) if times else None,
    }
    scores = [r.get("gated_score") for _, _, r in runs]
    if truth_score is None or any(s is None for s in scores) or not runs:
        out["regret"] = None  # the default reports no gated score
        return out
    regrets = [truth_score - s for s in scores]
    scale = max(abs(truth_score), 1e-12)
    search_failures = sum(1 for (_, _, r), g in zip(runs, regrets)
                          if not right_basin(r) and g > REGRET_TOLERANCE * scale)
    score_failures = sum(1 for (_, _, r), g in zip(runs, regrets)
                         if not right_basin(r) and g <= REGRET_TOLERANCE * scale)
    # The worst start: what was returned, and from where.
    worst = max(range(len(runs)), key=lambda i: regrets[i])
    w = runs[worst][2]
    out["regret"] = {
        "max": max(regrets),
        "median": statistics.median(regrets),
        "max_relative": max(regrets) / scale,
        "fraction_above_tolerance": sum(1 for g in regrets if g > REGRET_TOLERANCE * scale)
        / len(regrets),
        "tolerance_relative": REGRET_TOLERANCE,
        "search_failures": search_failures,
        "score_failures": score_failures,
        "worst_start": {"experiment": runs[worst][0], "value": runs[worst][1],
                        "gated_score": w.get("gated_score"),
                        "rotation_error_deg": w.get("rotation_error_deg"),
                        "translation_error_m": w.get("translation_error_m")},
    }
    return out


def pose_errors(T, T_true):
    """(rotation error deg, translation error m) of T against T_true (4x4 lists)."""
    trace = sum(T[k][i] * T_true[k][i] for i in range(3) for k in range(3))
    angle = math.degrees(math.acos(max(-1.0, min(1.0, (trace - 1.0) / 2.0))))
    dt = math.sqrt(sum((T[i][3] - T_true[i][3]) ** 2 for i in range(3)))
    return angle, dt


def reference_report(reference, default, rows, truth):
    """The reference search (issue 39, item 2: the complete search at once, `exhaustive`) from
    the starts of rows, against the same truth-refined score (`truth`, a truth_refined() result)
    as the default's: its regret_report(), and per start how its answer compares with the
    default's (`default`, the default's Aligner; its runs are cached): the same answer (within
    the dataset's right-basin thresholds of each other), and which scores higher by more than
    REGRET_TOLERANCE of the truth-refined score."""
    out = regret_report(reference, rows, None, truth=truth)
    out["strategy"] = reference.strategy
    scale = max(abs(truth[0].get("gated_score") or 0.0), 1e-12)
    same = default_higher = reference_higher = 0
    ratios = []
    starts = starts_of(rows)
    for _, _, D in starts:
        a, b = default.run(displace=D), reference.run(displace=D)
        rot, tr = pose_errors(a["T_target_source"], b["T_target_source"])
        if rot <= reference.thresholds[0] and tr <= reference.thresholds[1]:
            same += 1
        sa, sb = a.get("gated_score"), b.get("gated_score")
        if sa is not None and sb is not None:
            default_higher += sa - sb > REGRET_TOLERANCE * scale
            reference_higher += sb - sa > REGRET_TOLERANCE * scale
        if a.get("wall_time_s") and b.get("wall_time_s"):
            ratios.append(a["wall_time_s"] / b["wall_time_s"])
    out["same_answer_rate"] = same / len(starts) if starts else None
    out["default_scores_higher"] = default_higher
    out["reference_scores_higher"] = reference_higher
    out["median_time_ratio_default_over_reference"] = (statistics.median(ratios) if ratios
                                                       else None)
    return out


# --------------------------------------------------------------------------- basin

def basin_directions(kind_outdoor, up_axis, target_frames):
    """(name, kind, unit vector) per direction: translations along x, y, z of the target frame
    and the road's forward direction (outdoor, from the target's frames), and yaw about up."""
    axes = {"x": [1.0, 0.0, 0.0], "y": [0.0, 1.0, 0.0], "z": [0.0, 0.0, 1.0]}
    out = [(a + "_m", "translation", v) for a, v in axes.items()]
    if kind_outdoor:
        f = forward_direction(target_frames, axes[up_axis])
        if f is not None:
            out.append(("forward_m", "translation", f))
    out.append(("yaw_deg", "yaw", axes[up_axis]))
    return out


def offset_guess(T_true, kind, vector, amount, pivot):
    """The truth moved by `amount` (m, or deg for yaw about `vector` through `pivot`)."""
    if kind == "translation":
        return matmul4(translation4([amount * v for v in vector]), T_true)
    R = rotation4(vector, math.radians(amount))
    about = matmul4(translation4(pivot), matmul4(R, translation4([-p for p in pivot])))
    return matmul4(about, T_true)


def measure_direction(aligner, kind, vector, sign, prior, first, limit, bisections, pivot):
    """Largest offset (>= 0) from which the refinement alone reaches the right basin: doubled
    from `first` (capped at `limit`) until one fails, then bisected `bisections` times between
    the last success and the first failure. Returns (offset, True if `limit` itself succeeded)."""
    def ok(amount):
        r, used = aligner.given(offset_guess(aligner.T_true, kind, vector, sign * amount, pivot),
                                prior)
        return used is not None and right_basin(r)

    lo, hi = 0.0, min(first, limit)
    while ok(hi):
        if hi >= limit:
            return limit, True
        lo, hi = hi, min(2.0 * hi, limit)
    for _ in range(bisections):
        mid = 0.5 * (lo + hi)
        if ok(mid):
            lo = mid
        else:
            hi = mid
    return lo, False


def basin_report(aligner, d, source_path, target_path, prior, bisections, workers):
    """The basin of the default's refinement for dataset d, per direction and sign."""
    centroid, _ = read_map_summary(source_path)
    _, frames = read_map_summary(target_path)
    pivot = apply4(aligner.T_true, centroid) if centroid else [0.0, 0.0, 0.0]
    outdoor = d["kind"] == "outdoor"
    at_truth, used = aligner.given(aligner.T_true, list(prior))
    report = {"prior_sigma": used, "pivot_m": pivot,
              "refined_from_truth_right_basin": right_basin(at_truth), "directions": {}}
    if used is None:
        report["note"] = "no prior made the refinement run alone (initialisation never 'given')"
        return report
    first_m = 0.02 if not outdoor else 0.25
    limit_m = 2.0 if not outdoor else 64.0
    jobs = []
    for name, kind, vector in basin_directions(outdoor, d["up_axis"], frames):
        first, limit = (1.0, 90.0) if kind == "yaw" else (first_m, limit_m)
        for sign in (1.0, -1.0):
            jobs.append((name, sign, kind, vector, first, limit))
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        results = list(pool.map(lambda j: measure_direction(aligner, j[2], j[3], j[1], used, j[4],
                                                            j[5], bisections, pivot), jobs))
    for (name, sign, kind, vector, first, limit), (amount, at_limit) in zip(jobs, results):
        entry = report["directions"].setdefault(name, {"vector": vector, "limit": limit})
        entry["+" if sign > 0 else "-"] = amount
        entry["at_limit" + ("+" if sign > 0 else "-")] = at_limit
    for entry in report["directions"].values():
        entry["min"] = min(entry["+"], entry["-"])
    return report
