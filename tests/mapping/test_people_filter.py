from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.mapping.confirmation import ConfirmationParams
from tourbot.mapping.consistency import ConsistencyParams
from tourbot.mapping.incremental import IncrementalMapper
from tourbot.mapping.people_filter import (
    DEFAULT_MODE,
    FILTER_MODES,
    FarBlobParams,
    PeopleFilteredMapper,
    PeopleFilterParams,
    PeopleMappingConfig,
    hit_probability,
    in_boxes,
    person_beams,
)
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.raycast import DDACaster
from tourbot.metrics import relative_pose_error
from tourbot.people.sjpdaf import PeopleTracker, SJPDAFConfig
from tourbot.records import LaserGeometry, RobotLog, Scan

PAPER = PeopleFilterParams.paper()
BLOBS = replace(PAPER, free_sectors=True, far_blobs=FarBlobParams())  # the far blobs without the map's checks


def test_hit_probability_of_one_person() -> None:
    rng = np.random.default_rng(0)
    samples = rng.normal([2.0, 3.0], 0.03, (300, 2))
    p = hit_probability([samples], np.array([[2.0, 3.0], [2.2, 3.0], [3.0, 3.0]]))
    assert p[0] > 0.95
    assert p[1] > 0.5
    assert p[2] == 0.0


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), people=st.integers(0, 4))
def test_hit_probability_combines_people_as_eq_10(seed: int, people: int) -> None:
    rng = np.random.default_rng(seed)
    sets = [
        np.c_[rng.normal(rng.uniform(0, 3, 2), rng.uniform(0.02, 0.3), (50, 2)), np.zeros((50, 2))]
        for _ in range(people)
    ]
    pts = rng.uniform(-0.5, 3.5, (40, 2))
    both = hit_probability(sets, pts)
    assert np.all((both >= 0) & (both <= 1))
    each = [hit_probability([s], pts) for s in sets]
    expected = 1.0 - np.prod([1.0 - e for e in each], axis=0) if each else np.zeros(len(pts))
    assert np.allclose(both, expected)


def test_in_boxes() -> None:
    pts = np.array([[0.0, 0.0], [1.0, 1.0], [0.44, -0.44]])
    assert in_boxes(pts, np.array([[0.0, 0.0]]), 0.45).tolist() == [True, False, True]
    assert not in_boxes(pts, np.zeros((0, 2)), 0.45).any()


def test_existence_scales_a_tentative_persons_hit_probability() -> None:
    rng = np.random.default_rng(1)
    samples = rng.normal([1.0, 1.0], 0.05, (200, 2))
    pts = np.array([[1.0, 1.0], [1.1, 0.9]])
    full = hit_probability([samples], pts)
    third = hit_probability([samples], pts, existence=[1 / 3])
    assert np.allclose(third, full / 3)
    assert np.all(hit_probability([samples], pts, existence=[0.0]) == 0.0)


def test_a_beam_that_passed_the_person_is_kept() -> None:
    person = np.array([[3.0, 0.0]])
    ends = np.array([[2.9, 0.1], [3.3, 0.05], [3.1, 0.2], [3.0, 1.0]])  # leg, wall behind, leg, aside
    kept = person_beams(ends, np.zeros(2), person, np.array([0.3]), 0.2)
    assert kept.tolist() == [True, False, True, False]
    # without the range test, the wall behind the visitor would be lost too
    assert in_boxes(ends, person, 0.3).tolist() == [True, True, True, False]


def _walker_log(hall: OccupancyGrid, n: int = 70) -> tuple[RobotLog, np.ndarray]:
    """The robot stands still while a visitor walks up, stands a while in view, and walks on."""
    geom = LaserGeometry(361, -np.pi / 2, np.pi / 360, 30.0)
    caster = DDACaster(hall, geom.max_range)
    robot = np.array([10.5, 8.0, -np.pi / 2])
    scans, people = [], []
    for i in range(n):
        walked = min(i, 20) + max(i - 50, 0)  # stands still from scan 20 to 50
        centre = np.array([13.0 - 0.08 * walked, 6.0])
        swing = 0.12 * np.sin(0.8 * walked)
        legs = np.array([[centre[0] + swing, centre[1] + 0.1], [centre[0] - swing, centre[1] - 0.1]])
        ranges = caster.cast_with_circles(robot[None], geom.angles, legs, np.full(2, 0.06))[0]
        scans.append(
            Scan(0.1 * i, ranges.astype(np.float64), geom, odom=tuple(robot), reference=tuple(robot))
        )
        people.append(centre)
    return RobotLog("walker", scans), np.array(people)


