"""Tracking from a moving robot without odometry: poses by scan matching, no tracks on a static scene."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tourbot.geometry import compose, invert, relative, transform_points
from tourbot.mapping.ego_motion import ScanMatchedPoses
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.raycast import DDACaster
from tourbot.people.sjpdaf import PeopleTracker
from tourbot.records import LaserGeometry, Scan

GEOMETRY = LaserGeometry(
    num_beams=361, angle_min=-0.75 * math.pi, angle_increment=1.5 * math.pi / 360, max_range=20.0
)
# Pairs of thin posts 25 cm apart: to a laser they look just like a person's two legs.
POSTS = np.array(
    [[3.0, 2.0], [3.25, 2.0], [6.0, 6.5], [6.0, 6.75], [9.0, 3.0], [9.2, 3.15], [4.5, 7.5], [4.75, 7.5]]
)


def _room() -> OccupancyGrid:
    res = 0.05
    prob = np.zeros((200, 240), dtype=np.float32)  # 12 x 10 m
    prob[:2, :] = prob[-2:, :] = 1.0
    prob[:, :2] = prob[:, -2:] = 1.0
    prob[60:80, 150:190] = 1.0  # a cabinet
    prob[140:150, 40:90] = 1.0  # a bench
    return OccupancyGrid(prob=prob, resolution=res)


def _drive(scans: int = 90) -> tuple[list[Scan], np.ndarray]:
    """A robot driving an arc at 0.5 m/s through the room, 10 Hz, 1 cm range noise, no odometry."""
    rng = np.random.default_rng(3)
    caster = DDACaster(_room(), GEOMETRY.max_range)
    t = np.arange(scans) * 0.1
    heading = 0.2 + 0.25 * t
    x = 2.0 + np.cumsum(0.05 * np.cos(heading))
    y = 4.0 + np.cumsum(0.05 * np.sin(heading))
    poses = np.stack([x, y, heading], -1)
    ranges = caster.cast_with_circles(poses, GEOMETRY.angles, POSTS, np.full(len(POSTS), 0.05))
    out = [
        Scan(float(tk), r.astype(np.float64) + rng.normal(0.0, 0.01, r.shape), GEOMETRY)
        for tk, r in zip(t, ranges, strict=True)
    ]
    return out, poses


@pytest.fixture(scope="module")
def drive() -> tuple[list[Scan], np.ndarray]:
    return _drive()


def test_static_posts_give_no_confirmed_track_from_a_moving_robot(
    drive: tuple[list[Scan], np.ndarray],
) -> None:
    scans, truth = drive
    ego = ScanMatchedPoses()
    tracker = PeopleTracker(rng=np.random.default_rng(0), pose_source=ego)
    confirmed = sum(sum(t.confirmed for t in tracker.update(scan)) for scan in scans)
    assert confirmed == 0
    # The poses came from scan matching; the first scan is the origin of the world frame.
    rel_true = relative(truth[0], truth)
    err = np.linalg.norm(np.array(ego.mapper.poses)[:, :2] - rel_true[:, :2], axis=1)
    assert np.hypot(*(rel_true[-1, :2])) > 3.0  # the robot really drove
    assert err.max() < 0.15


def test_without_poses_the_same_posts_seem_to_walk(drive: tuple[list[Scan], np.ndarray]) -> None:
    # The failure the scan matching removes: taking the robot as still, static posts move.
    scans, _ = drive
    tracker = PeopleTracker(rng=np.random.default_rng(0))
    confirmed = sum(sum(t.confirmed for t in tracker.update(scan, (0.0, 0.0, 0.0))) for scan in scans)
    assert confirmed > 0


def test_a_person_walking_past_is_still_tracked(drive: tuple[list[Scan], np.ndarray]) -> None:
    scans, truth = drive
    from tests.people.scenes import legs_of

    caster = DDACaster(_room(), GEOMETRY.max_range)
    tracker = PeopleTracker(rng=np.random.default_rng(0), pose_source=ScanMatchedPoses())
    seen = 0
    for k, scan in enumerate(scans):
        person = (4.0 + 0.08 * k, 5.5)  # walking at 0.8 m/s along +x
        legs = np.array([c[:2] for c in legs_of(*person, 0.0, 0.9 * k)])
        r = caster.cast_with_circles(
            truth[k : k + 1], GEOMETRY.angles, np.r_[POSTS, legs], np.full(len(POSTS) + 2, 0.06)
        )
        live = Scan(scan.timestamp, r[0].astype(np.float64), GEOMETRY)
        seen += any(t.confirmed for t in tracker.update(live))
    assert seen > len(scans) // 2


def test_beams_ending_on_a_tracked_person_stay_out_of_the_map(drive: tuple[list[Scan], np.ndarray]) -> None:
    # A person standing at the first post (as the tracker would give it) is not written into the
    # map; the other posts are.
    scans, truth = drive
    # The world frame of the poses starts at the first scan: the posts in it.
    posts = transform_points(invert(truth[0]), POSTS[[0, 2]])

    def on_map(people: np.ndarray | None) -> list[bool]:
        ego = ScanMatchedPoses()
        for scan in scans[:10]:
            ego.integrate(scan, ego.match(scan), people)
        return ego.on_map(posts).tolist()

    assert on_map(None) == [True, True]
    assert on_map(posts[:1]) == [False, True]


def test_matched_steps_of_a_plausible_drive_pass_the_check(drive: tuple[list[Scan], np.ndarray]) -> None:
    scans, _ = drive
    ego = ScanMatchedPoses()
    for scan in scans[:30]:
        pose = ego.match(scan)
        assert ego.implausible() is None
        ego.integrate(scan, pose)


def test_a_step_too_fast_for_the_time_between_scans_is_implausible(
    drive: tuple[list[Scan], np.ndarray],
) -> None:
    import dataclasses

    scans, _ = drive
    # The same 0.5 m/s drive stamped ten times faster: 5 cm in 10 ms is 5 m/s, no robot's step.
    fast = [dataclasses.replace(s, timestamp=s.timestamp / 10.0) for s in scans[:10]]
    ego = ScanMatchedPoses()
    reasons = []
    for scan in fast:
        pose = ego.match(scan)
        reasons.append(ego.implausible())
        ego.integrate(scan, pose)
    assert reasons[0] is None
    assert any(r is not None and "m/s" in r for r in reasons)


def _first_inconsistency(scans: list[Scan]) -> int | None:
    import dataclasses

    ego = ScanMatchedPoses()
    for k, recorded in enumerate(scans):
        scan = dataclasses.replace(recorded, odom=None)
        pose = ego.match(scan)
        if ego.implausible() is not None:
            return k
        ego.integrate(scan, pose)
    return None


def test_scan_matching_that_loses_its_way_is_caught(shared_data: Path) -> None:
    from tourbot.io import load_log

    # The FHW tour, scans 4 s apart, matched without its odometry: the matcher loses its way
    # (metres off the reference within 15 scans) and the scans stop fitting the map.
    log = load_log(shared_data / "carmen" / "fhw-corrected.log.gz")
    caught = _first_inconsistency(log.scans[:60])
    assert caught is not None
    assert caught < 40


def test_scan_matching_of_a_standing_laser_among_people_passes(shared_data: Path) -> None:
    from tourbot.io.rosbag import read_bag

    log = read_bag(shared_data / "leg_tracker" / "positive_1.bag", scan_topic="right_scan")
    assert _first_inconsistency(log.scans) is None


# A robot with three lasers of 240 degrees (front, left, rear: none sees all around), each a few
# hundredths of a second after the other, as on negative_2.bag.
MOUNTS = {"front": (0.3, 0.0, 0.0), "left": (0.0, 0.25, math.pi / 2), "rear": (-0.4, 0.0, math.pi)}
_DELAYS = {"front": 0.0, "left": 0.03, "rear": 0.06}
_WIDE = LaserGeometry(
    num_beams=481, angle_min=-2.0 * math.pi / 3, angle_increment=4.0 * math.pi / 3 / 480, max_range=20.0
)


def _robot_at(t: np.ndarray) -> np.ndarray:
    """Still for 1 s, then an arc at 0.5 m/s turning at 0.25 rad/s."""
    moving = np.maximum(np.asarray(t, dtype=np.float64) - 1.0, 0.0)
    heading = 0.2 + 0.25 * moving
    x = 2.0 + 2.0 * (np.sin(heading) - math.sin(0.2))
    y = 4.0 - 2.0 * (np.cos(heading) - math.cos(0.2))
    return np.stack([x, y, heading], -1)


def three_lasers(
    scans: int = 80, geometry: LaserGeometry = _WIDE
) -> tuple[dict[str, list[Scan]], tuple[np.ndarray, np.ndarray]]:
    """The scans of each laser (no mount in their geometry: no tf) and the robot's true path."""
    rng = np.random.default_rng(4)
    caster = DDACaster(_room(), geometry.max_range)
    base = np.arange(scans) * 0.1
    streams: dict[str, list[Scan]] = {}
    for name, mount in MOUNTS.items():
        t = base + _DELAYS[name]
        lasers = np.array([compose(p, mount) for p in _robot_at(t)])
        ranges = caster.cast_with_circles(lasers, geometry.angles, POSTS, np.full(len(POSTS), 0.05))
        streams[name] = [
            Scan(float(tk), r.astype(np.float64) + rng.normal(0.0, 0.01, r.shape), geometry, sensor=name)
            for tk, r in zip(t, ranges, strict=True)
        ]
    return streams, (base, _robot_at(base))


