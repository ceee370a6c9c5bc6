#!/usr/bin/env python3
"""Simulate a Formula Student run, map it with graph SLAM from Python, and
plot the map over the true cones.

  pip install ./python matplotlib
  python3 examples/python/cone_slam.py run/ map.png
"""

import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import cairn


def main(folder, image):
    cairn.fs_sim(folder, seed=1, laps=2.0)
    out = cairn.fs_slam(os.path.join(folder, "log.jsonl"), estimator="graph", association="ml")
    with open(os.path.join(folder, "truth_map.csv")) as f:
        truth = np.array([[float(r["x"]), float(r["y"])] for r in csv.DictReader(f)])
    cones, path = out["map"], out["trajectory"]
    matched = np.mean(out["associations"][:, 2] >= 0)
    print("%d landmarks (%d true cones), %.1f%% of detections matched"
          % (len(cones), len(truth), 100 * matched))

    fig, ax = plt.subplots(figsize=(8, 6))
    ax.scatter(truth[:, 0], truth[:, 1], s=30, facecolors="none", edgecolors="0.5", label="true cones")
    ax.scatter(cones[:, 0], cones[:, 1], s=6, c="C3", label="mapped")
    ax.plot(path[:, 1], path[:, 2], color="C0", lw=0.8, label="estimated path")
    ax.set_aspect("equal")
    ax.legend()
    fig.savefig(image, dpi=120, bbox_inches="tight")
    print("wrote", image)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
