"""cairn.fs_sim and cairn.fs_slam: a simulated run mapped from Python."""

import csv
import pathlib

import numpy as np
import pytest

import cairn
from conftest import shared_file

ROOT = pathlib.Path(__file__).resolve().parents[2]


def truth_map(folder):
    with open(folder / "truth_map.csv") as f:
        return np.array([[float(r["x"]), float(r["y"])] for r in csv.DictReader(f)])


# The filters drift more than the graph over a lap (docs/estimators.md).
@pytest.mark.parametrize("estimator, within", [("graph", 0.5), ("ekf", 1.0), ("fastslam2", 1.0)])
def test_a_simulated_run_is_mapped(tmp_path, estimator, within):
    written = cairn.fs_sim(tmp_path, seed=2, laps=1.0)
    assert sorted(p.name for p in written) == [
        "log.jsonl", "truth_assoc.csv", "truth_map.csv", "truth_traj.tum"]
    out = cairn.fs_slam(tmp_path / "log.jsonl", estimator=estimator, association="ml",
                        particles=20)
    cones = truth_map(tmp_path)
    mapped = out["map"]
    assert mapped.shape[1] == 5 and len(out["colors"]) == len(mapped)
    # Most true cones have an estimate near, and most estimates a cone.
    near = lambda a, b: np.min(np.linalg.norm(a[:, None, :] - b[None, :, :2], axis=2), axis=1)
    assert np.mean(near(cones, mapped[:, :2]) < within) > 0.75
    assert np.mean(near(mapped[:, :2], cones) < within) > 0.75
    assert np.all(mapped[:, 2:4] >= 0)
    traj = out["trajectory"]
    assert traj.shape[1] == 4 and np.all(np.diff(traj[:, 0]) > 0)
    assoc = out["associations"]
    assert assoc.dtype == np.int64 and assoc.shape[1] == 3
    assert assoc[:, 2].max() < len(mapped) and assoc[:, 2].min() >= -1
    assert np.mean(assoc[:, 2] >= 0) > 0.9


def test_a_config_file_is_read(tmp_path):
    cairn.fs_sim(tmp_path, seed=4, laps=1.0, preset="hard")
    out = cairn.fs_slam(tmp_path / "log.jsonl", config=ROOT / "configs" / "hard.toml")
    assert len(out["map"]) > 0


def test_a_shared_track_is_driven(tmp_path):
    track = shared_file("tracks/eufs_small_track.csv")
    cairn.fs_sim(tmp_path, track=track, laps=1.0)
    assert len(truth_map(tmp_path)) > 20


def test_bad_input(tmp_path):
    with pytest.raises(ValueError, match="laps"):
        cairn.fs_sim(tmp_path, laps=0.0)
    with pytest.raises(ValueError, match="speed"):
        cairn.fs_sim(tmp_path, speed=1e9)
    with pytest.raises(ValueError, match="preset"):
        cairn.fs_sim(tmp_path, preset="easy")
    with pytest.raises(OSError):
        cairn.fs_sim(tmp_path, track=tmp_path / "none.csv")
    cairn.fs_sim(tmp_path, seed=1, laps=0.2)
    log = tmp_path / "log.jsonl"
    with pytest.raises(ValueError, match="estimator"):
        cairn.fs_slam(log, estimator="kalman")
    with pytest.raises(ValueError, match="association"):
        cairn.fs_slam(log, association="nearest")
    with pytest.raises(ValueError, match="particles"):
        cairn.fs_slam(log, particles=0)
    with pytest.raises(OSError):
        cairn.fs_slam(tmp_path / "missing.jsonl")
    bad_config = tmp_path / "bad.toml"
    bad_config.write_text("gate = -1.0\n")
    with pytest.raises(ValueError, match="gate"):
        cairn.fs_slam(log, config=bad_config)
    bad_log = tmp_path / "bad.jsonl"
    bad_log.write_text('{"t": 0.0, "type": "odom", "v": "fast", "yaw_rate": 0.0}\n')
    with pytest.raises(ValueError, match="line 1"):
        cairn.fs_slam(bad_log)
