#!/usr/bin/env python3
"""Cairn's Python package against GTSAM's Python wheel, timed in one process:
each file read and solved by Gauss-Newton from the file's values, the same
iteration cap (100) for both, each library's own stopping rules otherwise.
Also checks that Python gives the CLI's χ² (`cairn solve --solver gn --init
file`). Prints a Markdown table (docs/python.md has the last run).

  pip install ./python gtsam==4.3.0        # into one environment
  python3 scripts/python_bench.py [--shared ../shared] [--repeat 5] [--cairn target/release/cairn]
"""

import argparse
import json
import os
import statistics
import subprocess
import time

import cairn
import gtsam
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
FILES = ["2d/city10000.g2o", "3d/sphere2500.g2o"]
CAP = 100


def run_cairn(path):
    t0 = time.perf_counter()
    graph = cairn.read_g2o(path)
    t1 = time.perf_counter()
    summary = graph.optimize(solver="gn", init="file", max_iterations=CAP)
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1, summary.chi2, summary.iterations


def run_gtsam(path, is3d):
    t0 = time.perf_counter()
    graph, initial = gtsam.readG2o(path, is3d)
    # The gauge: a tight prior on the first pose, as Cairn holds it fixed.
    first = min(initial.keys())
    if is3d:
        noise = gtsam.noiseModel.Diagonal.Sigmas(np.full(6, 1e-6))
        graph.add(gtsam.PriorFactorPose3(first, initial.atPose3(first), noise))
    else:
        noise = gtsam.noiseModel.Diagonal.Sigmas(np.full(3, 1e-6))
        graph.add(gtsam.PriorFactorPose2(first, initial.atPose2(first), noise))
    t1 = time.perf_counter()
    params = gtsam.GaussNewtonParams()
    params.setMaxIterations(CAP)
    optimizer = gtsam.GaussNewtonOptimizer(graph, initial, params)
    result = optimizer.optimize()
    t2 = time.perf_counter()
    # GTSAM's error is ½Σ eᵀΩe; the prior adds ~0 at the fixed first pose.
    return t1 - t0, t2 - t1, 2.0 * graph.error(result), optimizer.iterations()


def cli_chi2(binary, path):
    out = subprocess.run([binary, "solve", path, "--solver", "gn", "--init", "file",
                          "-i", str(CAP), "--json", "-q"],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout)["summary"]["final_chi2"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--shared", default=os.path.join(ROOT, "../shared"))
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--cairn", default=os.path.join(ROOT, "target/release/cairn"))
    a = ap.parse_args()
    print("| file | Cairn read + solve (s) | GTSAM read + solve (s) | ratio | Cairn χ² (its.) "
          "| GTSAM 2·error (its.) | CLI χ² | Python − CLI (rel.) |")
    print("|---|---|---|---|---|---|---|---|")
    for name in FILES:
        path = os.path.join(a.shared, "datasets", name)
        is3d = name.startswith("3d/")
        ours, theirs = [], []
        for _ in range(a.repeat):  # alternated, so drift hits both alike
            ours.append(run_cairn(path))
            theirs.append(run_gtsam(path, is3d))
        c = statistics.median(r[0] + r[1] for r in ours)
        g = statistics.median(r[0] + r[1] for r in theirs)
        cli = cli_chi2(a.cairn, path)
        chi2, its = ours[0][2], ours[0][3]
        print("| %s | %.3f (%.3f + %.3f) | %.3f (%.3f + %.3f) | %.2f× | %.6f (%d) | %.6f (%d) | %.6f | %.1e |" % (
            name, c, statistics.median(r[0] for r in ours), statistics.median(r[1] for r in ours),
            g, statistics.median(r[0] for r in theirs), statistics.median(r[1] for r in theirs),
            c / g, chi2, its, theirs[0][2], theirs[0][3], cli, abs(chi2 - cli) / cli))


if __name__ == "__main__":
    main()
