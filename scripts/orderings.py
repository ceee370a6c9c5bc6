#!/usr/bin/env python3
"""Cairn's GN solve on the landmark files with each fill-reducing ordering:
block AMD (the default), scalar AMD, and landmarks first (the Schur complement
on the landmarks, as g2o's block solvers form it). The measurement behind the
default ordering.

  cargo build --release
  python3 scripts/orderings.py [--reps 3]

Writes the table between the orderings markers of BENCHMARKS.md.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
from bench import write_section  # noqa: E402

ORDERINGS = ["block-amd", "amd", "schur"]


def solve(cairn, path, ordering):
    command = [cairn, "solve", path, "--init", "file", "--ordering", ordering,
               "--threads", "1", "--json", "-q"]
    d = json.loads(subprocess.run(command, capture_output=True, text=True, check=True).stdout)
    s = d["summary"]
    return (d["solve_s"], s["phases"]["factorize"] / max(s["iterations"], 1),
            s["factor_nnz"], s["final_chi2"], s["iterations"])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cairn", default=os.path.join(ROOT, "target", "release", "cairn"))
    ap.add_argument("--data", default=os.path.join(ROOT, "..", "shared", "datasets", "landmarks"))
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--doc", default=os.path.join(ROOT, "BENCHMARKS.md"))
    a = ap.parse_args()

    files = sorted(f for f in os.listdir(a.data) if f.endswith(".g2o"))
    lines = ["| dataset | ordering | iterations | solve | factorise per iteration | "
             "factor non-zeros | final χ² |", "|---|---|---:|---:|---:|---:|---:|"]
    for f in files:
        path = os.path.join(a.data, f)
        runs = {o: [] for o in ORDERINGS}
        for _ in range(a.reps):
            for o in ORDERINGS:
                runs[o].append(solve(a.cairn, path, o))
        for o in ORDERINGS:
            total = statistics.median(r[0] for r in runs[o]) * 1000
            factorise = statistics.median(r[1] for r in runs[o]) * 1000
            _, _, nnz, chi2, iterations = runs[o][-1]
            row = (f"| {f[:-4]} | {o} | {iterations} | {total:.0f} ms | {factorise:.1f} ms | "
                   f"{nnz} | {chi2:.6g} |")
            print(row, flush=True)
            lines.append(row)
    if a.doc:
        write_section(a.doc, "orderings", "\n".join(lines))


if __name__ == "__main__":
    main()
