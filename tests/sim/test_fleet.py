"""Several robots in one museum: their poses shared between processes, their bodies in each
other's worlds (seen by the laser, stopping the base)."""

from __future__ import annotations

import math
import multiprocessing

import numpy as np
import pytest

from tourbot.records import Scan
from tourbot.sim.fleet import FleetPoses
from tourbot.sim.simulator import SimConfig, Simulator
from tourbot.site.default import default_site


def _write_from_another_process(name: str) -> None:
    fleet = FleetPoses(3, name=name)
    fleet.write(2, (4.0, 5.0, 0.5))
    fleet.close()


def test_poses_are_shared_between_processes() -> None:
    fleet = FleetPoses(3)
    try:
        assert fleet.others(0).shape == (0, 2)  # nobody has written yet
        fleet.write(0, (1.0, 2.0, 0.0))
        assert fleet.others(0).shape == (0, 2)  # one's own pose is not another robot
        process = multiprocessing.get_context("spawn").Process(
            target=_write_from_another_process, args=(fleet.name,)
        )
        process.start()
        process.join(timeout=60)
        assert process.exitcode == 0
        assert fleet.others(0).tolist() == [[4.0, 5.0]]
        assert fleet.others(2).tolist() == [[1.0, 2.0]]
    finally:
        fleet.close()
    with pytest.raises(ValueError, match="at least one robot"):
        FleetPoses(0)


def test_robots_see_and_stop_at_each_other() -> None:
    site = default_site()
    x, y, heading = site.exhibits[0].viewing_pose
    start = (x, y, heading + math.pi)  # turned away from the exhibit: the hall is open ahead
    ahead = (start[0] + 2.0 * math.cos(start[2]), start[1] + 2.0 * math.sin(start[2]), start[2])
    fleet = FleetPoses(2)
    try:
        config = SimConfig(dynamic_objects=False)
        a = Simulator(site, config, seed=0, start=start, fleet=(fleet, 0))
        b = Simulator(site, config, seed=1, start=ahead, fleet=(fleet, 1))
        alone = Simulator(site, config, seed=0, start=start)
        b.poll()  # b is there
        scan = next(r for r in a.poll() or () if isinstance(r, Scan))
        clean = next(r for r in alone.poll() or () if isinstance(r, Scan))
        front = np.argmin(np.abs(scan.geometry.angles))  # the beam straight ahead
        radius = config.robot.radius
        assert scan.ranges[front] == pytest.approx(2.0 - radius - scan.geometry.offset[0], abs=0.1)
        assert clean.ranges[front] > scan.ranges[front] + 0.3  # without the other robot: farther
        assert not a.laser.last_person_hits.any()  # seen, but not as a person
        # a drives into b: it stops at b's body, one collision with a robot
        a.command(0.5, 0.0)
        for _ in range(60):
            a.poll()
            b.poll()
        gap = math.hypot(a.robot.pose[0] - b.robot.pose[0], a.robot.pose[1] - b.robot.pose[1])
        assert gap >= 2 * radius - 0.06
        assert a.collisions.robot == 1
        assert a.collisions.person == a.collisions.static == 0
        # it may back away
        a.command(-0.3, 0.0)
        for _ in range(30):
            a.poll()
        assert math.hypot(a.robot.pose[0] - b.robot.pose[0], a.robot.pose[1] - b.robot.pose[1]) > gap + 0.2
    finally:
        fleet.close()


def _write_crowd_from_another_process(name: str) -> None:
    fleet = FleetPoses(2, name=name)
    people = np.array([[1.0, 2.0], [3.0, 4.0]])
    legs = np.array([[0.9, 2.0], [1.1, 2.0], [2.9, 4.0], [3.1, 4.0]])
    fleet.write_crowd(7.5, people, np.array([[0.5, 0.0], [0.0, -0.5]]), legs, np.full(4, 0.06))
    fleet.close()


def test_the_crowd_is_shared_between_processes() -> None:
    fleet = FleetPoses(2)
    try:
        assert fleet.read_crowd() is None  # the host has not written yet
        process = multiprocessing.get_context("spawn").Process(
            target=_write_crowd_from_another_process, args=(fleet.name,)
        )
        process.start()
        process.join(timeout=60)
        assert process.exitcode == 0
        crowd = fleet.read_crowd()
        assert crowd is not None
        assert crowd.time == 7.5
        assert crowd.positions.tolist() == [[1.0, 2.0], [3.0, 4.0]]
        assert crowd.velocities.tolist() == [[0.5, 0.0], [0.0, -0.5]]
        assert crowd.centres.shape == (4, 2)
        assert crowd.radii.tolist() == [0.06] * 4
    finally:
        fleet.close()


def test_the_robots_of_one_museum_see_one_crowd_that_walks_around_both() -> None:
    """The museum's world steps the one crowd with both robots' poses; both simulators see the same
    visitors (their lasers hit them, their truth is theirs) and run none of their own; no visitor
    walks into either robot."""
    from dataclasses import replace

    from tourbot.app.simulated import crowd_config
    from tourbot.sim.world import MuseumWorld

    site = default_site()
    crowd = crowd_config("peak")
    assert crowd is not None
    crowd = replace(crowd, robot_interest=0.0)
    config = SimConfig(dynamic_objects=False, crowd=crowd)
    starts = [site.exhibits[i].viewing_pose for i in (0, 3)]
    fleet = FleetPoses(2)
    try:
        sims = [Simulator(site, config, seed=i, start=starts[i], fleet=(fleet, i)) for i in range(2)]
        assert all(sim.crowd is None for sim in sims)
        world = MuseumWorld(site, crowd, fleet, seed=0, wait=1.0)
        hits = 0
        closest = math.inf
        radius = config.robot.radius
        for _ in range(600):  # 60 s: visitors who did not avoid a robot walked into it (10 times)
            world.step()
            for sim in sims:
                records = sim.poll() or ()
                if any(isinstance(r, Scan) for r in records):
                    hits += int(sim.laser.last_person_hits.sum())
            people = world.crowd.positions
            for sim in sims:
                assert np.array_equal(sim.people_positions(), people)
                x, y, _ = sim.robot.pose
                closest = min(closest, float(np.min(np.hypot(people[:, 0] - x, people[:, 1] - y))))
        truth = sims[1].truth().people
        assert len(truth) == world.crowd.num_people > 100
        assert truth[5].vx == pytest.approx(float(world.crowd.velocities[5, 0]))
        assert hits > 0  # the lasers see the world's visitors
        # nobody inside a robot (the crowd's hard constraint: robot radius + half a person's), up to
        # the step the world is behind a robot (it reads the poses before the robots move)
        assert closest >= radius + 0.5 * crowd.person_radius - 0.06
        assert sum(sim.collisions.person for sim in sims) == 0
    finally:
        fleet.close()
