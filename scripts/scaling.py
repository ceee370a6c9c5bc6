#!/usr/bin/env python3
"""Scaling of `cairn solve` on synthetic graphs from `cairn generate`: time per
Gauss-Newton iteration and peak memory (max RSS of the process) against the
number of edges, with the fitted exponents, a table and a plot.

  cargo build --release
  python3 scripts/scaling.py [--sizes-2d 10000,...] [--sizes-3d 10000,...] [--iterations 5]

Writes the table between the scaling markers of BENCHMARKS.md, the raw rows to
docs/bench/scaling.jsonl and a log-log plot to docs/bench/scaling.svg.
"""

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
from bench import write_section  # noqa: E402


def measure(cairn, world, n, iterations, threads, tmp):
    path = os.path.join(tmp, f"{world}-{n}.g2o")
    subprocess.run([cairn, "generate", world, "-n", str(n), "-o", path], check=True)
    command = [cairn, "solve", path, "--init", "file", "-i", str(iterations),
               "--relative-decrease", "0", "--threads", str(threads), "--json", "-q"]
    # ru_maxrss of the children is a running maximum, so each solve runs in a
    # fresh python child that reports its own child's peak.
    probe = ("import resource,subprocess,sys,json;"
             "p=subprocess.run(sys.argv[1:],capture_output=True,text=True);"
             "print(json.dumps(dict(rc=p.returncode,out=p.stdout,err=p.stderr[-400:],"
             "rss=resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)))")
    p = subprocess.run([sys.executable, "-c", probe] + command, capture_output=True, text=True,
                       check=True)
    r = json.loads(p.stdout)
    os.remove(path)
    if r["rc"] != 0:
        raise SystemExit(f"{world} {n}: {r['err']}")
    d = json.loads(r["out"])
    s = d["summary"]
    its = max(s["iterations"], 1)
    return dict(world=world, poses=d["vertices"], edges=d["edges"], iterations=s["iterations"],
                setup_s=s["setup_time"], per_iteration_s=(d["solve_s"] - s["setup_time"]) / its,
                factorize_s=s["phases"]["factorize"] / its, load_s=d["load_s"],
                peak_bytes=r["rss"] * 1024, factor_nnz=s["factor_nnz"], threads=threads)


def exponent(rows, key):
    """Least-squares slope of log(key) against log(edges)."""
    xs = [math.log(r["edges"]) for r in rows]
    ys = [math.log(r[key]) for r in rows]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    return (sum((x - mx) * (y - my) for x, y in zip(xs, ys))
            / sum((x - mx) ** 2 for x in xs))


