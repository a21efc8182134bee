"""The crowd of visitors: kernels against their references, and the behaviour the paper needs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from tourbot.maps.grid import OccupancyGrid
from tourbot.sim.crowd import (
    Crowd,
    CrowdConfig,
    CrowdError,
    line_of_sight,
    line_of_sight_reference,
    move_people,
    move_people_reference,
    social_forces,
    social_forces_reference,
    steer,
    steer_reference,
)


def _room(
    width: float = 16.0, height: float = 10.0, res: float = 0.1, wall_at: float | None = None
) -> OccupancyGrid:
    """A walled room; optionally an interior wall at x = ``wall_at`` with no opening."""
    rows, cols = round(height / res), round(width / res)
    prob = np.zeros((rows, cols), dtype=np.float32)
    prob[:2, :] = prob[-2:, :] = prob[:, :2] = prob[:, -2:] = 1.0
    if wall_at is not None:
        c = round(wall_at / res)
        prob[:, c : c + 2] = 1.0
    return OccupancyGrid(prob, res, (0.0, 0.0, 0.0))


@settings(max_examples=40, deadline=None)
@given(
    arrays(np.float64, (12, 2), elements=st.floats(-3.0, 3.0)),
    arrays(np.float64, (12,), elements=st.floats(0.05, 0.4)),
    arrays(np.float64, (12,), elements=st.floats(-4.0, 4.0)),
    arrays(np.bool_, (12,), elements=st.booleans()),
    st.floats(0.0, 1.0),
)
def test_social_forces_match_reference(
    pos: np.ndarray, radius: np.ndarray, heading: np.ndarray, standing: np.ndarray, anisotropy: float
) -> None:
    # Coincident people get an arbitrary push in the kernel; the reference leaves them out.
    d = np.linalg.norm(pos[:, None] - pos[None], axis=-1) + np.eye(len(pos))
    if (d < 1e-6).any():
        return
    np.testing.assert_allclose(
        social_forces(pos, radius, heading, standing, 2.1, 0.3, anisotropy),
        social_forces_reference(pos, radius, heading, standing, 2.1, 0.3, anisotropy),
        rtol=1e-9,
        atol=1e-9,
    )


def test_social_forces_push_apart_and_cancel() -> None:
    pos = np.array([[0.0, 0.0], [0.5, 0.0]])
    walking = np.zeros(2, dtype=bool)
    f = social_forces(pos, np.array([0.25, 0.25]), np.zeros(2), walking, 2.1, 0.3, 1.0)
    assert f[0, 0] < 0 < f[1, 0]
    np.testing.assert_allclose(f.sum(axis=0), 0.0, atol=1e-12)


def test_standing_people_do_not_push_each_other_until_they_touch() -> None:
    radii, heading = np.full(3, 0.25), np.zeros(3)
    standing = np.array([True, True, False])
    # Two standing 0.6 m apart: no force; a walker 0.6 m from a standing one: pushed both ways.
    pos = np.array([[0.0, 0.0], [0.6, 0.0], [0.6, 5.0]])
    f = social_forces(pos, radii, heading, standing, 2.1, 0.3, 1.0)
    np.testing.assert_array_equal(f[:2], 0.0)
    pos = np.array([[0.0, 0.0], [0.0, 5.0], [0.6, 0.0]])
    f = social_forces(pos, radii, heading, standing, 2.1, 0.3, 1.0)
    assert f[0, 0] < 0.0 < f[2, 0]
    # Touching standing people push each other apart.
    pos = np.array([[0.0, 0.0], [0.4, 0.0], [0.0, 5.0]])
    f = social_forces(pos, radii, heading, standing, 2.1, 0.3, 1.0)
    assert f[0, 0] < 0.0 < f[1, 0]


def test_social_forces_weaker_from_behind() -> None:
    """Both face +x: the one in front (index 1) has the other behind it and is pushed less."""
    pos = np.array([[0.0, 0.0], [0.6, 0.0]])
    f = social_forces(pos, np.array([0.25, 0.25]), np.zeros(2), np.zeros(2, dtype=bool), 2.1, 0.3, 0.3)
    assert f[0, 0] < 0 < f[1, 0]
    np.testing.assert_allclose(f[1, 0], 0.3 * -f[0, 0])


@settings(max_examples=40, deadline=None)
@given(
    arrays(np.bool_, (9, 11), elements=st.booleans()),
    arrays(np.float64, (6, 4), elements=st.floats(-0.5, 3.0)),
)
def test_line_of_sight_matches_reference(walkable: np.ndarray, ends: np.ndarray) -> None:
    a, b = ends[:, :2].copy(), ends[:, 2:].copy()
    np.testing.assert_array_equal(
        line_of_sight(walkable, 0.25, a, b), line_of_sight_reference(walkable, 0.25, a, b)
    )


def test_same_seed_same_crowd() -> None:
    grid = _room()
    cfg = CrowdConfig(num_people=30, robot_interest=0.5)

    def run(seed: int) -> np.ndarray:
        rng = np.random.default_rng(seed)
        crowd = Crowd(cfg, grid, rng, (8.0, 5.0, 0.0))
        for i in range(50):
            crowd.step(0.25, (8.0 + 0.01 * i, 5.0, 0.0), rng)
        return crowd.legs()[0]

    np.testing.assert_array_equal(run(3), run(3))
    assert not np.array_equal(run(3), run(4))


def test_people_stay_in_free_space_at_walking_speed() -> None:
    grid = _room(wall_at=8.0)
    cfg = CrowdConfig(num_people=60, robot_interest=0.5)
    rng = np.random.default_rng(0)
    robot = (4.0, 5.0, 0.0)
    crowd = Crowd(cfg, grid, rng, robot)
    left = crowd.positions[:, 0] < 8.0
    for _ in range(100):
        crowd.step(0.2, robot, rng)
        cells = grid.world_to_cell(crowd.positions)
        assert grid.free()[cells[:, 0], cells[:, 1]].all()
        assert np.linalg.norm(crowd.velocities, axis=1).max() <= cfg.speed_max + 1e-9
        assert np.linalg.norm(crowd.positions - robot[:2], axis=1).min() >= cfg.robot_radius
    # The closed interior wall is never crossed.
    np.testing.assert_array_equal(crowd.positions[:, 0] < 8.0, left)


def test_interest_draws_visitors_around_the_robot() -> None:
    grid = _room(24.0, 16.0)
    robot = (12.0, 8.0, 0.0)

    def near(interest: float) -> float:
        counts = []
        for seed in range(3):
            rng = np.random.default_rng(seed)
            crowd = Crowd(
                CrowdConfig(num_people=40, robot_interest=interest, interest_duration=1e6), grid, rng, robot
            )
            for _ in range(150):
                crowd.step(0.2, robot, rng)
            counts.append(int((np.linalg.norm(crowd.positions - robot[:2], axis=1) < 2.5).sum()))
        return float(np.mean(counts))

    drawn, indifferent = near(1.0), near(0.0)
    assert drawn >= 8
    assert drawn >= 2 * indifferent


def _settled_ring(seed: int) -> tuple[Crowd, tuple[float, float, float], np.random.Generator]:
    grid = _room(24.0, 16.0)
    robot = (12.0, 8.0, 0.0)
    rng = np.random.default_rng(seed)
    cfg = CrowdConfig(num_people=40, robot_interest=1.0, interest_duration=1e6, blocker_share=0.0)
    crowd = Crowd(cfg, grid, rng, robot)
    for _ in range(200):
        crowd.step(0.2, robot, rng)
    return crowd, robot, rng


def test_the_ring_at_the_robot_is_loose_and_in_front() -> None:
    crowd, robot, _ = _settled_ring(1)
    ring = crowd.positions[crowd.at_robot]
    assert len(ring) >= 6
    rel = ring - np.array(robot[:2])
    # In front (the robot faces +x) and no closer to each other than people who touch.
    assert np.mean(rel[:, 0] > 0.0) >= 0.8
    gaps = np.linalg.norm(ring[:, None] - ring[None], axis=-1) + 10 * np.eye(len(ring))
    assert gaps.min() >= 0.44
    # Not a lattice: the nearest-neighbour distances spread.
    nn = gaps.min(axis=1)
    assert np.ptp(nn) >= 0.2


def test_the_ring_steps_aside_and_follows_the_driving_robot() -> None:
    crowd, robot, rng = _settled_ring(4)
    x, y, th = robot
    members = crowd.at_robot.copy()

    def in_way(rel: np.ndarray) -> int:
        """People in the 0.9 m wide lane 0.5-2.5 m ahead of the robot (which faces +x)."""
        return int(np.sum((rel[:, 0] > 0.5) & (rel[:, 0] < 2.5) & (np.abs(rel[:, 1]) < 0.45)))

    assert in_way(crowd.positions[members] - np.array(robot[:2])) >= 2
    for k in range(1, 76):  # 7.5 s at 0.4 m/s along +x
        crowd.step(0.1, (x + 0.04 * k, y, th), rng)
    rx = x + 0.04 * 75
    pos = crowd.positions
    still = members & crowd.at_robot
    assert still.sum() >= 4
    rel = pos[still] - np.array([rx, y])
    # They came along (within a few metres of the robot) ...
    assert np.median(np.linalg.norm(rel, axis=1)) <= 3.5
    # ... and keep out of its way: at most one (on the way out) in the lane ahead.
    assert in_way(rel) <= 1


def _two_rings(seed: int) -> tuple[Crowd, np.ndarray, np.random.Generator]:
    """Two robots of one museum, 14 m apart in a hall, each with visitors standing at it."""
    grid = _room(30.0, 14.0)
    robots = np.array([[4.0, 7.0, 0.0], [16.0, 7.0, 0.0]])
    rng = np.random.default_rng(seed)
    cfg = CrowdConfig(num_people=60, robot_interest=1.0, interest_duration=1e6, blocker_share=0.0)
    crowd = Crowd(cfg, grid, rng, robots)
    for _ in range(200):
        crowd.step(0.2, robots, rng)
    return crowd, robots, rng


def test_visitors_gather_at_every_robot_of_the_museum() -> None:
    crowd, robots, _ = _two_rings(2)
    at = crowd.robot_of
    for k, (x, y, _) in enumerate(robots):
        ring = crowd.positions[at == k]
        assert len(ring) >= 6, f"robot {k + 1}: {len(ring)} visitors at it"
        d = np.hypot(ring[:, 0] - x, ring[:, 1] - y)
        assert np.median(d) <= 3.5  # at this robot, not the other (12 m away)
        assert np.mean(ring[:, 0] > x) >= 0.7  # in front of it (both face +x)
    with pytest.raises(CrowdError, match="made with 2 robots stepped with 1"):
        crowd.step(0.1, robots[0], np.random.default_rng(0))


@pytest.mark.parametrize("driver", [0, 1])
def test_a_ring_steps_aside_for_either_robot_and_follows_it(driver: int) -> None:
    """Robot ``driver + 1`` drives 6 m through its ring while the other stands: its visitors step
    out of its lane and come along (the tour group); the other robot's ring stays where it was."""
    crowd, robots, rng = _two_rings(3)  # two or more in each robot's lane
    other = 1 - driver
    at = crowd.robot_of
    members, others = at == driver, at == other
    x, y, th = robots[driver]

    def in_way(rel: np.ndarray) -> int:
        """People in the 0.9 m wide lane 0.5-2.5 m ahead of the driving robot (facing +x)."""
        return int(np.sum((rel[:, 0] > 0.5) & (rel[:, 0] < 2.5) & (np.abs(rel[:, 1]) < 0.45)))

    assert in_way(crowd.positions[members] - robots[driver, :2]) >= 2
    stay = crowd.positions[others].copy()
    poses = robots.copy()
    for k in range(1, 151):  # 15 s at 0.4 m/s along +x
        poses[driver] = (x + 0.04 * k, y, th)
        crowd.step(0.1, poses, rng)
    still = members & (crowd.robot_of == driver)
    assert still.sum() >= 4
    rel = crowd.positions[still] - poses[driver, :2]
    assert np.median(np.linalg.norm(rel, axis=1)) <= 3.5  # they came along ...
    assert in_way(rel) <= 1  # ... and keep out of its lane
    kept = others & (crowd.robot_of == other)
    moved = np.linalg.norm(crowd.positions[kept] - stay[kept[others]], axis=1)
    assert np.median(moved) <= 0.5  # the standing robot's ring stands


