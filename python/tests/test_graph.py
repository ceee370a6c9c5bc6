"""cairn.Graph: building from numpy, solving, values and marginals out."""

import math
import threading

import numpy as np
import pytest

import cairn


def square_loop(noise=0.0, seed=0):
    """Four poses around a 1 m square with odometry and a loop closure, the
    start off by `noise`."""
    rng = np.random.default_rng(seed)
    g = cairn.Graph()
    truth = [(0, 0, 0), (1, 0, math.pi / 2), (1, 1, math.pi), (0, 1, -math.pi / 2)]
    for i, (x, y, th) in enumerate(truth):
        dx, dy, dth = rng.normal(0, noise, 3) if i else (0, 0, 0)
        g.add_se2(i, x + dx, y + dy, th + dth)
    for i in range(4):
        g.add_edge_se2(i, (i + 1) % 4, [1.0, 0.0, math.pi / 2], np.eye(3))
    return g, np.array(truth, dtype=float)


def test_a_noisy_square_is_solved_to_its_truth():
    g, truth = square_loop(noise=0.1)
    assert g.num_vertices == 4 and g.num_edges == 4
    s = g.optimize(solver="gn", init="file")
    assert s.chi2_initial > 1e-3
    assert s.chi2 < 1e-12
    assert s.converged and s.init == "file" and not s.kept_start
    poses = g.se2_array()
    assert poses.shape == (4, 4)
    np.testing.assert_allclose(poses[:, 0], [0, 1, 2, 3])
    np.testing.assert_allclose(poses[:, 1:3], truth[:, :2], atol=1e-9)
    wrapped = np.angle(np.exp(1j * (poses[:, 3] - truth[:, 2])))
    np.testing.assert_allclose(wrapped, 0, atol=1e-9)


@pytest.mark.parametrize("solver", ["gn", "lm", "dogleg"])
@pytest.mark.parametrize("init", ["auto", "file", "chordal", "chordal-isotropic", "spanning-tree"])
def test_every_solver_and_start_reach_the_minimum(solver, init):
    g, _ = square_loop(noise=0.2, seed=1)
    s = g.optimize(solver=solver, init=init)
    assert s.chi2 < 1e-10, (solver, init, s)
    assert s.iterations == len(s.trace) >= 1
    first = s.trace[0]
    assert {"iteration", "chi2", "lambda", "radius", "trials", "gradient_max",
            "step_max", "time", "cumulative_time"} <= set(first)
    assert (first["lambda"] is not None) == (solver == "lm")


def test_a_custom_sized_graph_from_numpy_arrays():
    """A 200-pose spiral with landmarks, built from arrays: the solve
    recovers the truth to the noise's order and χ² lands near its expected
    value (edges' dimensions summed, less the free parameters)."""
    rng = np.random.default_rng(7)
    n, m = 200, 30
    theta = np.cumsum(np.full(n, 0.1))
    xy = np.cumsum(np.c_[np.cos(theta), np.sin(theta)], axis=0)
    poses = np.c_[xy, theta]
    marks = rng.uniform(xy.min(0) - 2, xy.max(0) + 2, (m, 2))
    g = cairn.Graph()
    for i, p in enumerate(poses):
        g.add_se2(i, *(p + (rng.normal(0, 0.3, 3) if i else 0)))
    for k, l in enumerate(marks):
        g.add_xy(1000 + k, *(l + rng.normal(0, 0.5, 2)))
    sigma_odo, sigma_obs = 0.01, 0.05
    residual_dims = 0
    for i in range(n - 1):
        c, s = math.cos(poses[i, 2]), math.sin(poses[i, 2])
        d = poses[i + 1, :2] - poses[i, :2]
        z = [c * d[0] + s * d[1], -s * d[0] + c * d[1], poses[i + 1, 2] - poses[i, 2]]
        g.add_edge_se2(i, i + 1, np.add(z, rng.normal(0, sigma_odo, 3)), np.eye(3) / sigma_odo**2)
        residual_dims += 3
    for i in range(0, n, 2):
        c, s = math.cos(poses[i, 2]), math.sin(poses[i, 2])
        for k in range(m):
            d = marks[k] - poses[i, :2]
            if np.hypot(*d) < 6:
                z = [c * d[0] + s * d[1], -s * d[0] + c * d[1]]
                g.add_edge_se2_xy(i, 1000 + k, np.add(z, rng.normal(0, sigma_obs, 2)),
                                  np.eye(2) / sigma_obs**2)
                residual_dims += 2
    s = g.optimize(solver="lm", init="auto")
    assert s.converged
    free = 3 * (n - 1) + 2 * m
    assert 0.5 * (residual_dims - free) < s.chi2 < 1.5 * (residual_dims - free)
    est = g.se2_array()
    assert np.max(np.hypot(*(est[:, 1:3] - poses[:, :2]).T)) < 0.5
    lm = g.xy_array()
    assert lm.shape == (m, 3)
    np.testing.assert_allclose(lm[:, 0], 1000 + np.arange(m))


