"""The forward camera's estimator: pairs images as the robot moves, publishes the table it finds."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tourbot.interfaces import ImageEstimator, PoseBelief
from tourbot.records import Image, Scan
from tourbot.runtime.vision import VisionObstacleEstimator
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


def _belief(pose: tuple[float, float, float]) -> PoseBelief:
    return PoseBelief(PoseEstimate(*pose), np.array([pose]), np.array([1.0]))


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