def test_a_group_follows_the_second_robot_on_its_tour() -> None:
    """A group at the second robot walks with it along a 10 m tour leg with a turn."""
    crowd, robots, rng = _two_rings(6)
    lead = crowd.groups
    at = crowd.robot_of
    in_group = np.flatnonzero((at == 1) & (np.bincount(lead, minlength=len(lead))[lead] >= 2))
    assert len(in_group) >= 2, "no group of two or more at the second robot"
    poses = robots.copy()
    path = [(16.0 + 0.05 * k, 7.0, 0.0) for k in range(1, 121)]  # 6 m east at 0.5 m/s ...
    path += [(22.0, 7.0 - 0.05 * k, -np.pi / 2) for k in range(1, 81)]  # ... then 4 m south
    gaps = []
    for pose in path:
        poses[1] = pose
        crowd.step(0.1, poses, rng)
        d = np.linalg.norm(crowd.positions[in_group] - np.array(pose[:2]), axis=1)
        gaps.append(d[crowd.robot_of[in_group] == 1])
    stayed = crowd.robot_of[in_group] == 1
    assert stayed.mean() >= 0.5  # most of the group is still with it at the end
    final = np.concatenate(gaps[-10:])
    assert np.median(final) <= 3.5  # and near it: 10 m from where they stood
    start = np.linalg.norm(crowd.positions[in_group[stayed]] - robots[1, :2], axis=1)
    assert start.min() >= 5.0


