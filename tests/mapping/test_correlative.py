from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.geometry import compose, invert, transform_points
from tourbot.mapping.correlative import SearchWindow, Submap, max_pyramid, search, search_reference


def _room(rng: np.random.Generator) -> np.ndarray:
    """Points on the walls of an L-shaped room with a pillar (metres)."""
    t = np.linspace(0, 1, 120)
    walls = [
        np.c_[8 * t, 0 * t],
        np.c_[8 + 0 * t, 5 * t],
        np.c_[8 * t, 5 + 0 * t],
        np.c_[0 * t, 5 * t],
        np.c_[3 + 0.4 * t, 2 + 0 * t],
        np.c_[3 + 0 * t, 2 + 0.4 * t],
        np.c_[5 + 1.5 * t, 3.5 + 0 * t],
    ]
    return np.concatenate(walls) + rng.normal(0, 0.005, (len(walls) * 120, 2))


def test_max_pyramid_bounds_every_block() -> None:
    rng = np.random.default_rng(0)
    g = rng.random((13, 17))
    pyr = max_pyramid(g, 3)
    for h in range(4):
        s = 1 << h
        for r in range(13):
            for c in range(17):
                assert pyr[h, r, c] == g[r : r + s, c : c + s].max()


def test_search_finds_a_scan_moved_within_the_window() -> None:
    rng = np.random.default_rng(1)
    world = _room(rng)
    submap = Submap(world, 0.05, 0.05)
    truth = np.array([4.0, 2.5, 0.3])
    scan = transform_points(invert(truth), world[::3])  # the room seen from ``truth``
    guess = compose(truth, np.array([0.6, -0.4, 0.12]))
    m = search(submap, scan, guess, SearchWindow(1.0, 0.2), min_score=0.5)
    assert m is not None
    assert math.hypot(*(m.pose[:2] - truth[:2])) < 0.06
    assert abs(m.pose[2] - truth[2]) < 0.01
    assert m.score > 0.85
    # outside the window it is not found, and a threshold above the best refuses the match
    assert search(submap, scan, compose(truth, np.array([3.0, 0, 0])), SearchWindow(0.5, 0.05), 0.8) is None
    assert search(submap, scan, guess, SearchWindow(1.0, 0.2), min_score=0.999) is None


@settings(max_examples=25, deadline=None)
@given(
    st.integers(0, 10_000),
    st.floats(-0.5, 0.5),
    st.floats(-0.5, 0.5),
    st.floats(-0.1, 0.1),
    st.floats(0.05, 0.6),
    st.sampled_from([0.0, 0.3, 0.7]),
)
def test_branch_and_bound_matches_exhaustive_search(
    seed: int, ex: float, ey: float, eth: float, linear: float, threshold: float
) -> None:
    rng = np.random.default_rng(seed)
    world = _room(rng)
    submap = Submap(world, 0.1, 0.1, levels=4)
    truth = np.array([rng.uniform(2, 6), rng.uniform(1, 4), rng.uniform(-3, 3)])
    scan = transform_points(invert(truth), world[rng.choice(len(world), 60, replace=False)])
    scan = scan + rng.normal(0, 0.03, scan.shape)
    guess = compose(truth, np.array([ex, ey, eth]))
    window = SearchWindow(linear, 0.05)
    fast = search(submap, scan, guess, window, threshold)
    slow = search_reference(submap, scan, guess, window, threshold)
    assert (fast is None) == (slow is None)
    if fast is not None and slow is not None:
        assert abs(fast.score - slow.score) < 1e-9