def test_people_are_left_out_of_the_map(hall: OccupancyGrid) -> None:
    log, people = _walker_log(hall)
    robot = log.reference_poses[0]
    plain = IncrementalMapper(start=robot)
    filtered = PeopleFilteredMapper.create(
        PeopleMappingConfig(filter=PeopleFilterParams.paper()), start=robot, seed=1
    )
    for scan in log.scans:
        plain.integrate(scan, robot)
        filtered.add_scan(scan, pose=robot)
    filtered.finish()
    assert filtered.removed_beams > 0

    walls = hall.cell_to_world(np.argwhere(hall.occupied()))

    def occupied_near_path(grid: OccupancyGrid) -> int:
        """Occupied cells near the walker's path and away from the hall's walls."""
        pts = grid.cell_to_world(np.argwhere(grid.occupied()))
        d = np.min(np.linalg.norm(pts[:, None, :] - people[None, :, :], axis=2), axis=1)
        w = np.min(np.linalg.norm(pts[:, None, :] - walls[None, ::4, :], axis=2), axis=1)
        return int(np.sum((d < 0.3) & (w > 0.15)))

    before = occupied_near_path(plain.grid())
    after = occupied_near_path(filtered.mapper.grid())
    assert before > 0
    assert after < 0.5 * before


def test_a_visitor_standing_where_the_floor_was_seen_free_is_left_out(hall: OccupancyGrid) -> None:
    """Without any confirmed track (the tracker here never confirms), the person features of a
    scan that stand where the map has seen free floor are people: a visitor who walks up and then
    stands still is not mapped, while the walls behind stay."""
    log, people = _walker_log(hall)
    robot = log.reference_poses[0]
    never = PeopleTracker(SJPDAFConfig(confirm_existence=0.99999), rng=np.random.default_rng(0))
    filtered = PeopleFilteredMapper.create(
        PeopleMappingConfig(filter=PeopleFilterParams.paper()), start=robot, tracker=never
    )
    plain = IncrementalMapper(start=robot)
    for scan in log.scans:
        plain.integrate(scan, robot)
        filtered.add_scan(scan, pose=robot)
    filtered.finish()
    standing = people[35]  # stands still from scan 20 to 50

    def near_person(grid: OccupancyGrid) -> int:
        pts = grid.cell_to_world(np.argwhere(grid.occupied()))
        return int(np.sum(np.linalg.norm(pts - standing, axis=1) < 0.3))

    assert near_person(plain.grid()) > 0
    assert near_person(filtered.mapper.grid()) == 0
    walls_plain = int((plain.grid().occupied() & hall_walls(plain.grid(), hall)).sum())
    walls_kept = int((filtered.mapper.grid().occupied() & hall_walls(plain.grid(), hall)).sum())
    assert walls_kept >= 0.99 * walls_plain


def hall_walls(grid: OccupancyGrid, hall: OccupancyGrid) -> np.ndarray:
    """Cells of ``grid`` that are occupied cells of the hall itself."""
    cells = hall.world_to_cell(grid.cell_to_world(np.argwhere(np.ones(grid.prob.shape, bool))))
    ok = hall.inside(cells)
    out = np.zeros(grid.prob.size, bool)
    out[ok] = hall.occupied()[cells[ok, 0], cells[ok, 1]]
    return out.reshape(grid.prob.shape)


def test_people_filtered_slam_tracks_like_plain_slam_without_people(hall_log: RobotLog) -> None:
    start = hall_log.reference_poses[0]
    plain = IncrementalMapper(start=start)
    filtered = PeopleFilteredMapper.create(
        PeopleMappingConfig(filter=PeopleFilterParams.paper()), start=start
    )
    for scan in hall_log.scans[:60]:
        plain.add_scan(scan)
        filtered.add_scan(scan)
    filtered.finish()
    ref = hall_log.reference_poses[:60]
    a = relative_pose_error(np.asarray(plain.poses), ref).trans_mean
    b = relative_pose_error(np.asarray(filtered.mapper.poses), ref).trans_mean
    assert b < 1.5 * a + 0.005
    assert filtered.mapper.grid().occupied().sum() > 0.8 * plain.grid().occupied().sum()


def test_the_map_only_rules_leave_the_alignment_alone(hall_log: RobotLog) -> None:
    """The far blobs act on the returned map only, and the checks on the finished map: scans are
    aligned with the tracks and person features judged against a map without them, so the path of
    the default mode is that of the paper's filter with free sectors (the hall's pillars, seen from
    afar, are blobs that the map rule holds back until seen repeatedly), while the maps differ."""
    start = hall_log.reference_poses[0]
    sectors = replace(PeopleFilterParams.paper(), free_sectors=True)
    runs = {}
    for name, params in (("sectors", sectors), ("default", PeopleFilterParams())):
        filtered = PeopleFilteredMapper.create(PeopleMappingConfig(filter=params), start=start)
        for scan in hall_log.scans[:40]:
            filtered.add_scan(scan)
        filtered.finish()
        runs[name] = filtered
    assert np.array_equal(np.asarray(runs["default"].mapper.poses), np.asarray(runs["sectors"].mapper.poses))
    assert runs["default"].removed_beams > runs["sectors"].removed_beams
    assert not np.array_equal(runs["default"].grid().prob, runs["sectors"].grid().prob)


