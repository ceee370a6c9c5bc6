#!/usr/bin/env python3
"""Benchmark suite: Cairn against the peers of ../shared/peers, in one run.

For every g2o file with at least --min-vertices vertices in the harness's
prepared data (../shared/peers/data, identical input for every library), and
for GN and LM: Cairn and each peer solve from the file's own vertices with at
most 100 iterations and a relative-decrease stop of 1e-5 (the peers' rule),
--reps times each, interleaved. Every final estimate is scored with the
harness's common χ² (g2o's objective). Prints the table, writes every run to
--jsonl and the table between the suite markers of BENCHMARKS.md.

Run it with the harness's Python (it imports the harness's scorer, which needs
numpy):

  cargo build --release
  ../shared/peers/.venv/bin/python scripts/bench.py [--reps 3] [--only city10000,sphere2500]
      [--peers gtsam,g2o,apex,tiny,factrs] [--algos gn,lm] [--threads 1]
  scripts/bench.py --render                      # redraw the tables from docs/bench/suite.jsonl
  scripts/bench.py --replace --only FRH          # rerun some files, keep the other runs
  scripts/bench.py --stop-rule ...               # also Cairn's GN with --stop-on-increase

Without a set-up harness (no .venv or peers-rust) it runs Cairn alone.
"""

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
PEERS_ALL = ["gtsam", "g2o", "apex", "tiny", "factrs"]
# Cairn's runs: from the file under the peers' rule; the defaults; LM with
# g2o's damping; GN under GTSAM's stopping rule; SE3 files on the Logmap
# objective.
CAIRN_RUNS = ["cairn", "cairn-default", "cairn-g2o-lm", "cairn-stop", "cairn-logmap"]


def is_se3(path):
    with open(path) as fh:
        return "_SE3:QUAT" in fh.read(1 << 16)
ALGOS_ALL = ["gn", "lm", "dogleg"]


def peer_command(peers_dir, lib, algo, path):
    if lib in ("gtsam", "g2o"):
        python = os.path.join(peers_dir, ".venv", "bin", "python")
        return [python, os.path.join(peers_dir, "run_peer.py"), "--lib", lib, "--algo", algo, path]
    rust = os.path.join(peers_dir, "rust", "target", "release", "peers-rust")
    return [rust, "--lib", lib, "--algo", algo, path]


def peer_available(peers_dir, lib):
    command = peer_command(peers_dir, lib, "gn", "x")
    return os.path.exists(command[0])


def run_peer(peers_dir, lib, algo, path, env, timeout):
    try:
        p = subprocess.run(peer_command(peers_dir, lib, algo, path), capture_output=True,
                           text=True, env=env, timeout=timeout)
    except subprocess.TimeoutExpired:
        return dict(status="timeout")
    lines = [line for line in p.stdout.splitlines() if line.startswith("{")]
    if not lines:
        return dict(status="crash", error=(p.stderr or "")[-300:])
    return json.loads(lines[-1])


def run_cairn(cairn, algo, path, threads, env, timeout, scorer, repair=False, extra=(),
              default=False, rotvec=False):
    """One `cairn solve` from the file under the peers' stopping rule (with
    `extra` arguments), or with `default`, `cairn solve` with its default
    options. A file whose information matrices are indefinite (cubicle) is
    refused, and solved again with them repaired; the harness scores the
    estimate with the file's own information, as the peers'. With `rotvec`
    the estimate is scored on the Logmap objective as well."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "out.g2o")
        options = [] if default else ["--init", "file", "--solver", algo, "-i", "100",
                                      "--relative-decrease", "1e-5"]
        command = [cairn, "solve", path] + options + [
            "--threads", str(threads), "--json", "-q",
            "-o", out] + (["--repair-information"] if repair else []) + list(extra)
        t0 = time.perf_counter()
        try:
            p = subprocess.run(command, capture_output=True, text=True, env=env, timeout=timeout)
        except subprocess.TimeoutExpired:
            return dict(status="timeout")
        wall = time.perf_counter() - t0
        if p.returncode != 0:
            if "not positive definite" in p.stderr and not repair:
                return run_cairn(cairn, algo, path, threads, env, timeout, scorer, True, extra,
                                 default, rotvec)
            return dict(status="error", error=p.stderr[-300:])
        d = json.loads(p.stdout)
        s = d["summary"]
        rec = dict(status="ok", iterations=s["iterations"], solve_s=d["solve_s"],
                   load_s=d["load_s"], write_s=d["write_s"], process_s=wall,
                   final_chi2=s["final_chi2"], phases=s["phases"], supernodal=s["supernodal"],
                   repaired=repair, init=d["init"])
        if scorer is not None:
            rec["common_chi2"] = scorer(path, out)
            if rotvec:
                rec["common_chi2_rotvec"] = scorer(path, out, rotvec=True)
        return rec


def make_scorer(peers_dir):
    """The harness's common χ² of an estimate written by Cairn, or None
    without the harness's Python packages."""
    sys.path.insert(0, peers_dir)
    try:
        import g2o_common
    except ImportError:
        return None

    def score(original, estimate, rotvec=False):
        g = g2o_common.read_g2o(original)
        e = g2o_common.read_g2o(estimate)
        return g2o_common.common_chi2(g, e.pose_est, e.point_est, rotvec=rotvec)

    return score


