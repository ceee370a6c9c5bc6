#!/usr/bin/env python3
"""The association accuracy a method without tracker ids can reach: each scan
of a simulated run matched from the TRUE poses and the TRUE map, as the scan's
most likely assignment under the front end's own model (Mahalanobis distance
plus log-determinant, a colour penalty, clutter as an alternative, no cone
taken twice). What is left wrong is the sensor's noise alone.

  cargo build --release
  python3 scripts/association_limit.py --preset hard --seeds 5 \\
      ../shared/tracks/eufs_boa_constrictor.csv ../shared/tracks/eufs_peanut.csv

Simulates each track with `cairn fs-sim` (seeds 0..N-1, two laps) into a
temporary folder and prints, per track, the share of detections matched right
(false positives count: right when left unmatched), scored as `cairn fs-eval`
scores a run, and the same for each detection matched alone.

  python3 scripts/association_limit.py --mrclam ../shared/real/mrclam/MRCLAM_Dataset6

A real recording has no true poses in the sensor's own terms: Vicon and the
surveyed map disagree with MRCLAM's camera by about 0.1 m (its offsets and
calibration), as much as the tubes' spacing. So each robot is imported and
solved by `cairn fs-smooth` given the barcodes, and its scans are matched
from that solution's poses and map under configs/mrclam.toml's noise: what a
front end that found the self-consistent solution would get. (Optimistic by
as much as the solution was fitted to those same detections.)
"""

import argparse
import collections
import csv
import json
import math
import os
import subprocess
import tempfile
import tomllib

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

# The simulator's presets (fs-tools/src/sim.rs) and the front end's
# model (frontend/config.rs, FINAL_GATE): range σ = a + b·r, bearing σ,
# false positives per scan.
PRESETS = {"standard": (0.05, 0.01, math.radians(0.5), 0.3),
           "hard": (0.1, 0.02, math.radians(2.0), 1.0)}
GATE = 18.42           # χ²(2) at 99.99%, the end-of-run gate
COLOR_PENALTY = 6.0    # FrontEndConfig::color_penalty
FOV, MAX_RANGE = math.pi, 15.0


def read_run(folder):
    cones = [(r["tag"], float(r["x"]), float(r["y"]))
             for r in csv.DictReader(open(os.path.join(folder, "truth_map.csv")))]
    poses = {}
    for line in open(os.path.join(folder, "truth_traj.tum")):
        t, x, y, _, _, _, qz, qw = map(float, line.split())
        poses[round(t * 1000)] = (x, y, 2 * math.atan2(qz, qw))
    truth = {(int(r["scan"]), int(r["det"])): int(r["landmark"])
             for r in csv.DictReader(open(os.path.join(folder, "truth_assoc.csv")))}
    scans = [r for r in map(json.loads, open(os.path.join(folder, "log.jsonl"))) if "cones" in r]
    return cones, poses, truth, scans


def colours_agree(detected, cone):
    return detected in ("unknown", cone) or (detected.endswith("orange") and cone.endswith("orange"))


def candidates(detection, pose, cones, noise):
    """(cost, cone) within the gate: d² + ln det S in the plane, as the front end."""
    a, b, sigma_b, _ = noise
    x, y, yaw = pose
    out = []
    for j, (tag, cx, cy) in enumerate(cones):
        r = math.hypot(cx - x, cy - y)
        if abs(r - detection["r"]) > 3.0:
            continue
        sigma_r = a + b * r
        db = (detection["b"] - math.atan2(cy - y, cx - x) + yaw + math.pi) % (2 * math.pi) - math.pi
        d2 = ((detection["r"] - r) / sigma_r) ** 2 + (db / sigma_b) ** 2
        if not colours_agree(detection["color"], tag):
            d2 += COLOR_PENALTY
        if d2 < GATE:
            out.append((d2 + 2 * math.log(sigma_r * sigma_b * r), j))
    return out


def hungarian(cost):
    """Rows to columns (rows ≤ columns) with the least total cost."""
    n, m = len(cost), len(cost[0])
    u, v, p, way = [0.0] * (n + 1), [0.0] * (m + 1), [0] * (m + 1), [0] * (m + 1)
    for i in range(1, n + 1):
        p[0], j0 = i, 0
        least, used = [math.inf] * (m + 1), [False] * (m + 1)
        while True:
            used[j0] = True
            i0, delta, j1 = p[j0], math.inf, 0
            for j in range(1, m + 1):
                if not used[j]:
                    c = cost[i0 - 1][j - 1] - u[i0] - v[j]
                    if c < least[j]:
                        least[j], way[j] = c, j0
                    if least[j] < delta:
                        delta, j1 = least[j], j
            for j in range(m + 1):
                if used[j]:
                    u[p[j]] += delta
                    v[j] -= delta
                else:
                    least[j] -= delta
            j0 = j1
            if p[j0] == 0:
                break
        while j0:
            j1 = way[j0]
            p[j0] = p[j1]
            j0 = j1
    rows = [0] * n
    for j in range(1, m + 1):
        if p[j]:
            rows[p[j] - 1] = j - 1
    return rows


