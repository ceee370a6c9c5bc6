#!/usr/bin/env python3
"""Solve every dataset in ../shared/datasets with `cairn solve` (GN and LM) and
print a Markdown table beside g2o's results from ../shared/peers/baseline.jsonl.

  scripts/compare_g2o.py [--cairn target/release/cairn] [--shared ../shared]
"""

import argparse
import glob
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cairn", default=os.path.join(HERE, "..", "target", "release", "cairn"))
    ap.add_argument("--shared", default=os.path.join(HERE, "..", "..", "shared"))
    args = ap.parse_args()

    baseline = {}
    with open(os.path.join(args.shared, "peers", "baseline.jsonl")) as f:
        for line in f:
            r = json.loads(line)
            if r["lib"] == "g2o":
                baseline[(r["file"], r["algo"])] = r

    print("| dataset | g2o GN χ² (it) | Cairn GN χ² (it) | rel. diff | g2o LM χ² (it) | Cairn LM χ² (it) | rel. diff |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for path in sorted(glob.glob(os.path.join(args.shared, "datasets", "*", "*.g2o"))):
        if "/parser/" in path or "/solutions/" in path:
            continue
        name = os.path.basename(path)
        cells = [name]
        for algo in ("gn", "lm"):
            # From the file's vertices, as g2o; LM with g2o's damping and τ.
            cmd = [args.cairn, "solve", path, "--solver", algo, "--init", "file", "--json", "-q"]
            if algo == "lm":
                cmd += ["--damping", "levenberg"]
            if name == "cubicle.g2o":
                cmd.append("--repair-information")
            p = subprocess.run(cmd, capture_output=True, text=True)
            if p.returncode != 0:
                cells += ["", "error: " + p.stderr.strip()[:60], ""]
                continue
            s = json.loads(p.stdout)["summary"]
            ref = baseline.get((name, algo))
            ours = "%.10g (%d)" % (s["final_chi2"], s["iterations"])
            if ref is None or ref.get("common_chi2") is None:
                cells += ["–", ours, ""]
                continue
            g = ref["common_chi2"]
            rel = (s["final_chi2"] - g) / max(abs(g), 1e-300)
            cells += ["%.10g (%s)" % (g, ref["iterations"]), ours, "%+.1e" % rel]
        print("| " + " | ".join(cells) + " |")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
