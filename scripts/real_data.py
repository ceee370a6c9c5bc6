#!/usr/bin/env python3
"""The real-data report: every estimator and association method on each robot
of MRCLAM Datasets 6 and 1, with and without the barcodes as tracker ids,
beside the batch smoother given the barcodes as associations. Writes the
tables between the `results` and `results-dataset1` markers of
docs/real-data.md and a map plot per robot.

  python3 scripts/real_data.py [--cairn target/release/cairn] [--shared ../shared]
"""

import argparse
import csv
import json
import math
import os
import re
import subprocess
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
ESTIMATORS = ["graph", "ekf", "fastslam1", "fastslam2"]
ASSOCIATIONS = ["ml", "scnn", "jcbb"]


def run(cmd):
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit("%s failed: %s" % (" ".join(cmd), out.stderr))
    return out


def score(cairn, truth, folder, plot=None, title=None):
    """fs-eval's report with the map placed by its best rigid alignment first
    (`--align`, as the real-data issue counts "mapped"); the ATE is the
    trajectory's in its own frame, as the log's start pose put it. Its
    `matches` are the landmarks matched one-to-one, by true cone."""
    cmd = [cairn, "fs-eval", "--truth", truth, "--map", folder + "/map.csv",
           "--traj", folder + "/traj.tum", "--assoc", folder + "/assoc.csv", "--json"]
    unplaced = json.loads(run(cmd).stdout)
    cmd += ["--align", "--matches-out", folder + "/matches.csv"]
    if plot:
        cmd += ["--plot", plot, "--title", title]
    report = json.loads(run(cmd).stdout)
    report["ate"] = unplaced["ate"]
    with open(folder + "/matches.csv") as f:
        report["matches"] = {int(r["truth_index"]): (float(r["x"]), float(r["y"]),
                                                    float(r["truth_x"]), float(r["truth_y"]))
                             for r in csv.DictReader(f)}
    return report


def aligned_rmse(pairs):
    """RMSE of estimated points (x, y) to true ones after their best rigid
    alignment (2-D Kabsch)."""
    n = len(pairs)
    ex = sum(p[0] for p in pairs) / n
    ey = sum(p[1] for p in pairs) / n
    tx = sum(p[2] for p in pairs) / n
    ty = sum(p[3] for p in pairs) / n
    dot = sum((p[0] - ex) * (p[2] - tx) + (p[1] - ey) * (p[3] - ty) for p in pairs)
    cross = sum((p[0] - ex) * (p[3] - ty) - (p[1] - ey) * (p[2] - tx) for p in pairs)
    a = math.atan2(cross, dot)
    c, s = math.cos(a), math.sin(a)
    err = sum((c * (p[0] - ex) - s * (p[1] - ey) - (p[2] - tx)) ** 2
              + (s * (p[0] - ex) + c * (p[1] - ey) - (p[3] - ty)) ** 2 for p in pairs)
    return math.sqrt(err / n)


def against_graph(reports):
    """Each filter run's map RMSE beside the graph's with the same
    association method, both over the true landmarks both mapped, each map
    aligned on those alone."""
    lines = ["| filter run | landmarks both mapped | filter's map RMSE (m) "
             "| graph's, same landmarks (m) |", "|---|---|---|---|"]
    for (estimator, method), r in reports.items():
        if estimator == "graph":
            continue
        graph = reports[("graph", method)]["matches"]
        common = sorted(set(r["matches"]) & set(graph))
        if len(common) < 3:
            lines.append("| %s, %s | %d | – | – |" % (estimator, method, len(common)))
            continue
        mine = aligned_rmse([r["matches"][i] for i in common])
        theirs = aligned_rmse([graph[i] for i in common])
        lines.append("| %s, %s | %d | %.3f | %.3f |" % (estimator, method, len(common), mine,
                                                        theirs))
    return "\n".join(lines)