def assign(pairs, clutter):
    """The scan's most likely assignment: a cone per detection or None.
    Detections that share no candidate are assigned apart."""
    group = list(range(len(pairs)))

    def root(i):
        while group[i] != i:
            group[i] = group[group[i]]
            i = group[i]
        return i

    holder = {}
    for i, ps in enumerate(pairs):
        for _, j in ps:
            group[root(i)] = root(holder.setdefault(j, i))
    members = collections.defaultdict(list)
    for i in range(len(pairs)):
        members[root(i)].append(i)
    chosen = [None] * len(pairs)
    for rows in members.values():
        cones = sorted({j for i in rows for _, j in pairs[i]})
        column = {j: k for k, j in enumerate(cones)}
        cost = [[1e9] * (len(cones) + len(rows)) for _ in rows]
        for r, i in enumerate(rows):
            for c, j in pairs[i]:
                cost[r][column[j]] = c
            cost[r][len(cones) + r] = clutter
        for r, k in enumerate(hungarian(cost)):
            chosen[rows[r]] = cones[k] if k < len(cones) else None
    return chosen


def limit(folder, noise, view=(FOV, MAX_RANGE), solved=None):
    """`solved`: (map, trajectory) files in `folder` to match from instead
    of the truth, the trajectory one pose per scan."""
    cones, poses, truth, scans = read_run(folder)
    if solved:
        cones = [(r["tag"], float(r["x"]), float(r["y"]))
                 for r in csv.DictReader(open(os.path.join(folder, solved[0])))]
        rows = [list(map(float, line.split())) for line in open(os.path.join(folder, solved[1]))]
        if len(rows) != len(scans):
            raise SystemExit(f"{solved[1]}: {len(rows)} poses for {len(scans)} scans")
        per_scan = [(r[1], r[2], 2 * math.atan2(r[6], r[7])) for r in rows]
    sector = 0.5 * view[0] * view[1] ** 2
    clutter = -2 * math.log(noise[3] / sector) - 2 * math.log(2 * math.pi)
    right = collections.Counter()
    for s, scan in enumerate(scans):
        pose = per_scan[s] if solved else poses[round(scan["t"] * 1000)]
        pairs = [candidates(d, pose, cones, noise) for d in scan["cones"]]
        alone = [min(ps + [(clutter, None)])[1] for ps in pairs]
        for i, chosen in enumerate(assign(pairs, clutter)):
            t = truth.get((s, i), -1)
            t = None if t < 0 else t
            right["jointly"] += chosen == t
            right["alone"] += alone[i] == t
            right["all"] += 1
    return right


def mrclam(dataset, cairn):
    """Per robot of an MRCLAM dataset: the scans matched from the barcode
    smoother's solution (see the module's text)."""
    config = os.path.join(ROOT, "configs", "mrclam.toml")
    c = tomllib.load(open(config, "rb"))
    noise = (c["range_sigma"], c["range_sigma_relative"], c["bearing_sigma"], c["false_positives"])
    print("| robot | jointly, per scan | each detection alone |\n|---|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for robot in range(1, 6):
            folder = os.path.join(tmp, f"r{robot}")
            run = lambda *args: subprocess.run([cairn, *args], check=True, capture_output=True)
            run("fs-import", "mrclam", dataset, "--robot", str(robot), "-o", folder)
            run("fs-smooth", folder + "/log.jsonl", "--assoc", folder + "/truth_assoc.csv",
                "--config", config, "--map-out", folder + "/s.csv", "--traj-out",
                folder + "/s.tum", "--assoc-out", folder + "/s_assoc.csv")
            right = limit(folder, noise, (c["fov"], c["max_range"]), ("s.csv", "s.tum"))
            print(f"| {robot} | {100 * right['jointly'] / right['all']:.2f}% "
                  f"| {100 * right['alone'] / right['all']:.2f}% |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("tracks", nargs="*", help="track files (any format fs-sim reads)")
    ap.add_argument("--mrclam", metavar="DATASET", help="an MRCLAM dataset folder instead")
    ap.add_argument("--preset", choices=sorted(PRESETS), default="hard")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--cairn", default=os.path.join(ROOT, "target", "release", "cairn"))
    a = ap.parse_args()
    if a.mrclam:
        return mrclam(a.mrclam, a.cairn)
    print(f"| track | jointly, per scan | each detection alone |\n|---|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for track in a.tracks:
            total = collections.Counter()
            for seed in range(a.seeds):
                folder = os.path.join(tmp, f"{os.path.basename(track)}-{seed}")
                subprocess.run([a.cairn, "fs-sim", "--track", track, "--preset", a.preset,
                                "--seed", str(seed), "-o", folder], check=True,
                               capture_output=True)
                total += limit(folder, PRESETS[a.preset])
            name = os.path.splitext(os.path.basename(track))[0]
            print(f"| {name} | {100 * total['jointly'] / total['all']:.2f}% "
                  f"| {100 * total['alone'] / total['all']:.2f}% |")


if __name__ == "__main__":
    main()