def test_groups_walk_abreast() -> None:
    grid = _room(24.0, 16.0)
    rng = np.random.default_rng(3)
    crowd = Crowd(CrowdConfig(num_people=30, robot_interest=0.0), grid, rng, (1.0, 1.0, 0.0))
    lead = crowd.groups
    members = np.flatnonzero(lead != np.arange(crowd.num_people))
    assert len(members) >= 5
    close = []
    for _ in range(300):
        crowd.step(0.1, (1.0, 1.0, 0.0), rng)
        v = np.linalg.norm(crowd.velocities, axis=1)
        walking = members[(v[members] > 0.3) & (v[lead[members]] > 0.3)]
        d = np.linalg.norm(crowd.positions[walking] - crowd.positions[lead[walking]], axis=1)
        close.extend(d.tolist())
    assert np.median(close) <= 1.2


def test_legs_two_per_person_near_the_body() -> None:
    grid = _room()
    rng = np.random.default_rng(2)
    crowd = Crowd(CrowdConfig(num_people=10), grid, rng, (8.0, 5.0, 0.0))
    for _ in range(20):
        crowd.step(0.1, (8.0, 5.0, 0.0), rng)
    centres, radii = crowd.legs()
    assert centres.shape == (20, 2)
    assert radii.shape == (20,)
    body = np.repeat(crowd.positions, 2, axis=0)
    assert np.linalg.norm(centres - body, axis=1).max() <= 0.1 + 0.15 + 1e-9
    bodies, body_radii = Crowd(CrowdConfig(num_people=10, target="body"), grid, rng).circles()
    assert bodies.shape == (10, 2)
    assert body_radii.shape == (10,)