def vertex_count(path):
    with open(path) as fh:
        return sum(1 for line in fh if line.startswith("VERTEX"))


def median(xs):
    return statistics.median(xs) if xs else None


def summarise(rows):
    """Median solve time, last χ² and iterations per (file, algo, lib)."""
    out = {}
    for r in rows:
        key = (r["file"], r["algo"], r["lib"])
        out.setdefault(key, []).append(r)
    table = {}
    for key, rs in out.items():
        # A run its library reports as failed (g2o's GN on cubicle diverges
        # to χ² 10²³) is no solve, though it has a time and a χ².
        good = [r for r in rs if r.get("solve_s") is not None and r.get("common_chi2") is not None
                and r.get("status") != "failed"]
        if not good:
            table[key] = dict(status=rs[-1].get("status"))
            continue
        table[key] = dict(
            solve_s=median([r["solve_s"] for r in good]),
            process_s=median([r["process_s"] for r in good if "process_s" in r]),
            wall_s=median([r["wall_s"] for r in good if "wall_s" in r]),
            load_s=median([r["load_s"] for r in good if r.get("load_s") is not None]),
            chi2=good[-1]["common_chi2"],
            chi2_rotvec=good[-1].get("common_chi2_rotvec"),
            iterations=good[-1].get("iterations"),
            repaired=good[-1].get("repaired", False),
            init=good[-1].get("init"),
            runs=len(good),
        )
    return table


def fmt_time(s):
    return "–" if s is None else f"{s * 1000:.0f} ms" if s < 10 else f"{s:.1f} s"


def no_worse(chi2, than):
    """χ² no worse than `than`: 1e-6 relative, 1e-9 absolute (for χ² ≈ 0)."""
    return chi2 <= than * (1 + 1e-6) + 1e-9


