#!/usr/bin/env python3
"""Cairn's GN solve time with each factorisation (simplicial, supernodal, the
default) and with 1 and 2 threads, on every benchmark file with at least 1,000
vertices (cubicle's indefinite information repaired): the measurement behind
the default factorisation and thread count.

  cargo build --release
  python3 scripts/factorization.py [--reps 3] [--only city10000,sphere2500]

Writes the table between the factorization markers of BENCHMARKS.md; with
--only, the rows of the other files stay as they were.
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
from bench import vertex_count, write_section  # noqa: E402

VARIANTS = [("simplicial", 1), ("supernodal", 1), ("auto", 1), ("auto", 2)]


def solve(cairn, path, factorization, threads):
    command = [cairn, "solve", path, "--init", "file", "-i", "100", "--relative-decrease",
               "1e-5", "--factorization", factorization, "--threads", str(threads), "--json",
               "-q", "--repair-information"]
    d = json.loads(subprocess.run(command, capture_output=True, text=True, check=True).stdout)
    return d["solve_s"], d["summary"]["supernodal"], d["summary"]["final_chi2"]


def kept_rows(doc):
    """The rows of the factorisation table in `doc`, by dataset."""
    if not os.path.exists(doc):
        return {}
    text = open(doc).read()
    begin, end = "<!-- factorization:begin -->", "<!-- factorization:end -->"
    if begin not in text or end not in text:
        return {}
    section = text[text.index(begin) + len(begin):text.index(end)]
    rows = [line for line in section.splitlines() if line.startswith("| ")][1:]
    return {line.split("|")[1].strip(): line for line in rows}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cairn", default=os.path.join(ROOT, "target", "release", "cairn"))
    ap.add_argument("--data", default=os.path.join(ROOT, "..", "shared", "peers", "data"))
    ap.add_argument("--only", default="")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--doc", default=os.path.join(ROOT, "BENCHMARKS.md"))
    a = ap.parse_args()

    files = sorted(f for f in os.listdir(a.data) if f.endswith(".g2o"))
    if a.only:
        keep = set(a.only.split(","))
        files = [f for f in files if f[:-4] in keep or f in keep]
    files = [f for f in files if vertex_count(os.path.join(a.data, f)) >= 1000]
    head = ["| dataset | simplicial | supernodal | default (kind) | default, 2 threads | "
            "same χ² with 2 threads |", "|---|---:|---:|---:|---:|---|"]
    # With --only, the other files' rows already in the document stay.
    rows = kept_rows(a.doc) if a.only and a.doc else {}
    for f in files:
        path = os.path.join(a.data, f)
        times = {v: [] for v in VARIANTS}
        kind, chi2 = {}, {}
        for _ in range(a.reps):
            for v in VARIANTS:
                t, supernodal, c = solve(a.cairn, path, *v)
                times[v].append(t)
                kind[v], chi2[v] = supernodal, c
        ms = {v: statistics.median(ts) * 1000 for v, ts in times.items()}
        default = "supernodal" if kind[("auto", 1)] else "simplicial"
        same = "yes" if chi2[("auto", 1)] == chi2[("auto", 2)] else "**no**"
        row = (f"| {f[:-4]} | {ms[VARIANTS[0]]:.0f} ms | {ms[VARIANTS[1]]:.0f} ms | "
               f"{ms[VARIANTS[2]]:.0f} ms ({default}) | {ms[VARIANTS[3]]:.0f} ms | {same} |")
        print(row, flush=True)
        rows[f[:-4]] = row
    table = "\n".join(head + [rows[name] for name in sorted(rows)])
    if a.doc:
        write_section(a.doc, "factorization", table)


if __name__ == "__main__":
    main()
