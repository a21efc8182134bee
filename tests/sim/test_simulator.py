from __future__ import annotations

import math

import numpy as np
import pytest

from tourbot.records import Odometry, Scan
from tourbot.robot import DiffDriveConfig
from tourbot.sim.crowd import CrowdConfig
from tourbot.sim.odometry import OdometryError, OdometryErrorConfig
from tourbot.sim.robot import DiffDrive, integrate_arc
from tourbot.sim.simulator import SimConfig, Simulator
from tourbot.site import Site


def test_diff_drive_respects_limits_and_integrates_arcs() -> None:
    cfg = DiffDriveConfig()
    robot = DiffDrive(cfg, (0.0, 0.0, 0.0))
    robot.command(5.0, 0.0)
    assert robot.cmd_speed == cfg.max_speed
    _, v, _ = robot.propose(0.1)
    assert v == pytest.approx(cfg.max_accel * 0.1)
    # a quarter circle of radius 1
    x, y, th = integrate_arc((0.0, 0.0, 0.0), 1.0, 1.0, math.pi / 2)
    assert (x, y, th) == pytest.approx((1.0, 1.0, math.pi / 2))


def test_odometry_error_is_systematic_and_random() -> None:
    rng = np.random.default_rng(0)
    exact = OdometryError(
        OdometryErrorConfig(
            translation_scale=1.0, rotation_scale=1.0, drift=0.0, alpha1=0, alpha2=0, alpha3=0, alpha4=0
        )
    )
    noisy = OdometryError(OdometryErrorConfig())
    pose = (0.0, 0.0, 0.0)
    for _ in range(100):  # 10 m straight
        nxt = (pose[0] + 0.1, 0.0, 0.0)
        exact.step(pose, nxt, rng)
        noisy.step(pose, nxt, rng)
        pose = nxt
    assert exact.pose == pytest.approx((10.0, 0.0, 0.0), abs=1e-9)
    # 1.5 % too long and a drift of half a degree per metre
    assert noisy.pose[0] == pytest.approx(10.15, abs=0.1)
    assert abs(noisy.pose[2]) > math.radians(2)


def test_simulator_is_deterministic_for_a_seed(hall: Site) -> None:
    def run(seed: int) -> tuple[np.ndarray, np.ndarray]:
        sim = Simulator(hall, SimConfig(crowd=CrowdConfig(num_people=10)), seed=seed, start=(2.0, 6.0, 0.0))
        sim.command(0.4, 0.1)
        scans = []
        for _ in range(30):
            scans += [r for r in sim.poll() or [] if isinstance(r, Scan)]
        return np.array([s.ranges for s in scans]), sim.people_positions()

    a, pa = run(3)
    b, pb = run(3)
    c, _ = run(4)
    assert np.array_equal(a, b)
    assert np.array_equal(pa, pb)
    assert not np.array_equal(a, c)


def test_records_carry_odometry_and_truth(hall: Site) -> None:
    sim = Simulator(hall, SimConfig(laser_rate=5.0), seed=0, start=(2.0, 6.0, 0.0))
    sim.command(0.5, 0.0)
    kinds = [[type(r) for r in sim.poll() or []] for _ in range(10)]
    assert all(k[0] is Odometry for k in kinds)
    assert sum(Scan in k for k in kinds) == 5  # 5 Hz laser, 10 Hz steps
    truth = sim.truth()
    assert truth.pose[0] > 2.0
    assert sim.time == pytest.approx(1.0)


def test_laser_sees_walls_and_legs_but_not_glass(hall: Site) -> None:
    sim = Simulator(hall, SimConfig(dynamic_objects=False), seed=0, start=(11.0, 6.0, 0.0))
    legs = np.array([[12.0, 6.05], [12.0, 5.95]])
    ranges = sim.laser.scan((11.0, 6.0, 0.0), legs, np.array([0.06, 0.06]), np.random.default_rng(0))
    g = sim.laser.geometry
    ahead = int(np.argmin(np.abs(g.angles)))
    assert ranges[ahead] == pytest.approx(1.0 - 0.06, abs=0.05)
    # without the legs the beam passes the glass case (x = 13) and hits the far wall (x = 20)
    ranges = sim.laser.scan((11.0, 6.0, 0.0), np.zeros((0, 2)), np.zeros(0), np.random.default_rng(0))
    assert ranges[ahead] == pytest.approx(9.0, abs=0.1)