@pytest.fixture(scope="module")
def robot() -> tuple[dict[str, list[Scan]], tuple[np.ndarray, np.ndarray]]:
    from tourbot.mapping.mounts import mount_lasers

    streams, truth = three_lasers()
    mounted, _ = mount_lasers(streams, "front")
    return mounted, truth


def test_three_lasers_on_one_map_follow_the_robot(
    robot: tuple[dict[str, list[Scan]], tuple[np.ndarray, np.ndarray]],
) -> None:
    from tourbot.mapping.ego_motion import path_disagreement

    lasers, (times, truth) = robot
    ego = ScanMatchedPoses(companions=[*lasers["left"], *lasers["rear"]])
    tracker = PeopleTracker(rng=np.random.default_rng(0), pose_source=ego)
    confirmed = 0
    for scan in lasers["front"]:
        confirmed += sum(t.confirmed for t in tracker.update(scan))
        assert ego.implausible() is None
    # the robot frame is the front laser's (its mount estimated as the origin)
    front = np.array([compose(p, MOUNTS["front"]) for p in truth])
    t, poses = ego.path()
    assert len(t) == len(lasers["front"])
    _, worst, heading = path_disagreement(t, poses, times, front)
    assert worst < 0.1
    assert heading < math.radians(2.0)
    assert set(ego.mean_fit()) == {"front", "left", "rear"}
    assert confirmed == 0  # the posts stand still


