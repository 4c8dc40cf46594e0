#!/usr/bin/env python3
"""Seeds for the fuzz targets of the new paths, derived from the real data at run time
(fuzz/run_fuzzers.sh; docs/robustness.md). Nothing of the data is copied into the repository.

    fuzz/make_seeds.py DATA_DIR OUT_DIR

Writes OUT_DIR/default_alignment/*: pairs of small maps cut from the real map pairs (TUM fr1/desk
ground-truth pair, KITTI stereo pair): every k-th landmark seen at least twice, 24 per map, with
its first two observations and the frames they name, "SOURCE\\n@@@\\nTARGET"; also with one
landmark moved to 1e9 m and to 1e300 m (a stereo landmark at near-zero disparity).
OUT_DIR/merge_manifest/*: manifests whose priors are poses of the TUM ground-truth trajectory.
OUT_DIR/cli_options/*: --initial-guess / --ground-truth rows from those poses, with displacements
and prior sigmas. A missing data folder writes nothing (the seeds in fuzz/corpus/ remain).
"""
import math
import pathlib
import sys


def small_map(path, count=24):
    """The text of a small map cut from a real map file (lmalign's format)."""
    frames = {}
    landmarks = []
    with open(path) as f:
        for line in f:
            fields = line.split()
            if not fields:
                continue
            if fields[0] == "FRAME":
                frames[fields[1]] = line.strip()
            elif fields[0] == "LANDMARK" and len(fields) >= 21 and int(fields[14]) >= 2:
                landmarks.append(fields)
    if not landmarks:
        return None
    step = max(1, len(landmarks) // count)
    chosen = landmarks[::step][:count]
    used = []
    out = []
    for fields in chosen:
        head = fields[:14]
        obs = fields[15:21]  # the first two observations (frame, u, v)
        for frame in (obs[0], obs[3]):
            if frame not in used:
                used.append(frame)
        out.append(" ".join(head + ["2"] + obs))
    missing = [f for f in used if f not in frames]
    if missing:
        return None
    return "\n".join([frames[f] for f in used] + out) + "\n"


def moved_first_landmark(text, x):
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if line.startswith("LANDMARK"):
            fields = line.split()
            fields[2] = x
            lines[i] = " ".join(fields)
            break
    return "\n".join(lines) + "\n"


def tum_poses(path, count=6):
    """(tx, ty, tz, qx, qy, qz, qw) rows of a TUM trajectory, evenly spaced."""
    rows = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            rows.append([float(v) for v in line.split()[1:8]])
    step = max(1, len(rows) // count)
    return rows[::step][:count]


def matrix(pose):
    tx, ty, tz, qx, qy, qz, qw = pose
    n = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    qx, qy, qz, qw = qx / n, qy / n, qz / n, qw / n
    r = [[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
         [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
         [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]]
    return [r[0] + [tx], r[1] + [ty], r[2] + [tz], [0.0, 0.0, 0.0, 1.0]]


def rows_text(m):
    return ["%.17g %.17g %.17g %.17g" % tuple(row) for row in m]


def main():
    data, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
    written = 0
    pairs = [("desk", data / "tum_fr1_desk/ground_truth_pair/desk_gt_a.txt",
              data / "tum_fr1_desk/ground_truth_pair/desk_gt_b.txt"),
             ("kitti", data / "kitti_stereo_vo/kitti_vo_a_ovl.txt",
              data / "kitti_stereo_vo/kitti_vo_b_ovl.txt")]
    folder = out / "default_alignment"
    for name, a, b in pairs:
        if not (a.exists() and b.exists()):
            continue
        source, target = small_map(a), small_map(b)
        if source is None or target is None:
            continue
        folder.mkdir(parents=True, exist_ok=True)
        for suffix, s in (("", source), ("_far1e9", moved_first_landmark(source, "1e9")),
                          ("_far1e300", moved_first_landmark(source, "1e300"))):
            (folder / ("%s%s.txt" % (name, suffix))).write_text(s + "@@@\n" + target)
            written += 1
    trajectory = data / "tum_fr1_desk/groundtruth.txt"
    if trajectory.exists():
        poses = [matrix(p) for p in tum_poses(trajectory)]
        folder = out / "merge_manifest"
        folder.mkdir(parents=True, exist_ok=True)
        entries = []
        for i, m in enumerate(poses):
            rows = ", ".join("[" + ", ".join("%.17g" % v for v in row) + "]" for row in m)
            prior = ("prior_sigma: [2.0, 0.1]" if i % 2 == 0 else
                     "prior_covariance: [[0.01,0,0,0,0,0],[0,0.01,0,0,0,0],[0,0,0.01,0,0,0],"
                     "[0,0,0,0.001,0,0],[0,0,0,0,0.001,0],[0,0,0,0,0,0.001]]")
            entries.append("  - {name: w%d, path: maps/w%d.txt, session: desk, T_world_map: [%s],"
                           " %s}" % (i, i, rows, prior))
        (folder / "desk_trajectory_priors.yaml").write_text("maps:\n" + "\n".join(entries) + "\n")
        (folder / "desk_two_priors.yaml").write_text("maps:\n" + "\n".join(entries[:2]) + "\n")
        written += 2
        folder = out / "cli_options"
        folder.mkdir(parents=True, exist_ok=True)
        for i, m in enumerate(poses[:3]):
            lines = ["guess " + r for r in rows_text(m)]
            lines += ["prior-sigma 5,0.5", "displace 0.1,-0.2,0.05,1,-2,30"]
            if i == 1:
                lines += ["truth " + r for r in rows_text(m)]
            (folder / ("desk_pose_%d.txt" % i)).write_text("\n".join(lines) + "\n")
            written += 1
    print("fuzz seeds from %s: %d files in %s" % (data, written, out))


if __name__ == "__main__":
    main()