def test_a_landmark_seen_from_fixed_poses_has_the_textbook_marginal():
    """Two fixed poses see one point; its covariance is (Σ Rᵢ Wᵢ Rᵢᵀ)⁻¹."""
    g = cairn.Graph()
    g.add_se2(0, 0.0, 0.0, 0.0)
    g.add_se2(1, 4.0, 0.0, math.pi / 2)
    g.add_xy(2, 2.0, 2.0)
    g.fix([0, 1])
    w0 = np.array([[4.0, 1.0], [1.0, 2.0]])
    w1 = np.array([[9.0, 0.0], [0.0, 1.0]])
    g.add_edge_se2_xy(0, 2, [2.0, 2.0], w0)
    g.add_edge_se2_xy(1, 2, [2.0, 2.0], w1)
    g.optimize(init="file")
    r1 = np.array([[0.0, -1.0], [1.0, 0.0]])
    expected = np.linalg.inv(w0 + r1 @ w1 @ r1.T)
    cov = g.marginals([2])
    assert set(cov) == {2}
    np.testing.assert_allclose(cov[2], expected, rtol=1e-9, atol=1e-12)
    with pytest.raises(ValueError, match="fixed"):
        g.marginals([0])
    with pytest.raises(ValueError, match="not in the graph"):
        g.marginals([99])


def test_se3_poses_and_edges():
    g = cairn.Graph()
    g.add_se3(0, [0, 0, 0], [0, 0, 0, 1])
    g.add_se3(1, [0.5, 0.2, 0.1], [0.1, 0.0, 0.0, 2.0])  # normalised
    half = math.pi / 8
    z = [1.0, 0.0, 0.0, 0.0, 0.0, math.sin(half), math.cos(half)]
    g.add_edge_se3(0, 1, z, np.eye(6))
    s = g.optimize(solver="gn", init="file")
    assert s.chi2 < 1e-16
    poses = g.se3_array()
    assert poses.shape == (2, 8)
    np.testing.assert_allclose(poses[0], [0, 0, 0, 0, 0, 0, 0, 1])
    q = poses[1, 4:]
    assert abs(np.linalg.norm(q) - 1) < 1e-12
    np.testing.assert_allclose(poses[1, 1:4], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(np.abs(q), np.abs(z[3:]), atol=1e-12)


def test_a_prior_and_fix_and_copy():
    g = cairn.Graph()
    g.add_se2(0, 0.3, 0.0, 0.0)
    g.add_prior_se2(0, [1.0, 2.0, 0.5], np.eye(3))
    c = g.copy()
    g.optimize(init="file")
    np.testing.assert_allclose(g.se2_array()[0, 1:], [1.0, 2.0, 0.5], atol=1e-12)
    np.testing.assert_allclose(c.se2_array()[0, 1:], [0.3, 0.0, 0.0])
    c.fix([0])
    s = c.optimize(init="file")
    assert s.termination == "nothing_to_optimize"
    np.testing.assert_allclose(c.se2_array()[0, 1:], [0.3, 0.0, 0.0])
    with pytest.raises(ValueError, match="vertex 5"):
        c.fix([0, 5], fixed=False)


def test_a_robust_kernel_holds_for_the_solve_only():
    g, truth = square_loop()
    g.add_edge_se2(0, 2, [5.0, 5.0, 0.0], np.eye(3) * 100)  # a false loop closure
    robust = g.copy()
    s = robust.optimize(solver="lm", init="file", robust_kernel="cauchy", robust_kernel_width=1.0)
    est = robust.se2_array()
    assert np.max(np.abs(est[:, 1:3] - truth[:, :2])) < 0.2
    # The kernel was taken off again: χ² is the plain one, far above the robust.
    assert robust.chi2() > 10 * s.chi2
    plain = g.copy()
    plain.optimize(solver="lm", init="file")
    assert np.max(np.abs(plain.se2_array()[:, 1:3] - truth[:, :2])) > 1.0


def test_write_and_read_back(tmp_path):
    g, _ = square_loop(noise=0.05)
    g.add_xy(10, 0.5, 0.5)
    g.add_edge_se2_xy(0, 10, [0.5, 0.5], [[2.0, 0.5], [0.5, 3.0]])
    g.add_se3(20, [1, 2, 3], [0, 0, 0, 1])
    g.fix([1])
    path = tmp_path / "out.g2o"
    g.write_g2o(path)
    back = cairn.read_g2o(str(path))
    assert back.num_vertices == g.num_vertices and back.num_edges == g.num_edges
    np.testing.assert_array_equal(back.se2_array(), g.se2_array())
    np.testing.assert_array_equal(back.xy_array(), g.xy_array())
    np.testing.assert_array_equal(back.se3_array(), g.se3_array())
    assert back.chi2() == g.chi2()
    assert "FIX 1" in path.read_text()


def test_the_gil_is_released_while_solving():
    """The main thread keeps running while another thread solves."""
    n = 20000
    g = cairn.Graph()
    for i in range(n):
        g.add_se2(i, 0.1 * i, 0.0, 0.0)
    for i in range(n - 1):
        g.add_edge_se2(i, i + 1, [0.101, 0.001, 0.0001], np.eye(3))
    for i in range(0, n - 50, 7):
        g.add_edge_se2(i, i + 50, [5.0, 0.0, 0.0], np.eye(3))
    started, done = threading.Event(), threading.Event()

    def solve():
        started.set()
        g.optimize(solver="lm", init="file")
        done.set()

    worker = threading.Thread(target=solve)
    worker.start()
    started.wait()
    # Held through the solve, the GIL would stop this loop until `done`.
    spins = 0
    while not done.is_set():
        spins += 1
    worker.join()
    assert spins > 10000, spins
