#!/usr/bin/env python3
"""Issue #3's per-iteration overhead over repeated runs: the share of Cairn's
GN solve spent outside the numeric factorisation and the triangular solves
(linearising, the one-off setup, updates), with its median, spread and the
setup time. One run varies by a few points on this machine; the target is
judged on the median.

  cargo build --release
  python3 scripts/overhead.py [--runs 11] [FILE ...]

Defaults to city10000 and sphere2500 from ../shared/datasets.
"""

import argparse
import json
import os
import statistics
import subprocess

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DATASETS = os.path.join(ROOT, "..", "shared", "datasets")
DEFAULT_FILES = [os.path.join(DATASETS, "2d", "city10000.g2o"),
                 os.path.join(DATASETS, "3d", "sphere2500.g2o")]


def one_run(cairn, path):
    """(share outside factorise + solve, solve seconds, setup seconds)."""
    command = [cairn, "solve", path, "--init", "file", "--threads", "1", "--json", "-q"]
    d = json.loads(subprocess.run(command, capture_output=True, text=True, check=True).stdout)
    s, total = d["summary"], d["solve_s"]
    inside = s["phases"]["factorize"] + s["phases"]["solve"]
    return (total - inside) / total, total, s["setup_time"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="*", default=DEFAULT_FILES)
    ap.add_argument("--cairn", default=os.path.join(ROOT, "target", "release", "cairn"))
    ap.add_argument("--runs", type=int, default=11)
    a = ap.parse_args()
    print("| file | runs | outside factorise + solve: median (min–max) | solve | setup |")
    print("|---|---:|---:|---:|---:|")
    for path in a.files:
        runs = [one_run(a.cairn, path) for _ in range(a.runs)]
        share = [r[0] for r in runs]
        print(f"| {os.path.basename(path)[:-4]} | {a.runs} | "
              f"{100 * statistics.median(share):.1f}% ({100 * min(share):.1f}–{100 * max(share):.1f}%) | "
              f"{1e3 * statistics.median(r[1] for r in runs):.1f} ms | "
              f"{1e3 * statistics.median(r[2] for r in runs):.1f} ms |")


if __name__ == "__main__":
    main()