def svg_plot(rows, path):
    """Log-log plot of time per iteration and peak memory against edges."""
    w, h, m = 640, 420, 60
    series = [(world, key, colour) for world in ("manhattan", "sphere")
              for key, colour in (("per_iteration_s", "#1f77b4"), ("peak_bytes", "#d62728"))]
    xs = [math.log10(r["edges"]) for r in rows]
    x0, x1 = math.floor(min(xs)), math.ceil(max(xs))
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
           f'font-family="sans-serif" font-size="12">',
           f'<rect width="{w}" height="{h}" fill="white"/>',
           f'<text x="{w / 2}" y="20" text-anchor="middle">cairn solve: scaling with edges '
           f'(log-log; each series normalised to its first point)</text>']
    ys = []
    for world, key, _ in series:
        rs = [r for r in rows if r["world"] == world]
        if rs:
            ys += [math.log10(r[key] / rs[0][key]) for r in rs]
    base = [r for r in rows if r["world"] == "manhattan"] or rows
    lx0 = math.log10(base[0]["edges"])
    y0, y1 = min(ys + [0]), max(ys + [x1 - lx0])

    def px(x, y):
        return (m + (x - x0) / (x1 - x0) * (w - 2 * m), h - m - (y - y0) / (y1 - y0) * (h - 2 * m))

    out.append(f'<rect x="{m}" y="{m}" width="{w - 2 * m}" height="{h - 2 * m}" fill="none" '
               f'stroke="black"/>')
    for d in range(x0, x1 + 1):
        x, _ = px(d, y0)
        out.append(f'<text x="{x}" y="{h - m + 16}" text-anchor="middle">1e{d}</text>')
    out.append(f'<text x="{w / 2}" y="{h - 12}" text-anchor="middle">edges</text>')
    for d in range(math.ceil(y0), math.floor(y1) + 1):
        _, y = px(x0, d)
        out.append(f'<text x="{m - 6}" y="{y + 4}" text-anchor="end">×1e{d}</text>')
    # a linear reference from the first point
    (ax, ay), (bx, by) = px(lx0, 0), px(x1, x1 - lx0)
    out.append(f'<line x1="{ax}" y1="{ay}" x2="{bx}" y2="{by}" stroke="gray" '
               f'stroke-dasharray="4 4"/>')
    legend = 0
    for world, key, colour in series:
        rs = [r for r in rows if r["world"] == world]
        if not rs:
            continue
        points = [px(math.log10(r["edges"]), math.log10(r[key] / rs[0][key])) for r in rs]
        dash = "" if world == "manhattan" else ' stroke-dasharray="8 3"'
        out.append(f'<polyline fill="none" stroke="{colour}" stroke-width="2"{dash} points="'
                   + " ".join(f"{x:.1f},{y:.1f}" for x, y in points) + '"/>')
        label = {"per_iteration_s": "time per iteration", "peak_bytes": "peak memory"}[key]
        y = m + 16 + 16 * legend
        out.append(f'<line x1="{m + 10}" y1="{y - 4}" x2="{m + 40}" y2="{y - 4}" '
                   f'stroke="{colour}" stroke-width="2"{dash}/>')
        out.append(f'<text x="{m + 46}" y="{y}">{world}: {label}</text>')
        legend += 1
    y = m + 16 + 16 * legend
    out.append(f'<line x1="{m + 10}" y1="{y - 4}" x2="{m + 40}" y2="{y - 4}" stroke="gray" '
               f'stroke-dasharray="4 4"/><text x="{m + 46}" y="{y}">linear</text>')
    out.append("</svg>")
    with open(path, "w") as fh:
        fh.write("\n".join(out) + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cairn", default=os.path.join(ROOT, "target", "release", "cairn"))
    ap.add_argument("--sizes-2d", default="10000,31623,100000,316228,1000000")
    ap.add_argument("--sizes-3d", default="10000,31623,100000")
    ap.add_argument("--iterations", type=int, default=5)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "bench", "scaling.jsonl"))
    ap.add_argument("--doc", default=os.path.join(ROOT, "BENCHMARKS.md"))
    a = ap.parse_args()

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for world, sizes in (("manhattan", a.sizes_2d), ("sphere", a.sizes_3d)):
            for n in (int(x) for x in sizes.split(",") if x):
                row = measure(a.cairn, world, n, a.iterations, a.threads, tmp)
                print(json.dumps(row), file=sys.stderr, flush=True)
                rows.append(row)
    os.makedirs(os.path.dirname(a.out), exist_ok=True)
    with open(a.out, "w") as fh:
        fh.writelines(json.dumps(r) + "\n" for r in rows)

    lines = ["| world | poses | edges | setup | per iteration | of which factorise | "
             "factor nnz | peak memory | bytes per edge |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['world']} | {r['poses']} | {r['edges']} | {r['setup_s']:.3f} s | "
                     f"{r['per_iteration_s']:.3f} s | {r['factorize_s']:.3f} s | "
                     f"{r['factor_nnz']} | {r['peak_bytes'] / 2**20:.0f} MiB | "
                     f"{r['peak_bytes'] / r['edges']:.0f} |")
    lines.append("")
    for world in ("manhattan", "sphere"):
        rs = [r for r in rows if r["world"] == world]
        if len(rs) >= 2:
            lines.append(f"- {world}: time per iteration grows as edges^"
                         f"{exponent(rs, 'per_iteration_s'):.2f}, the factor's non-zeros as "
                         f"edges^{exponent(rs, 'factor_nnz'):.2f}, peak memory as "
                         f"edges^{exponent(rs, 'peak_bytes'):.2f}.")
    table = "\n".join(lines)
    print(table)
    svg_plot(rows, os.path.join(os.path.dirname(a.out), "scaling.svg"))
    if a.doc:
        write_section(a.doc, "scaling", table)


if __name__ == "__main__":
    main()