def test_bad_config_and_preset_are_errors() -> None:
    with pytest.raises(CrowdError, match="preset"):
        CrowdConfig.preset("rush-hour")
    with pytest.raises(CrowdError, match="speed"):
        CrowdConfig(speed_min=2.0, speed_max=1.0)
    peak, sparse = CrowdConfig.preset("peak"), CrowdConfig.preset("sparse")
    assert peak.density is not None
    assert sparse.density is not None
    assert peak.density > sparse.density
    assert peak.robot_interest > sparse.robot_interest


def test_density_sets_the_number_of_people() -> None:
    grid = _room(20.0, 10.0)
    crowd = Crowd(CrowdConfig(density=0.5), grid, np.random.default_rng(0), (10.0, 5.0, 0.0))
    # About 0.5 per square metre of the ~19.4 x 9.4 m walkable floor (walls 0.2 m, clearance 0.125 m).
    assert 85 <= crowd.num_people <= 97


def _world(seed: int, n: int) -> dict[str, np.ndarray]:
    """A random but valid state of ``n`` people in a 6 x 5 m room with a pillar."""
    rng = np.random.default_rng(seed)
    wall_dist = rng.uniform(0.0, 1.0, size=(50, 60))
    wall_dir = rng.normal(size=(50, 60, 2))
    wall_dir /= np.linalg.norm(wall_dir, axis=-1, keepdims=True)
    walkable = rng.random((20, 24)) < 0.8
    return {
        "pos": rng.uniform(0.0, 5.0, size=(n, 2)),
        "vel": rng.normal(0.0, 0.7, size=(n, 2)),
        "desired": rng.normal(0.0, 1.0, size=(n, 2)),
        "cap": rng.uniform(0.5, 1.5, size=n),
        "radii": rng.uniform(0.2, 0.35, size=n),
        "group": np.minimum(np.arange(n), rng.integers(0, n, size=n)),
        "phase": rng.uniform(0.0, 6.0, size=n),
        "heading": rng.uniform(-3.0, 3.0, size=n),
        "wall_dist": wall_dist,
        "wall_dir": wall_dir,
        "walkable": walkable,
        "fields": np.where(rng.random((2, 20, 24)) < 0.9, rng.uniform(0.0, 30.0, size=(2, 20, 24)), np.inf),
    }


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 25), st.floats(0.01, 0.2), st.integers(1, 3))
def test_move_people_matches_reference(seed: int, n: int, h: float, m: int) -> None:
    w = _world(seed, n)
    # the museum's robots, and the one each visitor stands at (-1: none)
    robots = np.random.default_rng(seed + 1).uniform(0.5, 5.5, size=(m, 2))
    facing = np.random.default_rng(seed + 2).integers(-1, m, size=n)
    params = np.array([0.5, 0.25, 2.0, 0.08, 10.0, 0.2, 0.4, 10.0, 0.2, 0.5, 1.3, 0.3])
    args = (
        w["pos"],
        w["vel"],
        w["desired"],
        w["cap"],
        w["radii"],
        w["group"],
        facing,
        w["phase"],
        w["heading"],
        w["wall_dist"],
        w["wall_dir"],
        0.1,
        w["walkable"],
        0.25,
        robots,
        params,
        h,
    )
    for got, want in zip(move_people(*args), move_people_reference(*args), strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-7, atol=1e-7)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 25))
def test_steer_matches_reference(seed: int, n: int) -> None:
    w = _world(seed, n)
    rng = np.random.default_rng(seed + 1)
    target = rng.uniform(0.0, 5.0, size=(n, 2))
    moving = rng.random(n) < 0.8
    in_view = rng.random(n) < 0.5
    field_index = rng.integers(-1, 2, size=n)
    speed = rng.uniform(0.5, 1.5, size=n)
    args = (w["pos"], target, moving, in_view, field_index, w["fields"], 0.25, speed, 0.5)
    np.testing.assert_allclose(steer(*args), steer_reference(*args), atol=1e-12)