def row(label, r):
    mapped = 15 - r["missed"]
    ate = "–" if r.get("ate") is None else "%.2f" % r["ate"]
    return "| %s | %d | %d | %d | %.3f | %.1f%% | %.1f%% | %s |" % (
        label, r["landmarks"], mapped, r["phantom"], r["map_rmse_aligned"],
        100 * r["association_accuracy"], 100 * r["association_accuracy_majority"], ate)


HEADER = ("| run | landmarks | true ones mapped (of 15) | phantom | map RMSE aligned (m) "
          "| association | by majority | ATE (m) |\n|---|---|---|---|---|---|---|---|")


def robot_section(a, dataset, name, robot, work, config, plot):
    """The tables of one robot: the smoother given the barcodes, then every
    estimator and association method, then the barcodes as tracker ids."""
    lines = ["### %s, robot %d\n" % (name, robot), HEADER]
    folder = name.replace(" ", "")
    plain = os.path.join(work, "%s-r%d" % (folder, robot))
    ids = os.path.join(work, "%s-i%d" % (folder, robot))
    run([a.cairn, "fs-import", "mrclam", dataset, "--robot", str(robot), "-o", plain])
    run([a.cairn, "fs-import", "mrclam", dataset, "--robot", str(robot), "--ids", "-o", ids])
    run([a.cairn, "fs-smooth", plain + "/log.jsonl", "--assoc", plain + "/truth_assoc.csv",
         "--config", config, "--map-out", plain + "/map.csv", "--traj-out", plain + "/traj.tum",
         "--assoc-out", plain + "/assoc.csv"])
    lines.append(row("batch smoother, barcodes as associations", score(a.cairn, plain, plain)))
    reports = {}
    for folder, methods, tag in [(plain, ASSOCIATIONS, ""), (ids, ["tracking"], ", `--ids`")]:
        for estimator in ESTIMATORS:
            for method in methods:
                run([a.cairn, "fs-slam", folder + "/log.jsonl", "--config", config,
                     "--estimator", estimator, "--association", method,
                     "--map-out", folder + "/map.csv", "--traj-out", folder + "/traj.tum",
                     "--assoc-out", folder + "/assoc.csv"])
                path = title = None
                if estimator == "graph" and method == "ml" and folder == plain:
                    path = os.path.join(ROOT, plot % robot)
                    title = "MRCLAM %s, robot %d: graph SLAM, ml" % (name, robot)
                r = score(a.cairn, plain, folder, path, title)
                reports[(estimator, method)] = r
                lines.append(row("%s, %s%s" % (estimator, method, tag), r))
    lines += ["", "Over the true landmarks both mapped (`--ids` runs: tracking):", "",
              against_graph(reports)]
    print("%s robot %d done" % (name, robot))
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cairn", default=os.path.join(ROOT, "target/release/cairn"))
    ap.add_argument("--shared", default=os.path.join(ROOT, "../shared"))
    a = ap.parse_args()
    config = os.path.join(ROOT, "configs/mrclam.toml")
    work = tempfile.mkdtemp(prefix="cairn-real-")
    doc = os.path.join(ROOT, "docs/real-data.md")
    text = open(doc).read()
    for name, marker, plot in [("Dataset6", "results", "docs/real-data/robot%d.png"),
                               ("Dataset1", "results-dataset1", "docs/real-data/dataset1-robot%d.png")]:
        dataset = os.path.join(a.shared, "real/mrclam/MRCLAM_" + name)
        sections = [robot_section(a, dataset, name.replace("Dataset", "Dataset "), robot, work,
                                  config, plot) for robot in range(1, 6)]
        text = re.sub(r"(<!-- %s -->\n).*(<!-- /%s -->)" % (marker, marker),
                      lambda m: m.group(1) + "\n\n".join(sections) + "\n" + m.group(2),
                      text, flags=re.S)
    open(doc, "w").write(text)


if __name__ == "__main__":
    main()