def test_laser_marks_the_beams_that_hit_a_person_without_changing_the_ranges(hall: Site) -> None:
    sim = Simulator(hall, SimConfig(dynamic_objects=False), seed=0, start=(11.0, 6.0, 0.0))
    legs = np.array([[12.0, 6.05], [12.0, 5.95], [11.0, 7.0]])  # two legs, then a door-like circle
    radii = np.array([0.06, 0.06, 0.1])
    pose = (11.0, 6.0, 0.0)
    plain = sim.laser.scan(pose, legs, radii, np.random.default_rng(1))
    marked = sim.laser.scan(pose, legs, radii, np.random.default_rng(1), people=2)
    assert np.array_equal(plain, marked)
    person = sim.laser.last_person_hits
    g = sim.laser.geometry
    ahead = int(np.argmin(np.abs(g.angles)))
    left = int(np.argmin(np.abs(g.angles - math.pi / 2)))
    assert person[ahead]  # the leg is a person
    assert not person[left]  # the circle on the left is not
    # exactly the beams that end on the legs: without them those beams reach farther
    empty = sim.laser.scan(pose, legs[2:], radii[2:], np.random.default_rng(1))
    assert np.array_equal(person, marked < empty - 0.1)


def test_recorded_runs_keep_the_person_hits_of_each_scan(hall: Site) -> None:
    cfg = SimConfig(crowd=CrowdConfig(num_people=15), record=True)
    sim = Simulator(hall, cfg, seed=2, start=(2.0, 6.0, 0.0))
    for _ in range(20):
        sim.poll()
    log = sim.to_robot_log()
    assert len(sim.person_hit_history) == len(log.scans) == 20
    assert any(m.any() for m in sim.person_hit_history)
    for scan, person in zip(log.scans, sim.person_hit_history, strict=True):
        assert np.all(scan.ranges[person] < scan.geometry.max_range)


def test_bumping_the_glass_case_counts_and_stops(hall: Site) -> None:
    sim = Simulator(hall, SimConfig(dynamic_objects=False), seed=0, start=(12.0, 6.0, 0.0))
    sim.command(0.5, 0.0)
    for _ in range(40):
        sim.poll()
    assert sim.collisions.invisible == 1
    assert sim.robot.pose[0] < 13.0 - 0.3 + 0.05
    assert sim.truth().collisions == 1


def test_doors_swing_and_furniture_moves(hall: Site) -> None:
    sim = Simulator(hall, SimConfig(), seed=0, start=(2.0, 6.0, 0.0))
    before_door = sim.truth().doors[0].open_fraction
    before_bench = sim.truth().furniture[0]
    for _ in range(45):  # the bench moves at 3 s
        sim.poll()
    assert sim.truth().furniture[0] != before_bench
    assert sim.truth().doors[0].open_fraction == before_door
    for _ in range(20):  # the door starts closing at 5 s
        sim.poll()
    assert sim.truth().doors[0].open_fraction < before_door
    segments = sim.objects.segments()
    assert segments.shape == (1, 4 * len(sim.objects.shapes), 4)  # a leaf and a bench, 4 edges each
    # the bench is in the drawn world
    assert sim.world.occupied().sum() > sim.static.occupied().sum()


def test_people_collisions_are_counted(hall: Site) -> None:
    sim = Simulator(hall, SimConfig(crowd=CrowdConfig(num_people=1)), seed=0, start=(2.0, 6.0, 0.0))
    assert sim.crowd is not None
    sim._legs = (np.array([[2.1, 6.0]]), np.array([0.06]))
    sim._check_people()
    assert sim.collisions.person == 1
    sim._check_people()  # still the same contact
    assert sim.collisions.person == 1