def render(table, files, algos, peers):
    head = ["dataset", "algo", "Cairn it", "Cairn solve", "Cairn χ²", "fastest peer", "its χ²",
            "ratio", "χ² ok", "fastest peer as good", "ratio"] + [f"÷ {p}" for p in peers]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for f in files:
        for algo in algos:
            c = table.get((f, algo, "cairn"))
            if not c:
                continue
            if c.get("solve_s") is None:
                lines.append(f"| {f[:-4]} | {algo} | Cairn: {c.get('status')} |"
                             + " |" * (len(head) - 3))
                continue
            ok_peers = [(p, table[(f, algo, p)]) for p in peers
                        if table.get((f, algo, p), {}).get("solve_s") is not None]
            name = f[:-4] + (" (repaired)" if c.get("repaired") else "")
            cells = [name, algo, str(c["iterations"]), fmt_time(c["solve_s"]),
                     f"{c['chi2']:.6f}"]
            fastest = min(ok_peers, key=lambda pr: pr[1]["solve_s"], default=None)
            if fastest:
                p, r = fastest
                chi2_ok = no_worse(c["chi2"], r["chi2"])
                cells += [f"{p} {fmt_time(r['solve_s'])}", f"{r['chi2']:.6f}",
                          f"{c['solve_s'] / r['solve_s']:.2f}", "yes" if chi2_ok else "**no**"]
            else:
                cells += ["–"] * 4
            # The fastest peer whose χ² is as low as Cairn's.
            as_good = [(p, r) for p, r in ok_peers if no_worse(r["chi2"], c["chi2"])]
            best = min(as_good, key=lambda pr: pr[1]["solve_s"], default=None)
            if best:
                p, r = best
                cells += [f"{p} {fmt_time(r['solve_s'])}", f"{c['solve_s'] / r['solve_s']:.2f}"]
            else:
                cells += ["none", "–"]
            for p in peers:
                r = table.get((f, algo, p), {})
                cells.append(f"{c['solve_s'] / r['solve_s']:.2f}" if r.get("solve_s") else
                             (r.get("status") or "–"))
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def render_pair(table, files, algo, lib, peer, names):
    """Cairn's runs `lib` against one peer's `algo` runs, file by file;
    `names` heads Cairn's and the peer's columns."""
    mine, theirs = names
    lines = [f"| dataset | {mine} it | solve | χ² | {theirs} it | solve | χ² | ratio | χ² ok |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---|"]
    for f in files:
        c, g = table.get((f, algo, lib)), table.get((f, algo, peer))
        if not c or c.get("solve_s") is None:
            continue
        name = f[:-4] + (" (repaired)" if c.get("repaired") else "")
        cells = [name, str(c["iterations"]), fmt_time(c["solve_s"]), f"{c['chi2']:.6f}"]
        if g and g.get("solve_s") is not None:
            cells += [str(g["iterations"]), fmt_time(g["solve_s"]), f"{g['chi2']:.6f}",
                      f"{c['solve_s'] / g['solve_s']:.2f}",
                      "yes" if no_worse(c["chi2"], g["chi2"]) else "**no**"]
        else:
            cells += [(g or {}).get("status") or "–"] + ["–"] * 4
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def render_logmap(table, files, algos, peers):
    """SE3 files on the Logmap objective: Cairn with `--se3-error logmap`
    against every peer, all scored with the harness's common_chi2_rotvec."""
    lines = ["| dataset | algo | Cairn it | Cairn solve | Cairn χ² (Logmap) | fastest peer "
             "| its χ² (Logmap) | ratio | χ² ok | fastest peer as low | ratio |",
             "|---|---|---:|---:|---:|---|---:|---:|---|---|---:|"]
    for f in files:
        for algo in algos:
            c = table.get((f, algo, "cairn-logmap"))
            if not c or c.get("solve_s") is None or c.get("chi2_rotvec") is None:
                continue
            ok = [(p, table[(f, algo, p)]) for p in peers
                  if table.get((f, algo, p), {}).get("solve_s") is not None
                  and table[(f, algo, p)].get("chi2_rotvec") is not None]
            name = f[:-4] + (" (repaired)" if c.get("repaired") else "")
            cells = [name, algo, str(c["iterations"]), fmt_time(c["solve_s"]),
                     f"{c['chi2_rotvec']:.6f}"]
            fastest = min(ok, key=lambda pr: pr[1]["solve_s"], default=None)
            if fastest:
                p, r = fastest
                cells += [f"{p} {fmt_time(r['solve_s'])}", f"{r['chi2_rotvec']:.6f}",
                          f"{c['solve_s'] / r['solve_s']:.2f}",
                          "yes" if no_worse(c["chi2_rotvec"], r["chi2_rotvec"]) else "**no**"]
            else:
                cells += ["–"] * 4
            low = [(p, r) for p, r in ok if no_worse(r["chi2_rotvec"], c["chi2_rotvec"])]
            best = min(low, key=lambda pr: pr[1]["solve_s"], default=None)
            cells += ([f"{best[0]} {fmt_time(best[1]['solve_s'])}",
                       f"{c['solve_s'] / best[1]['solve_s']:.2f}"] if best else ["none", "–"])
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def render_default(table, files, peers):
    """The headline: `cairn solve FILE` with its defaults and with `--init
    file` (whole process: start, parse, solve, write) against each peer's
    load + solve, GN or LM, whichever is faster."""
    head = ["dataset", "Cairn default", "its χ² (start)", "Cairn --init file", "its χ²",
            "fastest peer", "its χ²", "default ÷", "file ÷", "fastest peer as low", "default ÷"]
    lines = ["| " + " | ".join(head) + " |", "|---|---:|---:|---:|---:|---|---:|---:|---:|---|---:|"]
    for f in files:
        d, c = table.get((f, "gn", "cairn-default")), table.get((f, "gn", "cairn"))
        if not d or d.get("process_s") is None:
            continue
        runs = [(f"{p} {algo}", r["load_s"] + r["solve_s"], r["chi2"])
                for p in peers for algo in ("gn", "lm")
                for r in [table.get((f, algo, p), {})]
                if r.get("solve_s") is not None and r.get("load_s") is not None]
        fastest = min(runs, key=lambda x: x[1], default=None)
        low = [x for x in runs if no_worse(x[2], d["chi2"])]
        fastest_low = min(low, key=lambda x: x[1], default=None)
        name = f[:-4] + (" (repaired)" if d.get("repaired") else "")
        cells = [name, fmt_time(d["process_s"]), f"{d['chi2']:.6f} ({d.get('init', '?')})"]
        file_s = c.get("process_s") if c else None
        cells += [fmt_time(file_s), f"{c['chi2']:.6f}" if c and c.get("chi2") is not None else "–"]
        if fastest:
            cells += [f"{fastest[0]} {fmt_time(fastest[1])}", f"{fastest[2]:.6f}",
                      f"{d['process_s'] / fastest[1]:.2f}",
                      f"{file_s / fastest[1]:.2f}" if file_s else "–"]
        else:
            cells += ["–"] * 4
        if fastest_low:
            cells += [f"{fastest_low[0]} {fmt_time(fastest_low[1])}",
                      f"{d['process_s'] / fastest_low[1]:.2f}"]
        else:
            cells += ["none", "–"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def render_phases(rows, files):
    """Cairn's GN phase times per iteration (medians over the runs), and the
    share of an iteration outside the numeric factorisation and solves."""
    names = ["linearize", "assemble", "factorize", "solve", "update", "chi2"]
    lines = ["| dataset | it | " + " | ".join(names) + " | other | outside factorise + solve |",
             "|---|---:|" + "---:|" * (len(names) + 2)]
    for f in files:
        runs = [r for r in rows if r["file"] == f and r["algo"] == "gn" and r["lib"] == "cairn"
                and r.get("phases") and r.get("iterations")]
        if not runs:
            continue
        per_it = {n: median([r["phases"][n] / r["iterations"] for r in runs]) for n in names}
        total = median([r["solve_s"] / r["iterations"] for r in runs])
        other = max(total - sum(per_it.values()), 0.0)
        outside = (total - per_it["factorize"] - per_it["solve"]) / total
        cells = [f"{per_it[n] * 1000:.2f}" for n in names]
        lines.append(f"| {f[:-4]} | {runs[0]['iterations']} | " + " | ".join(cells) +
                     f" | {other * 1000:.2f} | {outside:.0%} |")
    lines.append("")
    lines.append("Milliseconds per iteration; *other* is setup (structure and symbolic "
                 "analysis, once per solve) and bookkeeping, spread over the iterations.")
    return "\n".join(lines)


def write_section(path, name, text):
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    doc = open(path).read() if os.path.exists(path) else ""
    if begin in doc and end in doc:
        doc = re.sub(re.escape(begin) + ".*?" + re.escape(end),
                     lambda _: f"{begin}\n{text}\n{end}", doc, flags=re.S)
    else:
        doc += f"\n{begin}\n{text}\n{end}\n"
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write(doc)
    os.replace(tmp, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cairn", default=os.path.join(ROOT, "target", "release", "cairn"))
    ap.add_argument("--peers-dir", default=os.path.join(ROOT, "..", "shared", "peers"))
    ap.add_argument("--peers", default=",".join(PEERS_ALL))
    ap.add_argument("--algos", default="gn,lm")
    ap.add_argument("--only", default="")
    ap.add_argument("--min-vertices", type=int, default=1000)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1, help="threads for every library")
    ap.add_argument("--timeout", type=float, default=300)
    ap.add_argument("--jsonl", default=os.path.join(ROOT, "docs", "bench", "suite.jsonl"))
    ap.add_argument("--doc", default=os.path.join(ROOT, "BENCHMARKS.md"),
                    help="write the tables between its suite markers ('' for none)")
    ap.add_argument("--render", action="store_true",
                    help="only redraw the tables from the runs already in --jsonl")
    ap.add_argument("--replace", action="store_true",
                    help="rerun --only's files and replace their runs in --jsonl")
    ap.add_argument("--stop-rule", action="store_true",
                    help="also run Cairn's GN with --stop-on-increase (GTSAM's stopping rule), "
                         "recorded as library cairn-stop")
    a = ap.parse_args()

    data = os.path.join(a.peers_dir, "data")
    if not os.path.isdir(data):
        sys.exit(f"{data} is missing: set up ../shared/peers first (see its README)")
    files = sorted(f for f in os.listdir(data) if f.endswith(".g2o"))
    if a.only:
        keep = set(a.only.split(","))
        files = [f for f in files if f[:-4] in keep or f in keep]
    files = [f for f in files if vertex_count(os.path.join(data, f)) >= a.min_vertices]
    files.sort(key=lambda f: os.path.getsize(os.path.join(data, f)))
    peers = [p for p in a.peers.split(",") if p and peer_available(a.peers_dir, p)]
    algos = a.algos.split(",")
    scorer = make_scorer(a.peers_dir)
    if scorer is None:
        print("note: numpy is missing, so Cairn's χ² is not scored by the harness", file=sys.stderr)
    env = dict(os.environ)
    for k in ("RAYON_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env[k] = str(a.threads)

    os.makedirs(os.path.dirname(a.jsonl), exist_ok=True)
    # Runs kept from an earlier --jsonl: all of them (--render), or all but
    # the (file, algorithm, library) triples rerun now (--replace; with
    # --peers, the other peers' runs of those files stay).
    kept = []
    if a.render or a.replace:
        kept = [json.loads(line) for line in open(a.jsonl)]
        kept = [r for r in kept if a.render or r["file"] not in files or r["algo"] not in algos
                or r["lib"] not in CAIRN_RUNS + peers]
    # The peers run now, and the peers in the tables (those run now or kept).
    shown = [p for p in PEERS_ALL
             if (p in peers and not a.render) or any(r["lib"] == p for r in kept)]
    if a.render:
        files = []
    rows = list(kept)
    with open(a.jsonl + ".tmp", "w") as log:
        log.writelines(json.dumps(r) + "\n" for r in kept)
        for f in files:
            path = os.path.join(data, f)
            for algo in algos:
                for rep in range(a.reps):
                    stop = ["cairn-stop"] if a.stop_rule and algo == "gn" else []
                    default = ["cairn-default"] if algo == "gn" else []
                    g2o_lm = ["cairn-g2o-lm"] if algo == "lm" else []
                    logmap = ["cairn-logmap"] if is_se3(path) else []
                    for lib in ["cairn"] + default + g2o_lm + logmap + stop + peers:
                        if lib == "cairn-logmap":
                            rec = run_cairn(a.cairn, algo, path, a.threads, env, a.timeout, scorer,
                                            extra=["--se3-error", "logmap"], rotvec=True)
                        elif lib == "cairn-g2o-lm":
                            rec = run_cairn(a.cairn, algo, path, a.threads, env, a.timeout, scorer,
                                            extra=["--damping", "levenberg"])
                        elif lib == "cairn-default":
                            rec = run_cairn(a.cairn, algo, path, a.threads, env, a.timeout, scorer,
                                            default=True)
                        elif lib == "cairn":
                            rec = run_cairn(a.cairn, algo, path, a.threads, env, a.timeout, scorer)
                        elif lib == "cairn-stop":
                            rec = run_cairn(a.cairn, algo, path, a.threads, env, a.timeout, scorer,
                                            extra=["--stop-on-increase"])
                        else:
                            t0 = time.perf_counter()
                            rec = run_peer(a.peers_dir, lib, algo, path, env, a.timeout)
                            rec["wall_s"] = time.perf_counter() - t0
                        rec.update(lib=lib, algo=algo, file=f, rep=rep, threads=a.threads)
                        rows.append(rec)
                        log.write(json.dumps(rec) + "\n")
                        log.flush()
                        print(f"{f:30s} {algo} {lib:7s} rep {rep}: solve {rec.get('solve_s')} "
                              f"χ² {rec.get('common_chi2')}", file=sys.stderr, flush=True)

    os.replace(a.jsonl + ".tmp", a.jsonl)
    files = sorted({r["file"] for r in rows}, key=lambda f: os.path.getsize(os.path.join(data, f)))
    table = summarise(rows)
    algos = [x for x in ALGOS_ALL if any(r["algo"] == x for r in rows)]
    headline = render_default(table, files, shown)
    suite = render(table, files, algos, shown)
    phases = render_phases(rows, files)
    # GN under GTSAM's stopping rule (`--stop-on-increase`) against GTSAM's
    # GN; LM with g2o's damping (`--damping levenberg`) against g2o's LM.
    stop_rule = render_pair(table, files, "gn", "cairn-stop", "gtsam", ("Cairn", "GTSAM"))
    same_lm = render_pair(table, files, "lm", "cairn-g2o-lm", "g2o",
                          ("Cairn (g2o damping)", "g2o LM"))
    logmap = render_logmap(table, files, algos, shown)
    print(headline, suite, same_lm, logmap, stop_rule, phases, sep="\n\n")
    if a.doc:
        write_section(a.doc, "default", headline)
        write_section(a.doc, "suite", suite)
        write_section(a.doc, "stop-rule", stop_rule)
        write_section(a.doc, "same-lm", same_lm)
        write_section(a.doc, "logmap", logmap)
        write_section(a.doc, "phases", phases)


if __name__ == "__main__":
    main()
