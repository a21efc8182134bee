"""The forward camera's estimator: pairs images as the robot moves, publishes the table it finds."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.interfaces import ImageEstimator, PoseBelief
from tourbot.records import Image, Scan
from tourbot.runtime.vision import VisionEstimatorConfig, VisionObstacleEstimator, evidence_weights
from tourbot.sim.camera import ForwardCameraSim
from tourbot.sim.simulator import SimConfig, Simulator
from tourbot.site import site_from_dict
from tourbot.snapshot import PoseEstimate

ROOM = {
    "name": "room",
    "map": {"walls": [[[0, 0], [10, 0], [10, 6], [0, 6]]], "resolution": 0.05},
    "invisible_obstacles": [
        {
            "name": "table",
            "outline": [[5, 2.2], [6, 2.2], [6, 2.8], [5, 2.8]],
            "height": [0, 0.75],
            "kind": "table",
        }
    ],
}


def _belief(pose: tuple[float, float, float], cov: np.ndarray | None = None) -> PoseBelief:
    c = np.zeros((3, 3)) if cov is None else cov
    rows = [(float(r[0]), float(r[1]), float(r[2])) for r in c]
    estimate = PoseEstimate(*pose, covariance=(rows[0], rows[1], rows[2]))
    return PoseBelief(estimate, np.array([pose]), np.array([1.0]))


def _weights_reference(pose: np.ndarray, cov: np.ndarray, pts: np.ndarray, tol: float) -> np.ndarray:
    """Point by point: the displacement's covariance J C J^T, its largest eigenvalue, Rayleigh."""
    out = []
    for x, y in pts:
        ax, ay = x - pose[0], y - pose[1]
        jac = np.array([[1.0, 0.0, -ay], [0.0, 1.0, ax]])
        s2 = float(np.linalg.eigvalsh(jac @ cov @ jac.T).max())
        out.append(1.0 if s2 <= 0 else 1.0 - math.exp(-(tol**2) / (2.0 * s2)))
    return np.array(out)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), scale=st.floats(1e-6, 1.0))
def test_evidence_weights_match_the_displacement_covariance_point_by_point(seed: int, scale: float) -> None:
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(3, 3)) * np.array([scale, scale, 0.3 * scale])[:, None]
    cov = a @ a.T
    pose = rng.uniform(-5, 5, 3)
    pts = rng.uniform(-8, 8, (12, 2))
    w = evidence_weights(pose, cov, pts, 0.1)
    np.testing.assert_allclose(w, _weights_reference(pose, cov, pts, 0.1), rtol=1e-7, atol=1e-9)
    assert np.all((w >= 0) & (w <= 1))


def test_evidence_weights_closed_forms() -> None:
    pose = np.array([1.0, 2.0, 0.3])
    pts = np.array([[1.0, 2.0], [4.0, 2.0], [1.0, -1.0]])
    assert evidence_weights(pose, np.zeros((3, 3)), pts, 0.1).tolist() == [1.0, 1.0, 1.0]  # exact pose
    # position only (5 cm each way): the same everywhere, 1 - exp(-t^2 / (2 s^2))
    w = evidence_weights(pose, np.diag([0.05**2, 0.05**2, 0.0]), pts, 0.1)
    np.testing.assert_allclose(w, 1.0 - math.exp(-2.0), rtol=1e-12)
    # heading only (2 degrees): nothing at the robot, growing with the distance (3 m: 10.5 cm)
    sd = math.radians(2.0)
    w = evidence_weights(pose, np.diag([0.0, 0.0, sd**2]), pts, 0.1)
    assert w[0] == 1.0
    np.testing.assert_allclose(w[1:], 1.0 - math.exp(-(0.1**2) / (2 * (3.0 * sd) ** 2)), rtol=1e-12)
    assert 0.3 < w[1] < 0.5


