"""The search: annealing steps and the verification's likelihood ratio test."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from tourbot.geometry import compose
from tourbot.localization.mcl import MonteCarloLocalization
from tourbot.localization.mcl.search import anneal_step
from tourbot.maps.grid import OccupancyGrid

from ..conftest import simulate, waypoints_path
from .conftest import tuned
from .scenes import crowd_around


@settings(max_examples=40, deadline=None)
@given(arrays(np.float64, 50, elements=st.floats(-50, 0)), st.floats(0.05, 0.9))
def test_anneal_step_keeps_the_effective_sample_size(ll: np.ndarray, frac: float) -> None:
    def ess(d: float) -> float:
        w = np.exp(d * ll - (d * ll).max())
        return float(w.sum() ** 2 / (w * w).sum())

    target = frac * ll.size
    d = anneal_step(np.zeros(ll.size), ll, 1.0, target)
    assert 0.0 <= d <= 1.0
    assert ess(d) >= target - 1e-6
    if d < 1.0:  # the largest such step: a little more would go below the target
        assert ess(min(1.0, d + 1e-6 + 1e-3 * d)) < target + 1e-3 * ll.size


def test_verification_weighs_the_track_against_the_best_place(room: OccupancyGrid) -> None:
    # A likelihood ratio of the track against the best place a search of the map finds for the
    # scan: at the true pose, also with a crowd hiding part of the scan, the best alternative is
    # the track itself (a few centimetres off); moved by 1.5 m the track loses by far.
    truth = waypoints_path(10)
    crowded = simulate(room, truth, seed=25, circles=crowd_around(truth, np.random.default_rng(25), 14))
    cfg = tuned(300, 100, recovery={"verify_period": 5.0})
    margin_needed = cfg.recovery.verify_margin
    for k in (2, 6):
        scan = crowded.scans[k]
        r = np.asarray(scan.ranges)
        valid = r < scan.geometry.max_range
        search = MonteCarloLocalization(room, cfg, seed=26).search
        rng = np.random.default_rng([26, 1])
        drawn, margin = search.verify(truth[k], 60, r, scan.geometry, valid, rng, None)
        assert drawn.shape == (60, 3)  # the reset samples, should the track fail
        assert margin < margin_needed
        moved = compose(truth[k], np.array([1.5, 0.0, 0.0]))
        assert search.verify(moved, 60, r, scan.geometry, valid, rng, None)[1] > margin_needed


def test_scan_drawn_poses_come_from_the_scan(room: OccupancyGrid) -> None:
    truth = waypoints_path(10)
    scan = simulate(room, truth, seed=30).scans[5]
    r = np.asarray(scan.ranges)
    valid = r < scan.geometry.max_range
    search = MonteCarloLocalization(room, tuned(300, 100), seed=31).search
    rng = np.random.default_rng(32)
    wrong = compose(truth[5], np.array([0.8, 0.0, 3.0]))
    poses = search.scan_drawn_poses(50, r, scan.geometry, valid, wrong, rng, far=True)
    assert poses.shape == (50, 3)
    near = np.hypot(*(poses[:, :2] - truth[5, :2]).T) < 0.3
    assert near.mean() > 0.5  # most of them at the true pose, not around the wrong estimate
