"""The object overlay writes doors and furniture into a log, consistently with what it recorded."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tourbot.maps.objects import door_shape, furniture_shape
from tourbot.records import LaserGeometry, RobotLog, Scan
from tourbot.sim.object_overlay import (
    ObjectOverlayConfig,
    object_truth_path,
    overlay_objects,
    read_object_truth,
    write_object_truth,
)
from tourbot.sim.overlay import OverlayError
from tourbot.site.model import Door, Furniture


def _log(ranges: float = 5.0, n: int = 30) -> RobotLog:
    g = LaserGeometry(num_beams=181, angle_min=-math.pi / 2, angle_increment=math.pi / 180, max_range=20.0)
    scans = [
        Scan(float(k), np.full(181, ranges), g, odom=(0.0, 0.0, 0.0), reference=(0.0, 0.0, 0.0))
        for k in range(n)
    ]
    return RobotLog(source="test", scans=scans)


SHAPES = [
    door_shape(Door(name="d", hinge=(2.0, -0.45), leaf_length=0.9, closed_direction=math.pi / 2)),
    furniture_shape(
        Furniture(
            name="b",
            outline=[(-0.2, -0.2), (0.2, -0.2), (0.2, 0.2), (-0.2, 0.2)],
            poses=[(3.0, 1.5, 0.0), (3.0, 2.5, 0.0)],
        )
    ),
]
POSES: list[list[tuple[float, float, float]]] = [[], [(3.0, 1.5, 0.0), (3.0, 2.5, 0.0)]]


def test_objects_shorten_beams_in_front_only() -> None:
    out, truth = overlay_objects(_log(), SHAPES, POSES, ObjectOverlayConfig(period=5.0), seed=1)
    assert truth.names == ["d", "b"]
    assert truth.states[0].shape == (30, 1)
    assert len({float(v) for v in truth.states[0][:, 0]}) > 1  # the door moved during the log
    ahead = out.scans[0].ranges[90]  # the beam straight ahead meets the door, whatever its angle near 0
    assert ahead <= 5.0
    assert np.all(out.scans[0].ranges <= 5.0 + 0.05)
    assert sum(truth.changed) > 0
    # a nearer real wall keeps its reading: nothing is written behind it
    near, _ = overlay_objects(_log(ranges=1.0), SHAPES, POSES, seed=1)
    np.testing.assert_array_equal(near.scans[0].ranges, np.full(181, 1.0))


def test_the_overlaid_log_keeps_what_its_odometry_is() -> None:
    log = _log()
    log.odometry_kind, log.notes = "rebuilt", ["odometry: rebuilt from the increments"]
    out, _ = overlay_objects(log, SHAPES, POSES, seed=1)
    assert out.odometry_kind == "rebuilt"
    assert out.notes == log.notes


def test_truth_round_trips(tmp_path) -> None:  # type: ignore[no-untyped-def]
    _, truth = overlay_objects(_log(), SHAPES, POSES, seed=2)
    path = object_truth_path(tmp_path / "x.log.gz")
    assert path.name == "x.objects.json"
    write_object_truth(truth, path)
    back = read_object_truth(path)
    assert back.names == truth.names
    np.testing.assert_allclose(back.states[1], truth.states[1], atol=1e-6)


def test_a_log_without_reference_is_refused() -> None:
    log = _log()
    from dataclasses import replace

    log = RobotLog(source="x", scans=[replace(s, reference=None) for s in log.scans])
    with pytest.raises(OverlayError, match="reference"):
        overlay_objects(log, SHAPES, POSES)