def test_the_two_modes() -> None:
    """The default (``checked``) is the dataclass's default; ``paper`` has none of the rules beyond
    the paper; the tracker's share of the parameters is the same in both."""
    assert FILTER_MODES == (DEFAULT_MODE, "paper")
    assert PeopleFilterParams.mode(DEFAULT_MODE) == PeopleFilterParams()
    paper = PeopleFilterParams.mode("paper")
    assert paper == PeopleFilterParams.paper()
    beyond = ("free_sectors", "far_blobs", "consistency", "confirmation")
    assert not any(getattr(paper, name) for name in beyond)
    assert all(getattr(PeopleFilterParams(), name) for name in beyond)
    assert replace(PeopleFilterParams(), **{n: getattr(paper, n) for n in beyond}) == paper
    assert PeopleFilteredMapper.create().mapper.params.free_sectors
    assert not PeopleFilteredMapper.create(PeopleMappingConfig(filter=paper)).mapper.params.free_sectors
    with pytest.raises(ValueError, match="unknown people filter mode"):
        PeopleFilterParams.mode("joint")


def _pole_then_visitor(poles: int) -> list[Scan]:
    """A wall 12 m ahead with a pole at 8 m (beams 10-11) in ``poles`` scans, then one scan with a
    visitor at 9 m as well (beams 40-41), all from the same pose."""
    geom = LaserGeometry(61, -math.radians(30), math.radians(1), 30.0)
    wall = 12.0 / np.cos(geom.angles)
    pole = wall.copy()
    pole[10:12] = 8.0
    visitor = pole.copy()
    visitor[40:42] = 9.0
    return [Scan(float(t), r, geom, odom=(0.0, 0.0, 0.0)) for t, r in enumerate([pole] * poles + [visitor])]


def test_a_far_visitor_is_left_out_as_a_blob_but_not_a_pole_seen_before() -> None:
    """A visitor 9 m away in front of a wall is one or two beams: no leg feature. The blob mode
    leaves those beams out; a blob seen at one spot scan after scan (a pole) is mapped from its
    fourth scan on."""
    scans = _pole_then_visitor(4)
    left = {}
    for mode, params in (("paper", PAPER), ("blobs", BLOBS)):
        filtered = PeopleFilteredMapper.create(PeopleMappingConfig(filter=params), start=np.zeros(3))
        for scan in scans:
            filtered.add_scan(scan, pose=np.zeros(3))
        filtered.finish()
        left[mode] = np.asarray(filtered.left_out)
    assert not left["paper"].any()
    assert left["blobs"][4, 40:42].all()  # the visitor
    assert left["blobs"][:3, 10:12].all()  # the pole the first three times
    assert not left["blobs"][3:, 10:12].any()  # ... then it is static
    assert left["blobs"].sum() == 8


def test_the_confirmed_mode_gives_back_a_pole_other_scans_confirm_but_not_a_visitor() -> None:
    """The pole of the test above is left out as a blob the first three times, then mapped; the
    kept beams of the later scans end where those left-out beams ended, so the finished map gets
    their hits back. The visitor, seen in one scan where no other scan's kept beam ended, is not
    given back."""
    scans = _pole_then_visitor(8)
    geom = scans[0].geometry
    runs = {}
    confirming = replace(
        BLOBS,
        confirmation=ConfirmationParams(),
        consistency=ConsistencyParams(ring_free=0.4, group_member_cells=6),
    )
    for mode, params in (("blobs", BLOBS), ("confirmed", confirming)):
        filtered = PeopleFilteredMapper.create(PeopleMappingConfig(filter=params), start=np.zeros(3))
        for scan in scans:
            filtered.add_scan(scan, pose=np.zeros(3))
        filtered.finish()
        runs[mode] = (filtered, filtered.grid())
    blobs, confirmed = runs["blobs"], runs["confirmed"]
    assert np.array_equal(np.asarray(blobs[0].left_out), np.asarray(confirmed[0].left_out))
    assert confirmed[0].restored_beams == 6  # the pole's two beams in each of the first three scans
    assert blobs[0].restored_beams == 0
    ends = 8.0 * np.stack([np.cos(geom.angles[10:12]), np.sin(geom.angles[10:12])], axis=1)
    cells = blobs[1].world_to_cell(ends)
    assert (confirmed[1].prob[cells[:, 0], cells[:, 1]] > blobs[1].prob[cells[:, 0], cells[:, 1]]).all()
    spots = 9.0 * np.stack([np.cos(geom.angles[40:42]), np.sin(geom.angles[40:42])], axis=1)
    cells = confirmed[1].world_to_cell(spots)
    assert not confirmed[1].occupied()[cells[:, 0], cells[:, 1]].any()


