"""The detector on rendered pairs: the laser-invisible table is found where it stands, the empty
room gives (nearly) nothing, and a visitor walking by is masked."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tourbot.records import Image, Scan
from tourbot.sim.camera import ForwardCameraSim
from tourbot.sim.simulator import SimConfig, Simulator
from tourbot.site import Site, site_from_dict
from tourbot.vision.detector import View, VisionDetector
from tourbot.vision.model import scan_endpoints

from .conftest import ROOM


def _drive(site: Site, steps: int = 30) -> list[View]:
    """Views from the true pose while driving towards the table at 0.4 m/s."""
    cam = ForwardCameraSim(site, seed=0)
    sim = Simulator(site, SimConfig(dynamic_objects=False), seed=0, start=(2.4, 2.5, 0.0), cameras=[cam])
    views: list[View] = []
    scan = None
    for _ in range(steps):
        sim.command(0.4, 0.0)
        for r in sim.poll() or []:
            if isinstance(r, Scan):
                scan = r
            if isinstance(r, Image) and scan is not None:
                pose = np.array(sim.robot.pose)
                ep, ok = scan_endpoints(scan, pose)
                views.append(View(r.pixels, pose, ep, ok))
    return views


def _detections(site: Site) -> np.ndarray:
    views = _drive(site)
    det = VisionDetector(ForwardCameraSim(site).camera)
    pts = [det.detect(a, b).obstacles for a, b in zip(views[::2], views[1::2], strict=False)]
    return np.vstack(pts)


@pytest.mark.slow
def test_the_table_is_found_where_it_stands(room: Site) -> None:
    pts = _detections(room)
    # within 15 cm of the table's outline
    on_table = (pts[:, 0] > 4.85) & (pts[:, 0] < 6.15) & (pts[:, 1] > 2.05) & (pts[:, 1] < 2.95)
    assert on_table.sum() >= 100
    assert on_table.mean() > 0.85


@pytest.mark.slow
def test_an_empty_room_gives_almost_nothing() -> None:
    empty = site_from_dict({**ROOM, "invisible_obstacles": []}, base_dir=Path("."))
    assert len(_detections(empty)) <= 5


def test_a_moving_laser_return_masks_its_columns(room: Site) -> None:
    views = _drive(room, 6)
    a, b = views[-2], views[-1]
    det = VisionDetector(ForwardCameraSim(room).camera)
    plain = det.detect(a, b)
    assert not plain.masked.any()
    # a visitor 2 m ahead in image t, not in image t-1: a wide run of new endpoints
    legs = b.pose[:2] + np.array([2.0, 0.0]) + np.stack([np.zeros(5), np.linspace(-0.1, 0.1, 5)], axis=-1)
    moved = replace(b, endpoints=np.vstack([b.endpoints, legs]), returned=np.r_[b.returned, np.ones(5, bool)])
    masked = det.detect(a, moved).masked
    cols = np.flatnonzero(masked.any(axis=0))
    assert 200 < cols.mean() < 440  # straight ahead: the middle of the image
