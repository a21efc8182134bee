"""The object estimator in the runtime loop: alternating scans (Table 1), snapshot contents."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.objects.conftest import make_scan
from tourbot.interfaces import PoseBelief, ScanShare
from tourbot.maps.objects import door_shape
from tourbot.maps.raycast import DDACaster
from tourbot.objects.estimator import ObjectStateEstimator
from tourbot.objects.runtime import ObjectsEstimator
from tourbot.records import Record, Scan
from tourbot.runtime import Runtime
from tourbot.site.model import Site
from tourbot.snapshot import PoseEstimate


class ListSource:
    name = "list"

    def __init__(self, records: list[Record]) -> None:
        self.records = records
        self.t = 0.0

    @property
    def time(self) -> float:
        return self.t

    def poll(self):  # type: ignore[no-untyped-def]
        if not self.records:
            return None
        r = self.records.pop(0)
        self.t = r.timestamp
        return [r]


class FakeLocalizer:
    def __init__(self) -> None:
        self.scans = 0

    def on_odometry(self, odom) -> None:  # type: ignore[no-untyped-def]
        pass

    def on_scan(self, scan: Scan) -> PoseBelief:
        self.scans += 1
        assert scan.reference is not None
        p = np.asarray(scan.reference)[None]
        return PoseBelief(PoseEstimate(*scan.reference), p, np.ones(1))


def test_objects_get_the_odd_scans_and_reach_the_snapshot(room: Site) -> None:
    shape = door_shape(room.doors[0])
    rng = np.random.default_rng(0)
    scans: list[Record] = [
        make_scan(room, [shape], [np.array([math.radians(30.0)])], (2.0 + 0.025 * k, 2.0, 1.2), 0.1 * k, rng)
        for k in range(40)
    ]
    estimator = ObjectsEstimator(
        ObjectStateEstimator([shape], DDACaster(room.grid, 10.0)), {"door": math.pi / 2}
    )
    assert estimator.scan_share == ScanShare.ALL
    estimator.scan_share = ScanShare.ALTERNATE  # Table 1
    localizer = FakeLocalizer()
    runtime = Runtime(ListSource(scans), localizer, estimators=[estimator])
    while runtime.step() is not None:
        pass
    assert localizer.scans == 20
    assert len(estimator.history) == 20
    snap = runtime.snapshot()
    assert snap.doors[0].name == "door"
    assert abs(snap.doors[0].angle - math.radians(30.0)) < math.radians(3.0)
    assert abs(snap.doors[0].open_fraction - 1 / 3) < 0.05
    assert snap.estimators["objects"]["objects"][0]["status"] == "observed"


def test_the_estimates_reach_the_world_and_the_snapshot_carries_the_drawn_outline(room: Site) -> None:
    from tourbot.objects.world import ObjectWorld
    from tourbot.web.runtime_link import view_of

    shape = door_shape(room.doors[0])
    rng = np.random.default_rng(1)
    scans: list[Record] = [
        make_scan(room, [shape], [np.array([0.0])], (2.0 + 0.025 * k, 2.0, 1.2), 0.1 * k, rng)
        for k in range(20)
    ]

    class Planner:
        grids: list = []  # noqa: RUF012 - one instance

        def set_map(self, grid) -> None:  # type: ignore[no-untyped-def]
            self.grids.append(grid)

    planner = Planner()
    world = ObjectWorld(room.grid, [shape], [planner])
    estimator = ObjectsEstimator(
        ObjectStateEstimator([shape], DDACaster(room.grid, 10.0)), {"door": math.pi / 2}, world=world
    )
    runtime = Runtime(ListSource(scans), FakeLocalizer(), estimators=[estimator])
    before = runtime.snapshot()
    assert view_of(before).objects == ()  # nothing estimated yet: nothing drawn
    while runtime.step() is not None:
        pass
    assert planner.grids, "the door found closed never reached the map users"
    assert abs(world.drawn["door"][0]) < math.radians(3.0)
    view = view_of(runtime.snapshot())
    (door,) = view.objects
    assert door.kind == "door"
    # the leaf closed: along the wall from the hinge (3.0, 3.975) to 3.9
    xs = [x for x, _ in door.outline]
    ys = [y for _, y in door.outline]
    assert min(xs) == pytest.approx(3.0, abs=0.03)
    assert max(xs) == pytest.approx(3.9, abs=0.03)
    assert max(ys) - min(ys) < 0.1
