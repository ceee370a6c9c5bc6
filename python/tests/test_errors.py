"""Bad input becomes a Python exception carrying Cairn's message."""

import math

import numpy as np
import pytest

import cairn


@pytest.fixture
def pair():
    g = cairn.Graph()
    g.add_se2(0, 0.0, 0.0, 0.0)
    g.add_se2(1, 1.0, 0.0, 0.0)
    return g


def test_shapes_and_values_are_checked(pair):
    with pytest.raises(ValueError, match="measurement must have 3 numbers, got 2"):
        pair.add_edge_se2(0, 1, [1.0, 0.0], np.eye(3))
    with pytest.raises(ValueError, match=r"information must be 3×3"):
        pair.add_edge_se2(0, 1, [1.0, 0.0, 0.0], np.eye(2))
    with pytest.raises(ValueError, match="NaN or infinite"):
        pair.add_edge_se2(0, 1, [1.0, math.nan, 0.0], np.eye(3))
    with pytest.raises(ValueError, match="NaN or infinite"):
        pair.add_edge_se2(0, 1, [1.0, 0.0, 0.0], np.diag([1.0, math.inf, 1.0]))
    with pytest.raises(ValueError, match="positive definite|not symmetric|symmetric"):
        pair.add_edge_se2(0, 1, [1.0, 0.0, 0.0], -np.eye(3))
    with pytest.raises(ValueError, match="q must not be zero"):
        pair.add_se3(5, [0, 0, 0], [0, 0, 0, 0])
    with pytest.raises(ValueError, match="non-finite"):
        pair.add_se2(7, math.nan, 0.0, 0.0)
    assert pair.num_edges == 0


def test_ids_are_checked(pair):
    with pytest.raises(ValueError, match="vertex 0 is already in the graph"):
        pair.add_se2(0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="vertex 9 is not in the graph"):
        pair.add_edge_se2(0, 9, [1.0, 0.0, 0.0], np.eye(3))
    with pytest.raises(ValueError, match="itself"):
        pair.add_edge_se2(0, 0, [1.0, 0.0, 0.0], np.eye(3))
    pair.add_xy(3, 1.0, 1.0)
    with pytest.raises(ValueError, match="vertex 3 is XY"):
        pair.add_edge_se2(0, 3, [1.0, 0.0, 0.0], np.eye(3))


def test_solve_options_are_checked(pair):
    pair.add_edge_se2(0, 1, [1.0, 0.0, 0.0], np.eye(3))
    with pytest.raises(ValueError, match="solver must be"):
        pair.optimize(solver="newton")
    with pytest.raises(ValueError, match="init must be"):
        pair.optimize(init="random")
    with pytest.raises(ValueError, match="max_iterations"):
        pair.optimize(max_iterations=0)
    with pytest.raises(ValueError, match="unknown robust kernel"):
        pair.optimize(robust_kernel="bisquare")
    with pytest.raises(ValueError, match="robust_kernel_width"):
        pair.optimize(robust_kernel="huber", robust_kernel_width=-1.0)
    with pytest.raises(OverflowError):
        pair.optimize(max_iterations=-1)


def test_files(tmp_path):
    with pytest.raises(OSError, match="nope.g2o"):
        cairn.read_g2o(tmp_path / "nope.g2o")
    bad = tmp_path / "bad.g2o"
    bad.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 zero\n")
    with pytest.raises(ValueError, match="line 2"):
        cairn.read_g2o(bad)
    indefinite = tmp_path / "indefinite.g2o"
    indefinite.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\n"
                          "EDGE_SE2 0 1 1 0 0 -1 0 0 1 0 1\n")
    with pytest.raises(ValueError, match="positive definite"):
        cairn.read_g2o(indefinite)
    g = cairn.read_g2o(indefinite, repair_information=True)
    assert g.num_edges == 1
    with pytest.raises(OSError):
        g.write_g2o(tmp_path / "no" / "such" / "dir" / "x.g2o")
