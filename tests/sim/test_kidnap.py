"""Kidnapping on a log: the paper's rate and perturbation, and odometry carried consistently."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tourbot.geometry import relative
from tourbot.records import LaserGeometry, Odometry, RobotLog, Scan
from tourbot.sim.kidnap import Kidnap, KidnapConfig, KidnapError, apply_kidnaps, plan_kidnaps


def _straight_log(n: int = 50, step: float = 0.5) -> RobotLog:
    geometry = LaserGeometry(5, -math.pi / 2, math.pi / 4, 50.0)
    scans, odometry = [], []
    for i in range(n):
        pose = (i * step, 0.1 * i, 0.02 * i)
        odometry.append(Odometry(float(i) - 0.5, pose))
        scans.append(Scan(float(i), np.ones(5), geometry, odom=pose, reference=pose))
    return RobotLog("synthetic", scans, odometry)


def test_rate_is_per_metre_of_motion() -> None:
    ref = np.zeros((10001, 3))
    ref[:, 0] = np.arange(10001) * 1.0  # 10 km in 1 m steps
    rng = np.random.default_rng(0)
    counts = [len(plan_kidnaps(ref, np.arange(10001.0), rng)) for _ in range(20)]
    # Expected 0.005 * 10000 = 50 per run.
    assert 45 < np.mean(counts) < 55
    assert plan_kidnaps(np.zeros((100, 3)), np.arange(100.0), rng) == []


def test_perturbation_matches_the_paper() -> None:
    ref = np.zeros((20001, 3))
    ref[:, 0] = np.arange(20001) * 1.0
    kids = plan_kidnaps(
        ref, np.arange(20001.0), np.random.default_rng(1), KidnapConfig(probability_per_metre=0.05)
    )
    turns = np.abs(np.array([k.delta[2] for k in kids]))
    shifts = np.array([math.hypot(k.delta[0], k.delta[1]) for k in kids])
    assert turns.min() >= math.pi / 2 - 1e-9
    assert shifts.max() <= 1.0
    assert 0.4 < shifts.mean() < 0.6
    assert all(k.scan >= 1 for k in kids)


def test_odometry_gains_the_phantom_motion_and_keeps_its_increments() -> None:
    log = _straight_log()
    kid = Kidnap(scan=20, time=20.0, delta=(0.3, -0.2, math.pi))
    out = apply_kidnaps(log, [kid])
    before, after = log.odom_poses, out.odom_poses
    np.testing.assert_allclose(after[:20], before[:20])
    # At the kidnap the odometry shows the phantom motion on top of the true pose.
    np.testing.assert_allclose(relative(before[20], after[20]), kid.delta, atol=1e-12)
    # Later increments are unchanged in the robot frame.
    np.testing.assert_allclose(
        relative(after[20:-1], after[21:]), relative(before[20:-1], before[21:]), atol=1e-12
    )
    # References and ranges untouched.
    np.testing.assert_allclose(out.reference_poses, log.reference_poses)
    # Raw odometry after scan 19 is carried the same way as the scans.
    raw = np.array([o.pose for o in out.odometry])
    np.testing.assert_allclose(raw[:20], np.array([o.pose for o in log.odometry])[:20])
    np.testing.assert_allclose(
        relative(raw[20], after[20]), relative(np.array(log.odometry[20].pose), before[20]), atol=1e-12
    )


def test_bad_kidnap_is_an_error() -> None:
    with pytest.raises(KidnapError, match="outside"):
        apply_kidnaps(_straight_log(5), [Kidnap(scan=9, time=9.0, delta=(0.0, 0.0, 1.0))])
