"""The museum's world in its own process: ready, stopped, and started again when it dies."""

from __future__ import annotations

import itertools
import time

import numpy as np
import pytest

from tourbot.sim.fleet import FleetPoses
from tourbot.site.default import default_site
from tourbot.web.serve import SimulatedWorldFactory
from tourbot.web.supervised import RobotProcessError
from tourbot.web.world_process import WorldProcess


def test_a_world_that_cannot_start_says_why() -> None:
    fleet = FleetPoses(1)
    try:
        world = WorldProcess(SimulatedWorldFactory("fhw", "empty", 0, (fleet.name, 1)))
        with pytest.raises(RobotProcessError, match="an empty museum has no crowd"):
            world.wait_ready(120.0)
    finally:
        fleet.close()


@pytest.mark.slow
def test_a_world_whose_process_dies_carries_its_crowd_on() -> None:
    """kill -9 of the world's process: it is started again within seconds, and its visitors walk on
    from where they were (the crowd's clock never goes back, no jump beyond walking)."""
    site = default_site()
    fleet = FleetPoses(2)
    world = None
    try:
        for k in range(2):
            fleet.write(k, site.exhibits[k].viewing_pose)
        world = WorldProcess(SimulatedWorldFactory("fhw", "40", 0, (fleet.name, 2)))
        world.wait_ready(300.0)
        looks: list[tuple[float, np.ndarray]] = []

        def watch(seconds: float) -> None:
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                crowd = fleet.read_crowd()
                if crowd is not None and (not looks or crowd.time != looks[-1][0]):
                    looks.append((crowd.time, crowd.positions))
                time.sleep(0.02)

        watch(1.5)
        world._process.kill()
        killed = len(looks)
        deadline = time.monotonic() + 120.0
        while len(looks) < killed + 20 and time.monotonic() < deadline:
            watch(0.5)
        assert world.restarts, "the world was not started again"
        assert world.alive
        assert len(looks) >= killed + 20, "the restarted world does not step"
        times = np.array([t for t, _ in looks])
        assert (np.diff(times) > 0).all(), "the crowd's clock went back: a fresh crowd"
        for (t0, p0), (t1, p1) in itertools.pairwise(looks):
            assert len(p1) == len(p0) == 40
            assert float(np.max(np.linalg.norm(p1 - p0, axis=1))) <= 1.8 * (t1 - t0) + 0.2
    finally:
        if world is not None:
            world.close()
        fleet.close()