def test_the_consistent_mode_clears_a_visitor_the_finished_map_sees_floor_around() -> None:
    """One beam on a visitor 3 m away, in two scans: no leg pair, no far blob, so ``blobs`` maps
    it. An earlier scan from elsewhere saw the floor around and behind the spot: ``consistent``
    clears that speck and nothing else."""
    geom = LaserGeometry(61, -math.radians(30), math.radians(1), 30.0)
    wall = 6.0 / np.cos(geom.angles)
    visitor = wall.copy()
    visitor[30] = 3.0
    poses = [np.zeros(3), np.array([0.0, 0.52, 0.0]), np.array([0.0, 0.52, 0.0])]
    scans = [Scan(float(t), r, geom, odom=(0.0, 0.0, 0.0)) for t, r in enumerate([wall, visitor, visitor])]
    grids = {}
    for mode, params in (("blobs", BLOBS), ("consistent", replace(BLOBS, consistency=ConsistencyParams()))):
        filtered = PeopleFilteredMapper.create(PeopleMappingConfig(filter=params), start=np.zeros(3))
        for scan, pose in zip(scans, poses, strict=True):
            filtered.add_scan(scan, pose=pose)
        filtered.finish()
        assert not np.asarray(filtered.left_out).any()
        grids[mode] = filtered.grid()
        assert filtered.cleared_cells == (mode == "consistent")
    row, col = grids["blobs"].world_to_cell(np.array([3.0, 0.52]))
    assert grids["blobs"].occupied()[row, col]
    assert not grids["consistent"].occupied()[row, col]
    changed = grids["blobs"].occupied() != grids["consistent"].occupied()
    assert changed.sum() == 1


def test_the_kept_mode_gives_back_a_post_face_the_map_holds_on_both_sides_but_not_a_visitor() -> None:
    """A post's flat face 0.4 m wide (five beams), 8 m ahead in front of a wall at 12 m, is a far
    blob: left out in the first scans, then mapped; then a visitor at 9 m in one scan. Fewer than
    four other scans kept beams on the face, so ``far`` gives nothing back; ``kept`` gives back
    the left-out beams whose end has the face the map holds on both sides (not those at the
    face's edges), and not the visitor's, which has nothing around it."""
    geom = LaserGeometry(121, -math.radians(30), math.radians(0.5), 30.0)
    wall = 12.0 / np.cos(geom.angles)
    post = wall.copy()
    face = np.abs(8.0 * np.tan(geom.angles)) <= 0.2
    post[face] = 8.0 / np.cos(geom.angles[face])
    visitor = post.copy()
    visitor[100:102] = 9.0
    scans = [Scan(float(t), r, geom, odom=(0.0, 0.0, 0.0)) for t, r in enumerate([post] * 3 + [visitor])]
    runs = {}
    no_lines = replace(PeopleFilterParams(), confirmation=ConfirmationParams())  # no line of structure
    for mode, params in (("far", no_lines), ("kept", PeopleFilterParams())):
        filtered = PeopleFilteredMapper.create(PeopleMappingConfig(filter=params), start=np.zeros(3))
        for scan in scans:
            filtered.add_scan(scan, pose=np.zeros(3))
        filtered.finish()
        runs[mode] = (filtered, filtered.grid())
    far, kept = runs["far"], runs["kept"]
    left = np.asarray(far[0].left_out)
    assert np.array_equal(left, np.asarray(kept[0].left_out))
    assert left[0, face].all()  # the face, left out as a blob
    assert not left[2:, face].any()  # ... then mapped
    assert left[3, 100:102].all()  # the visitor
    assert far[0].restored_beams == 0
    assert 0 < kept[0].restored_beams < left[:, face].sum()
    inner = np.flatnonzero(face)[1:-1]
    ends = (8.0 / np.cos(geom.angles[inner]))[:, None] * np.stack(
        [np.cos(geom.angles[inner]), np.sin(geom.angles[inner])], axis=1
    )
    cells = far[1].world_to_cell(ends)
    assert (kept[1].prob[cells[:, 0], cells[:, 1]] > far[1].prob[cells[:, 0], cells[:, 1]]).all()
    spots = 9.0 * np.stack([np.cos(geom.angles[100:102]), np.sin(geom.angles[100:102])], axis=1)
    cells = kept[1].world_to_cell(spots)
    assert not kept[1].occupied()[cells[:, 0], cells[:, 1]].any()
