#!/usr/bin/env python3
"""Solve a g2o pose graph with Cairn from Python and plot it with matplotlib.

  pip install ./python matplotlib
  python3 examples/python/solve_g2o.py ../shared/datasets/2d/input_INTEL_g2o.g2o intel.png
"""

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

import cairn


def main(path, image):
    graph = cairn.read_g2o(path)
    before = graph.se2_array()
    summary = graph.optimize(solver="gn", init="auto")
    after = graph.se2_array()
    print(summary)
    for row in summary.trace:
        print("iteration %(iteration)2d  chi2 %(chi2).6e  %(time).4f s" % row)

    fig, ax = plt.subplots(figsize=(7, 7))
    ax.plot(before[:, 1], before[:, 2], color="0.7", lw=0.8, label="start")
    ax.plot(after[:, 1], after[:, 2], color="C3", lw=1.0,
            label="solved (χ² %.1f, from the %s start)" % (summary.chi2, summary.init))
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend()
    fig.savefig(image, dpi=120, bbox_inches="tight")
    print("wrote", image)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