def test_the_lasers_agree_alone_and_all_but_one(
    robot: tuple[dict[str, list[Scan]], tuple[np.ndarray, np.ndarray]],
) -> None:
    from tourbot.mapping.ego_motion import laser_agreement

    lasers, _ = robot
    ego = ScanMatchedPoses(companions=[*lasers["left"], *lasers["rear"]])
    for scan in lasers["front"]:
        ego.integrate(scan, ego.match(scan))
    rows = laser_agreement(lasers, ego.path())
    assert [r.lasers for r in rows] == [
        ("front",),
        ("left",),
        ("rear",),
        ("left", "rear"),
        ("front", "rear"),
        ("front", "left"),
    ]
    for row in rows:
        assert row.length > 3.0  # the robot drove about 3.5 m
        assert row.max_off < 0.2


def test_a_laser_whose_mount_is_wrong_breaks_the_agreement(
    robot: tuple[dict[str, list[Scan]], tuple[np.ndarray, np.ndarray]],
) -> None:
    import dataclasses

    from tourbot.mapping.ego_motion import laser_agreement

    lasers, _ = robot
    # the rear laser believed turned by 10 degrees: it drags the shared path off (its scans fit the
    # map only at the wrong pose), and neither it alone nor the others agree with that path
    wrong = dict(lasers)
    g = lasers["rear"][0].geometry
    bad = dataclasses.replace(g, offset=(g.offset[0], g.offset[1], g.offset[2] + math.radians(10.0)))
    wrong["rear"] = [dataclasses.replace(s, geometry=bad) for s in lasers["rear"]]
    ego = ScanMatchedPoses(companions=[*wrong["left"], *wrong["rear"]])
    for scan in wrong["front"]:
        ego.integrate(scan, ego.match(scan))
    rows = {r.lasers: r for r in laser_agreement(wrong, ego.path())}
    assert all(r.max_off > 0.3 for r in rows.values())  # all under 0.2 m with the right mounts


def test_the_three_lasers_of_a_driving_robot_agree_on_one_map(shared_data: Path) -> None:
    from tourbot.mapping.ego_motion import laser_agreement, path_length
    from tourbot.mapping.mounts import bag_lasers

    # negative_2.bag: a robot driving about 35 m with no odometry. Each laser alone finds a path
    # up to 1-2 m off the others' (before: 35.1, 34.9 and 36.9 m long in one frame, three steps of
    # 4-6 m/s on the right laser); on one map the lasers give one path, and any two of them the same.
    lasers, _ = bag_lasers(shared_data / "leg_tracker" / "negative_2.bag", "/rear_scan")
    ego = ScanMatchedPoses(companions=[*lasers["/left_scan"], *lasers["/right_scan"]])
    for scan in lasers["/rear_scan"]:
        ego.integrate(scan, ego.match(scan))
        assert ego.implausible() is None
    times, poses = ego.path()
    assert 30.0 < path_length(poses) < 40.0
    steps = np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1) / np.diff(times)
    assert steps.max() < 1.5
    pairs = [r for r in laser_agreement(lasers, (times, poses)) if len(r.lasers) == 2]
    assert len(pairs) == 3
    assert all(r.max_off < 0.3 and r.implausible == 0 for r in pairs)
