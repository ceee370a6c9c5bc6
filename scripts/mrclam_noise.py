#!/usr/bin/env python3
"""Measure the MRCLAM robots' sensor and odometry errors against Vicon.

Usage: python3 scripts/mrclam_noise.py ../shared/real/mrclam/MRCLAM_Dataset6

For every landmark detection with a readable barcode, the range and bearing
the Vicon pose and landmark predict are compared with the measured ones; the
commanded velocities are compared with the Vicon poses' motion over 1 s.
Prints robust spreads (1.4826·MAD) and tail fractions, per range band. These
are the numbers behind configs/mrclam.toml.

It also prints, per robot, how well per-detection maximum likelihood could
associate even with Vicon's poses and the true map under configs/mrclam.toml's
noise: the share of detections whose true landmark is not the most likely
one, with the bearings as measured and without each robot's median bearing
offset (a turned camera, which an estimator's headings absorb). The landmarks
stand in groups of two or three 0.15-0.25 m apart, which range noise of
0.1-0.2 m cannot tell apart along the line of sight.
"""
import bisect
import math
import os
import statistics
import sys


def table(path):
    rows = []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if line and not line.startswith("#"):
                rows.append([float(x) for x in line.split()])
    return rows


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def pose_at(truth, times, t):
    i = bisect.bisect_left(times, t)
    if i == 0 or i == len(times):
        return None
    a, b = truth[i - 1], truth[i]
    if b[0] - a[0] > 0.1:
        return None
    u = (t - a[0]) / (b[0] - a[0])
    return (a[1] + u * (b[1] - a[1]), a[2] + u * (b[2] - a[2]), a[3] + u * wrap(b[3] - a[3]))


def mahalanobis(pose, landmark, r, b):
    """χ² of a range/bearing detection against a landmark from a pose, with
    configs/mrclam.toml's noise (σ_r = 0.02 + 0.04·r, σ_b = 0.014 rad)."""
    dx, dy = landmark[0] - pose[0], landmark[1] - pose[1]
    er = (r - math.hypot(dx, dy)) / (0.02 + 0.04 * r)
    eb = wrap(b - wrap(math.atan2(dy, dx) - pose[2])) / 0.014
    return er * er + eb * eb


def robust_sigma(xs):
    m = statistics.median(xs)
    return m, 1.4826 * statistics.median([abs(x - m) for x in xs])


# The robots answer their commands this late (s): the graph learns a scan
# latency of 153-198 ms on four of Dataset 6's robots (docs/real-data.md).
LAG = 0.15


def turn_errors(odo, truth, times, window=1.0):
    """(commanded |turn|, heading error) over windows of `window` s, the
    true headings read LAG later than the commands."""
    rows = []
    k = 0
    while k < len(odo) - 1:
        t0 = odo[k][0]
        j, turn, turned = k, 0.0, 0.0
        while j + 1 < len(odo) and odo[j + 1][0] - t0 < window:
            dt = odo[j + 1][0] - odo[j][0]
            turn += odo[j][2] * dt
            turned += abs(odo[j][2]) * dt
            j += 1
        if j == k:
            k += 1
            continue
        p0, p1 = pose_at(truth, times, t0 + LAG), pose_at(truth, times, odo[j][0] + LAG)
        k = j
        if p0 is not None and p1 is not None:
            rows.append((turned, wrap(p1[2] - p0[2]) - turn))
    return rows


