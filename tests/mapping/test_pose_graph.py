from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tourbot.geometry import compose, relative
from tourbot.mapping.pose_graph import PoseGraph, PoseGraphError, edge_errors
from tourbot.metrics.relative import aligned_trajectory_error

INFO = np.diag([400.0, 400.0, 2500.0])  # 5 cm, 1.1 deg
LOOP = np.diag([100.0, 100.0, 2500.0])


def _square(n: int = 80) -> np.ndarray:
    """Poses around a 10 m square, ending where they began."""
    side = n // 4
    pts = []
    for k in range(4):
        for t in np.linspace(0, 10, side, endpoint=False):
            x, y = [(t, 0), (10, t), (10 - t, 10), (0, 10 - t)][k]
            pts.append((x, y, k * np.pi / 2))
    return np.asarray(pts)


def _drifted_graph(truth: np.ndarray, rng: np.random.Generator) -> PoseGraph:
    g = PoseGraph()
    pose = truth[0].copy()
    g.add_node(pose)
    for i in range(1, len(truth)):
        step = relative(truth[i - 1], truth[i]) + np.r_[rng.normal(0, 0.02, 2), 0.01 + rng.normal(0, 0.005)]
        pose = compose(pose, step)
        g.add_node(pose)
        g.add_edge(i - 1, i, step, INFO)
    return g


def test_a_closure_straightens_the_loop_and_a_false_one_does_not_wreck_it() -> None:
    truth = _square()
    g = _drifted_graph(truth, np.random.default_rng(0))
    drifted = aligned_trajectory_error(g.array(), truth).rmse
    n = len(truth)
    # a true closure, far from the drifted estimate: with the plain cost it pulls the loop shut
    # (graph SLAM adds closures so, once they pass its consistency check) ...
    g.add_edge(n - 1, 0, relative(truth[n - 1], truth[0]), LOOP)
    closed = aligned_trajectory_error(g.optimize(), truth).rmse
    assert drifted > 1.0
    assert closed < 0.25 * drifted
    # ... and keeps the robust kernel from then on
    g.edges[-1] = replace(g.edges[-1], robust=True)
    assert aligned_trajectory_error(g.optimize(), truth).rmse < closed + 0.02
    # a false closure: the far corner said to be at the start
    wrong = PoseGraph(list(g.poses), list(g.edges))
    wrong.add_edge(n // 4, 0, np.zeros(3), LOOP, robust=True)
    survived = aligned_trajectory_error(wrong.optimize(), truth).rmse
    assert survived < closed + 0.1
    # without the robust kernel the same false closure bends the square
    plain = PoseGraph(list(g.poses), list(g.edges))
    plain.add_edge(n // 4, 0, np.zeros(3), LOOP, robust=False)
    assert aligned_trajectory_error(plain.optimize(), truth).rmse > 1.0


def test_bad_edges_are_refused() -> None:
    g = PoseGraph()
    g.add_node(np.zeros(3))
    with pytest.raises(PoseGraphError, match="do not exist"):
        g.add_edge(0, 1, np.zeros(3), INFO)
    g.add_node(np.ones(3))
    with pytest.raises(PoseGraphError, match="positive definite"):
        g.add_edge(0, 1, np.zeros(3), -INFO)
    with pytest.raises(PoseGraphError, match="no nodes"):
        PoseGraph().optimize()


@pytest.mark.parametrize(("name", "shrink"), [("intel", 10.0), ("MIT", 1e5), ("CSAIL", 1e4)])
def test_real_pose_graphs_converge(shared_data: Path, name: str, shrink: float) -> None:
    from tourbot.io.g2o import read_g2o

    data = read_g2o(shared_data / "posegraph" / f"{name}.g2o")
    g = PoseGraph()
    for p in data.poses:
        g.add_node(p)
    for (i, j), m, info in zip(data.edges, data.measurements, data.information, strict=True):
        g.add_edge(int(i), int(j), m, info)
    before = edge_errors(g.array(), g.edges).sum()
    after = edge_errors(g.optimize(), g.edges)
    assert after.sum() < before / shrink
    # a minimum: optimising again from there finds nothing better
    again = edge_errors(g.optimize(), g.edges).sum()
    assert again == pytest.approx(after.sum(), rel=1e-3)


def test_many_agreeing_false_closures_do_not_bend_a_slack_stretch() -> None:
    """Freiburg 079's failure in small: a run of closures that agree with each other but not with
    the loop (each 1 m and 10 deg off), and a stretch of slack edges (a front end that fitted its
    scans poorly) that they could bend; DCS switches them off (a Cauchy kernel, with the same
    scale, leaves the square 0.33 m off). Twenty closures only 0.3 m and 3 deg off win against
    the one true closure under either kernel: those are the verification's to refuse."""
    truth = _square()
    n = len(truth)
    g = PoseGraph()
    for pose in truth:
        g.add_node(pose)
    for i in range(1, n):
        info = INFO / 25.0 if n // 2 <= i < 3 * n // 4 else INFO  # the third side: 5x the deviations
        g.add_edge(i - 1, i, relative(truth[i - 1], truth[i]), info)
    g.add_edge(n - 1, 0, relative(truth[n - 1], truth[0]), LOOP, robust=True)  # the true closure
    false = np.array([1.0, 0.0, np.radians(10.0)])
    for k in range(20):  # the fourth side's nodes seen from the first side's, all as far off
        a, b = k, n - 1 - k
        g.add_edge(a, b, compose(relative(truth[a], truth[b]), false), LOOP, robust=True)
    assert aligned_trajectory_error(g.optimize(), truth).rmse < 0.05
