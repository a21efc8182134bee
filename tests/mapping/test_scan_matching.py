from __future__ import annotations

import cv2
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.mapping.scan_matching import MatchParams, curvature, hill_climb, score, score_reference


def _field(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.random((40, 50)).astype(np.float32)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 1000),
    x=st.floats(-0.5, 3.0),
    y=st.floats(-0.5, 2.5),
    th=st.floats(-4, 4),
)
def test_score_kernel_matches_numpy_reference(seed: int, x: float, y: float, th: float) -> None:
    field = _field(seed)
    rng = np.random.default_rng(seed + 1)
    pts = rng.uniform(-1.5, 1.5, (30, 2))
    w = rng.uniform(0, 1, 30)
    pose = np.array([x, y, th])
    assert np.isclose(
        score(field, 0.05, pose, pts, w, 0.02), score_reference(field, 0.05, pose, pts, w, 0.02)
    )


def test_hill_climb_recovers_an_offset() -> None:
    # an L-shaped wall, blurred: the scan of it seen from a known pose
    res = 0.05
    walls = np.zeros((200, 200), np.float32)
    walls[50, 50:150] = 1.0
    walls[50:150, 50] = 1.0
    blurred = np.asarray(cv2.GaussianBlur(walls, (0, 0), 2.0), dtype=np.float32)
    field = blurred / blurred.max()
    wall = np.r_[
        np.c_[np.linspace(2.6, 7.4, 60), np.full(60, 2.525)],
        np.c_[np.full(60, 2.525), np.linspace(2.6, 7.4, 60)],
    ]
    truth = np.array([5.0, 5.0, 0.3])
    c, s = np.cos(truth[2]), np.sin(truth[2])
    d = wall - truth[:2]
    local = np.c_[c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]]
    start = truth + np.array([0.15, -0.12, 0.06])
    params = MatchParams()
    best, _ = hill_climb(
        field, res, start, local, np.full(len(local), 0.5), start, np.array([1.0, 1.0, 1.0]), params
    )
    assert np.hypot(*(best[:2] - truth[:2])) < 0.03
    assert abs(best[2] - truth[2]) < 0.01


def test_the_curvature_of_a_match_to_one_wall_is_nothing_along_it() -> None:
    """One straight wall pins the distance to it and the heading, not the position along it."""
    res = 0.05
    walls = np.zeros((200, 200), np.float32)
    walls[50, 20:180] = 1.0
    blurred = np.asarray(cv2.GaussianBlur(walls, (0, 0), 1.0), dtype=np.float32)
    field = blurred / blurred.max()
    pose = np.array([5.0, 4.0, 0.0])
    local = np.c_[np.linspace(-2.0, 2.0, 80), np.full(80, 2.525 - 4.0)]
    info = curvature(field, res, pose, local, np.full(80, 0.5), 0.02, np.array([res, res, res / 2.0]))
    assert np.allclose(info, info.T)
    values, vectors = np.linalg.eigh(info)
    assert values[0] >= 0.0
    assert abs(vectors[0, 0]) > 0.99  # the direction with no information: along the wall (x)
    assert values[0] < 1e-3 * values[-1]
    assert info[1, 1] > 100.0 * max(info[0, 0], 1e-9)