def main(folder):
    subject = {int(b): int(s) for s, b in table(os.path.join(folder, "Barcodes.dat"))}
    landmarks = {int(r[0]): (r[1], r[2]) for r in table(os.path.join(folder, "Landmark_Groundtruth.dat"))}
    dr, db, ranges, fov = [], [], [], []
    dv, dw, speeds = [], [], []
    turns = []
    biases = {}
    per_frame = []
    ceiling = {}
    scale = {}
    for robot in range(1, 6):
        truth = table(os.path.join(folder, f"Robot{robot}_Groundtruth.dat"))
        times = [r[0] for r in truth]
        frames = {}
        seen = []
        for t, code, r, b in table(os.path.join(folder, f"Robot{robot}_Measurement.dat")):
            s = subject.get(int(code))
            if s is None or s not in landmarks:
                continue
            frames[t] = frames.get(t, 0) + 1
            p = pose_at(truth, times, t)
            if p is None:
                continue
            lx, ly = landmarks[s]
            dx, dy = lx - p[0], ly - p[1]
            dr.append(r - math.hypot(dx, dy))
            db.append(wrap(b - wrap(math.atan2(dy, dx) - p[2])))
            ranges.append(r)
            fov.append(abs(b))
            seen.append((p, r, b, s, db[-1]))
        per_frame.extend(frames.values())
        # The robot's own bearing offset (a camera turned on its mount); the
        # graph's headings can take it up, the truth's cannot.
        offset = statistics.median(e for *_, e in seen)
        for k, shift in enumerate([0.0, offset]):
            wrong = sum(1 for p, r, b, s, _ in seen if min(
                landmarks, key=lambda j: mahalanobis(p, landmarks[j], r, b - shift)) != s)
            ceiling.setdefault(robot, [offset, len(seen), 0, 0])[2 + k] = wrong
        odo = table(os.path.join(folder, f"Robot{robot}_Odometry.dat"))
        turns.extend(turn_errors(odo, truth, times))
        long = turn_errors(odo, truth, times, window=10.0)
        biases[robot] = statistics.mean(e / 10.0 for _, e in long)
        step = 67  # about 1 s of odometry
        for k in range(0, len(odo) - step, step):
            t0, t1 = odo[k][0], odo[k + step][0]
            p0, p1 = pose_at(truth, times, t0), pose_at(truth, times, t1)
            if p0 is None or p1 is None:
                continue
            v_cmd = sum(o[1] for o in odo[k:k + step]) / step
            w_cmd = sum(o[2] for o in odo[k:k + step]) / step
            dt = t1 - t0
            dist = math.hypot(p1[0] - p0[0], p1[1] - p0[1])
            fwd = (p1[0] - p0[0]) * math.cos(p0[2]) + (p1[1] - p0[1]) * math.sin(p0[2])
            dv.append(math.copysign(dist, fwd) / dt - v_cmd)
            dw.append(wrap(p1[2] - p0[2]) / dt - w_cmd)
            speeds.append(abs(v_cmd))
            sums = scale.setdefault(robot, [0.0, 0.0, 0.0, 0.0])
            sums[0] += v_cmd * math.copysign(dist, fwd) / dt
            sums[1] += v_cmd * v_cmd
            sums[2] += w_cmd * wrap(p1[2] - p0[2]) / dt
            sums[3] += w_cmd * w_cmd
    print(f"detections of landmarks: {len(dr)}")
    for lo, hi in [(0, 2), (2, 3), (3, 4), (4, 5), (5, 10)]:
        sel = [i for i, r in enumerate(ranges) if lo <= r < hi]
        if len(sel) < 20:
            continue
        mr, sr = robust_sigma([dr[i] for i in sel])
        mb, sb = robust_sigma([db[i] for i in sel])
        print(f"range {lo}-{hi} m: n={len(sel)} range bias {mr:+.3f} σ {sr:.3f} m; "
              f"bearing bias {math.degrees(mb):+.2f}° σ {math.degrees(sb):.2f}°")
    mr, sr = robust_sigma(dr)
    mb, sb = robust_sigma(db)
    print(f"all: range bias {mr:+.3f} σ {sr:.3f} m; bearing bias {math.degrees(mb):+.2f}° σ {math.degrees(sb):.2f}°")
    big = sum(1 for x, y in zip(dr, db) if abs(x - mr) > 5 * sr or abs(y - mb) > 5 * sb)
    print(f"beyond 5σ in range or bearing: {100 * big / len(dr):.1f}%")
    q = sorted(ranges)
    print(f"range 1st/50th/99th percentile: {q[len(q) // 100]:.2f} / {q[len(q) // 2]:.2f} / {q[99 * len(q) // 100]:.2f} m")
    f = sorted(fov)
    print(f"|bearing| 99th percentile / max: {math.degrees(f[99 * len(f) // 100]):.1f}° / {math.degrees(f[-1]):.1f}°")
    print(f"landmarks per camera frame: mean {statistics.mean(per_frame):.2f}")
    mv, sv = robust_sigma(dv)
    mw, sw = robust_sigma(dw)
    for robot, (vs, vv, ws, ww) in sorted(scale.items()):
        print(f"robot {robot}: true = scale × commanded (least squares over 1 s): "
              f"speed {vs / vv:.3f}, yaw rate {ws / ww:.3f}")
    for robot, (offset, total, wrong, unturned) in sorted(ceiling.items()):
        print(f"robot {robot}: with Vicon's pose and the true map, {100 * wrong / total:.1f}% of "
              f"{total} detections are nearer (χ²) to another landmark than to their own; "
              f"{100 * unturned / total:.1f}% without the robot's bearing offset "
              f"({math.degrees(offset):+.2f}°)")
    print(f"odometry over 1 s: speed error {mv:+.4f} σ {sv:.4f} m/s (mean |v| {statistics.mean(speeds):.3f}); "
          f"yaw-rate error {mw:+.4f} σ {sw:.4f} rad/s")
    # A turn's heading error, beyond the yaw rate's: RMS by how far the
    # commands turned in 1 s; its variance grows as the angle turned.
    for lo, hi in [(0.0, 0.02), (0.02, 0.1), (0.1, 0.2), (0.2, 0.4), (0.4, 10.0)]:
        sel = [(a, e) for a, e in turns if lo <= a < hi]
        if len(sel) < 20:
            continue
        rms = math.sqrt(sum(e * e for _, e in sel) / len(sel))
        mean = statistics.mean(a for a, _ in sel)
        print(f"commanded |turn| {lo}-{hi} rad in 1 s (mean {mean:.3f}), true heading {LAG} s later: "
              f"n={len(sel)} heading error RMS {rms:.4f} rad")
    turning = [(a, e) for a, e in turns if a >= 0.02]
    sigma = math.sqrt(sum(e * e for _, e in turning) / sum(a for a, _ in turning))
    print(f"turn_sigma (heading error² per rad turned, windows turning ≥ 0.02 rad): {sigma:.3f} rad/√rad")
    # A bias is what stays over the whole run: the mean over 10 s windows.
    print("yaw-rate bias (mean error over 10 s windows) by robot: "
          + ", ".join(f"{r}: {b:+.4f}" for r, b in sorted(biases.items())) + " rad/s")


if __name__ == "__main__":
    main(sys.argv[1])
