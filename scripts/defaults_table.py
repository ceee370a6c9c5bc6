#!/usr/bin/env python3
"""Solve every dataset with `cairn solve`'s default options and print a Markdown
table beside the best peer (lowest common_chi2 of any peer and algorithm in
../shared/peers/baseline.jsonl) and the MANIFEST's computed minimum.

  scripts/defaults_table.py [--cairn target/release/cairn] [--shared ../shared] [-- extra cairn args]
"""

import argparse
import glob
import json
import os
import re
import subprocess

HERE = os.path.dirname(os.path.abspath(__file__))


def manifest_minima(shared):
    minima = {}
    for line in open(os.path.join(shared, "datasets", "MANIFEST.md")):
        cols = [c.strip() for c in line.split("|")]
        if len(cols) > 10 and re.match(r"(2d|3d|landmarks)/", cols[1]):
            m = re.match(r"[-0-9.e+]+", cols[9])
            if m and m.group(0) not in ("-", "–"):
                minima[os.path.basename(cols[1])] = (float(m.group(0)), "not" in cols[9])
    return minima


def best_peers(shared):
    best = {}
    for line in open(os.path.join(shared, "peers", "baseline.jsonl")):
        r = json.loads(line)
        c = r.get("common_chi2")
        if c is None or r.get("status") not in (None, "ok"):
            continue
        if r["file"] not in best or c < best[r["file"]][0]:
            best[r["file"]] = (c, "%s %s" % (r["lib"], r["algo"]))
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cairn", default=os.path.join(HERE, "..", "target", "release", "cairn"))
    ap.add_argument("--shared", default=os.path.join(HERE, "..", "..", "shared"))
    ap.add_argument("extra", nargs="*")
    args = ap.parse_args()
    minima, peers = manifest_minima(args.shared), best_peers(args.shared)
    print("| dataset | Cairn χ² (start, it) | best peer χ² | MANIFEST minimum | vs peer | vs minimum |")
    print("|---|---:|---:|---:|---:|---:|")
    for path in sorted(glob.glob(os.path.join(args.shared, "datasets", "*", "*.g2o"))):
        if "/parser/" in path or "/solutions/" in path:
            continue
        name = os.path.basename(path)
        cmd = [args.cairn, "solve", path, "--json", "-q"] + args.extra
        if name == "cubicle.g2o":
            cmd.append("--repair-information")
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            print("| %s | error: %s | | | | |" % (name, p.stderr.strip()[:80]))
            continue
        d = json.loads(p.stdout)
        chi2 = d["summary"]["final_chi2"]
        ours = "%.6f (%s, %d)" % (chi2, d["init"], d["summary"]["iterations"])
        peer, mini = peers.get(name), minima.get(name)
        peer_cell = "%.6f (%s)" % peer if peer else "–"
        mini_cell = ("%.6f%s" % (mini[0], " (unverified)" if mini[1] else "")) if mini else "–"
        vs_peer = "%+.1e" % ((chi2 - peer[0]) / peer[0]) if peer and peer[0] > 1e-12 else ""
        vs_min = "%+.1e" % ((chi2 - mini[0]) / mini[0]) if mini and mini[0] > 1e-12 else ""
        print("| %s | %s | %s | %s | %s | %s |" % (name, ours, peer_cell, mini_cell, vs_peer, vs_min))


if __name__ == "__main__":
    main()