@pytest.mark.slow
def test_estimator_publishes_the_table_and_ignores_other_cameras() -> None:
    site = site_from_dict(ROOM, base_dir=Path("."))
    cam = ForwardCameraSim(site, seed=0)
    sim = Simulator(site, SimConfig(dynamic_objects=False), seed=0, start=(2.4, 2.5, 0.0), cameras=[cam])
    est = VisionObstacleEstimator(site.grid, cam.camera)
    assert isinstance(est, ImageEstimator)
    for _ in range(30):
        sim.command(0.4, 0.0)
        for r in sim.poll() or []:
            if isinstance(r, Scan):
                est.on_scan(r, _belief(sim.robot.pose))  # the truth stands in for the localizer
            elif isinstance(r, Image):
                est.on_image(r, None)
                est.on_image(Image(r.timestamp, r.pixels, camera="ceiling", odom=r.odom), None)
    assert est.images == 15  # 5 Hz for 3 s; the ceiling images are not counted
    assert est.pairs >= 8
    pts = np.asarray(est.state().extra["obstacles"])
    assert len(pts) >= 5
    near = (pts[:, 0] > 4.85) & (pts[:, 0] < 6.15) & (pts[:, 1] > 2.05) & (pts[:, 1] < 2.95)
    assert near.mean() >= 0.8


@pytest.mark.slow
def test_the_pose_uncertainty_discounts_the_evidence_and_stops_it_when_too_large() -> None:
    """The same drive past the table, its images placed by an estimate that is exact, unsure of its
    heading by 3 degrees, or unsure of its position by 20 cm: full evidence, less of it, none."""
    site = site_from_dict(ROOM, base_dir=Path("."))
    cam = ForwardCameraSim(site, seed=0)
    sim = Simulator(site, SimConfig(dynamic_objects=False), seed=0, start=(2.4, 2.5, 0.0), cameras=[cam])
    records: list[tuple[Scan | Image, tuple[float, float, float]]] = []
    for _ in range(30):
        sim.command(0.4, 0.0)
        records += [(r, sim.robot.pose) for r in sim.poll() or [] if isinstance(r, (Scan, Image))]
    spreads = {
        "exact": np.zeros((3, 3)),
        "heading": np.diag([0.0, 0.0, math.radians(3.0) ** 2]),
        "lost": np.diag([0.2**2, 0.2**2, 0.0]),
    }
    runs = {}
    for name, cov in spreads.items():
        est = VisionObstacleEstimator(site.grid, cam.camera)
        for r, pose in records:
            if isinstance(r, Scan):
                est.on_scan(r, _belief(pose, cov))  # the truth stands in for the localizer
            else:
                est.on_image(r, None)
        runs[name] = est
    exact, heading, lost = runs["exact"], runs["heading"], runs["lost"]
    assert exact.pairs >= 8
    assert exact.uncertain == heading.uncertain == 0
    assert heading.pairs == exact.pairs
    # 20 cm of position spread: P(within 10 cm) = 0.12 < 0.25: no pair used, nothing mapped
    assert lost.pairs == 0
    assert lost.uncertain >= 8
    assert not lost.map.seen.any()
    # 3 degrees at 1-3 m: 5-16 cm of spread: less evidence than with the exact pose
    seen = exact.map.seen
    assert np.array_equal(heading.map.seen, seen)
    hits = exact.map.log_odds > 0
    assert hits.sum() >= 5
    # (a cell's misses are discounted too: one with both may end a little higher)
    assert np.mean(heading.map.log_odds[hits] < exact.map.log_odds[hits]) > 0.9
    assert heading.map.log_odds.max() < exact.map.log_odds.max()
    assert np.abs(heading.map.log_odds).sum() < 0.8 * np.abs(exact.map.log_odds).sum()
    assert heading.map.occupied().sum() < exact.map.occupied().sum()


def test_a_lost_estimate_uses_no_pair() -> None:
    """Without rendering: two images 10 cm apart, placed by an estimate 20 cm unsure, are not paired."""
    from tourbot.records import LaserGeometry
    from tourbot.vision.camera import ForwardCamera

    grid = site_from_dict(ROOM, base_dir=Path(".")).grid
    cam = ForwardCamera()
    est = VisionObstacleEstimator(grid, cam, VisionEstimatorConfig())
    geom = LaserGeometry(num_beams=3, angle_min=-0.5, angle_increment=0.5, max_range=8.0)
    pixels = np.zeros((cam.height, cam.width), dtype=np.uint8)
    lost = np.diag([0.2**2, 0.2**2, 0.0])
    for k in range(3):
        odom = (2.0 + 0.1 * k, 2.5, 0.0)
        est.on_scan(Scan(float(k), np.full(3, 4.0), geom, odom=odom), _belief(odom, lost))
        est.on_image(Image(float(k), pixels, camera="forward", odom=odom))
    assert (est.images, est.pairs, est.uncertain) == (3, 0, 2)
