from __future__ import annotations

import math

import numpy as np
import pytest

from tourbot.maps.objects import ObjectShape, door_shape, segment_ranges
from tourbot.maps.raycast import DDACaster
from tourbot.records import LaserGeometry, Scan
from tourbot.site.model import Door, Site, site_from_dict


@pytest.fixture(scope="session")
def room() -> Site:
    """A 6 x 4 m room whose north wall has a 0.9 m doorway at x 3.0-3.9 with a door opening outwards."""
    walls = [
        [[0, 0], [6, 0], [6, 0.05], [0, 0.05]],
        [[0, 0], [0.05, 0], [0.05, 4], [0, 4]],
        [[5.95, 0], [6, 0], [6, 4], [5.95, 4]],
        [[0, 3.95], [3.0, 3.95], [3.0, 4.0], [0, 4.0]],
        [[3.9, 3.95], [6, 3.95], [6, 4.0], [3.9, 4.0]],
        [[0, 6], [6, 6], [6, 6.05], [0, 6.05]],
        [[0, 4], [0.05, 4], [0.05, 6], [0, 6]],
        [[5.95, 4], [6, 4], [6, 6], [5.95, 6]],
    ]
    door = {
        "name": "door",
        "hinge": [3.0, 3.975],
        "leaf_length": 0.9,
        "closed_direction": 0.0,
        "opening_angle": math.pi / 2,
        "thickness": 0.04,
    }
    from pathlib import Path

    return site_from_dict(
        {"name": "room", "map": {"walls": walls, "resolution": 0.05}, "doors": [door]}, base_dir=Path(".")
    )


GEOMETRY = LaserGeometry(num_beams=360, angle_min=-math.pi, angle_increment=math.radians(1.0), max_range=10.0)


def make_scan(
    room: Site,
    shapes: list[ObjectShape],
    states: list[np.ndarray],
    pose: tuple[float, float, float],
    t: float,
    rng: np.random.Generator,
    blockers: np.ndarray | None = None,
) -> Scan:
    """A scan of the room with the objects in ``states`` (and ``blockers``: extra edges (1, M, 4))."""
    caster = DDACaster(room.grid, GEOMETRY.max_range)
    p = np.asarray(pose, dtype=np.float64)[None]
    base = caster.cast(p, GEOMETRY.angles).astype(np.float64)
    segs = np.concatenate([s.segments(x)[0] for s, x in zip(shapes, states, strict=True)])[None]
    if blockers is not None:
        segs = np.concatenate([segs, blockers], axis=1)
    r = segment_ranges(p, GEOMETRY.angles, segs, base)[0, 0].astype(np.float64)
    r = np.where(r < GEOMETRY.max_range, r + rng.normal(0, 0.01, r.shape), GEOMETRY.max_range)
    return Scan(t, r, GEOMETRY, odom=pose, reference=pose)


def door_of(room: Site) -> ObjectShape:
    d: Door = room.doors[0]
    return door_shape(d)