def test_sensor_stream_round_trips_through_a_carmen_log(hall: Site, tmp_path) -> None:  # type: ignore[no-untyped-def]
    from tourbot.io.carmen import read_carmen, write_carmen

    sim = Simulator(hall, SimConfig(record=True), seed=0, start=(2.0, 6.0, 0.0))
    sim.command(0.4, 0.2)
    for _ in range(20):
        sim.poll()
    log = sim.to_robot_log()
    path = tmp_path / "sim.log.gz"
    write_carmen(log, path)
    back = read_carmen(path)
    assert len(back.scans) == len(log.scans) == 20
    np.testing.assert_allclose(back.ranges, log.ranges, atol=1e-3)
    np.testing.assert_allclose(back.reference_poses, log.reference_poses, atol=1e-4)


def test_a_carried_robot_stands_where_it_was_set_down_and_the_odometry_sees_nothing(hall: Site) -> None:
    sim = Simulator(hall, SimConfig(dynamic_objects=False), seed=3, start=(2.0, 6.0, 0.0))
    sim.command(0.3, 0.0)
    for _ in range(10):
        sim.poll()
    before = sim.odometry.pose
    sim.carry((6.0, 3.0, 1.0))
    assert sim.robot.speed == 0.0
    sim.command(0.0, 0.0)
    records = sim.poll()
    assert records is not None
    odom = next(r for r in records if isinstance(r, Odometry))
    # the wheels did not turn: the odometry moved by at most the last step's deceleration
    assert math.hypot(odom.pose[0] - before[0], odom.pose[1] - before[1]) < 0.05
    assert math.hypot(sim.robot.pose[0] - 6.0, sim.robot.pose[1] - 3.0) < 0.05


def test_cameras_on_the_robot_give_image_records_at_their_rate() -> None:
    from tourbot.ceiling.rig import CeilingCamera
    from tourbot.records import Image
    from tourbot.sim.camera import CeilingCameraSim, SimCamera
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site

    site = load_site(site_path("domus"))
    cam = CeilingCameraSim(site, CeilingCamera(), seed=1)
    assert isinstance(cam, SimCamera)
    sim = Simulator(site, SimConfig(record=True), seed=0, cameras=[cam])
    images: list[Image] = []
    for _ in range(25):  # 2.5 s at dt 0.1: the 1 Hz camera at 0.1, 1.1 and 2.1 s
        records = sim.poll()
        assert records is not None
        images += [r for r in records if isinstance(r, Image)]
    assert [round(i.timestamp, 6) for i in images] == [0.1, 1.1, 2.1]
    assert all(i.camera == "ceiling" and i.pixels.dtype == np.uint8 for i in images)
    assert images[0].reference is not None
    assert images[0].odom is not None
    assert [i.timestamp for i in sim.image_history["ceiling"]] == [i.timestamp for i in images]
    # the CARMEN log keeps the laser and the odometry only
    log = sim.to_robot_log()
    assert len(log.scans) == 25
    assert len(log.odometry) == 25


def test_the_laser_sees_what_spans_its_plane_of_the_obstacles() -> None:
    from pathlib import Path

    from tourbot.site import site_from_dict

    from .conftest import HALL

    def beam_ahead(obstacle: dict) -> float:
        site = site_from_dict({**HALL, "invisible_obstacles": [obstacle]}, base_dir=Path("."))
        sim = Simulator(
            site, SimConfig(dynamic_objects=False, laser_rate=10.0), seed=0, start=(2.0, 2.5, 0.0)
        )
        for _ in range(2):
            for r in sim.poll() or []:
                if isinstance(r, Scan):
                    return float(r.ranges[len(r.ranges) // 2])
        raise AssertionError("no scan")

    outline = [[4, 2], [5, 2], [5, 3], [4, 3]]
    free = beam_ahead({"name": "low", "outline": outline, "height": [0.0, 0.3]})
    assert free > 5.0  # a bench below the plane: the beam passes
    assert abs(beam_ahead({"name": "box", "outline": outline, "height": [0.0, 0.9]}) - 2.0) < 0.05
    assert beam_ahead({"name": "glass", "outline": outline, "height": [0.0, 1.0], "kind": "glass"}) > 5.0
    # a table on legs: the beam straight ahead passes between the legs at y 2.05 and 2.95
    assert beam_ahead({"name": "t", "outline": outline, "height": [0.0, 0.75], "kind": "table"}) > 5.0
