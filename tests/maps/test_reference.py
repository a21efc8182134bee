"""The reference map: the beam-tracing kernel against its numpy twin, a synthetic room, real logs."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.maps.grid import MapError
from tourbot.maps.reference import (
    ReferenceMapParams,
    build_reference_map,
    trace_beams,
    trace_beams_reference,
)
from tourbot.records import LaserGeometry, RobotLog, Scan

coord = st.floats(-3.0, 23.0, allow_nan=False)


@settings(max_examples=40, deadline=None)
@given(
    beams=st.lists(
        st.tuples(
            coord,
            coord,
            st.one_of(st.floats(-7.0, 7.0), st.sampled_from([math.pi, -math.pi, math.pi / 2, math.pi / 4])),
            st.floats(0.0, 15.0),
            st.booleans(),
        ),
        min_size=1,
        max_size=40,
    ),
    crossing=st.booleans(),
)
def test_kernel_matches_numpy_reference(
    beams: list[tuple[float, float, float, float, bool]], crossing: bool
) -> None:
    ox, oy, th, ln, hit = (np.array(c) for c in zip(*beams, strict=True))
    shape = (20, 17)
    fast = trace_beams(ox, oy, th, ln, hit.astype(bool), shape, crossing=crossing)
    slow = trace_beams_reference(ox, oy, th, ln, hit.astype(bool), shape, crossing=crossing)
    np.testing.assert_array_equal(fast[0], slow[0])
    np.testing.assert_array_equal(fast[1], slow[1])


def test_a_beam_along_a_grid_line_from_a_subnormal_hair_below_it_ends() -> None:
    # found by hypothesis: y = -5e-324 lies in row -1, a hair below the line y = 0, and the beam
    # runs along x (sin(-pi) snapped to 0); the walk used to take that line as crossed at once,
    # forever, without moving
    args = (np.array([5.697039760894983]), np.array([-5e-324]), np.array([-math.pi]), np.array([6.9]))
    for hit in (True, False):
        for crossing in (True, False):
            fast = trace_beams(*args, np.array([hit]), (20, 17), crossing=crossing)
            slow = trace_beams_reference(*args, np.array([hit]), (20, 17), crossing=crossing)
            np.testing.assert_array_equal(fast[0], slow[0])
            np.testing.assert_array_equal(fast[1], slow[1])


@pytest.mark.parametrize(
    ("corner", "theta"),
    [((0.5, 0.5), math.pi / 4), ((2.0, 3.0), 0.0), ((2.0, 3.0), math.pi), ((4.0, 4.0), -3 * math.pi / 4)],
)
def test_kernel_matches_reference_through_corners_and_along_grid_lines(
    corner: tuple[float, float], theta: float
) -> None:
    args = (np.array([corner[0]]), np.array([corner[1]]), np.array([theta]), np.array([3.3]))
    for hit in (True, False):
        fast = trace_beams(*args, np.array([hit]), (8, 8))
        slow = trace_beams_reference(*args, np.array([hit]), (8, 8))
        np.testing.assert_array_equal(fast[0], slow[0])
        np.testing.assert_array_equal(fast[1], slow[1])


def test_one_beam_along_a_row() -> None:
    """From the middle of cell 0 along +x, 3.3 cells: cells 0-2 free, hit at the crossing nearest."""
    o = np.array([0.5])
    hits, misses = trace_beams(o, o, np.array([0.0]), np.array([3.3]), np.array([True]), (1, 6))
    # crossings at 0.5, 1.5, 2.5, 3.5: 3.5 is nearest to 3.3, so the cell entered there (4) is hit
    np.testing.assert_array_equal(hits[0], [0, 0, 0, 0, 1, 0])
    np.testing.assert_array_equal(misses[0], [1, 1, 1, 1, 0, 0])
    hits, misses = trace_beams(
        o, o, np.array([0.0]), np.array([3.3]), np.array([True]), (1, 6), crossing=False
    )
    np.testing.assert_array_equal(hits[0], [0, 0, 0, 1, 0, 0])
    np.testing.assert_array_equal(misses[0], [1, 1, 1, 0, 0, 0])
    hits, misses = trace_beams(o, o, np.array([0.0]), np.array([3.3]), np.array([False]), (1, 6))
    np.testing.assert_array_equal(hits[0], [0] * 6)
    np.testing.assert_array_equal(misses[0], [1, 1, 1, 1, 0, 0])


def _room_log(people: bool = False) -> RobotLog:
    """A robot turning in place in the middle of a 6 m x 4 m room, optionally with a passer-by."""
    geometry = LaserGeometry(361, -math.pi, math.pi / 180, 20.0)
    scans = []
    for k in range(36):
        pose = (3.0 + 0.02 * k, 2.0, k * math.pi / 18)
        angles = pose[2] + geometry.angles
        c, s = np.cos(angles), np.sin(angles)
        with np.errstate(divide="ignore"):
            tx = np.where(c > 0, (6.0 - pose[0]) / c, np.where(c < 0, -pose[0] / c, np.inf))
            ty = np.where(s > 0, (4.0 - pose[1]) / s, np.where(s < 0, -pose[1] / s, np.inf))
        ranges = np.minimum(tx, ty)
        if people and k % 6 == 0:
            ranges[(np.abs(geometry.angles - 0.3) < 0.05)] = 1.0  # someone 1 m away, once in a while
        scans.append(Scan(float(k), ranges, geometry, pose, pose))
    return RobotLog("room", scans)


def test_room_map_has_walls_free_inside_and_unknown_outside() -> None:
    grid = build_reference_map(_room_log(), 0.05)
    walls = grid.world_to_cell(np.array([[6.0, 2.0], [0.0, 1.0], [3.0, 4.0], [1.5, 0.0]]))
    occupied = grid.occupied()
    assert all(occupied[r - 1 : r + 2, c - 1 : c + 2].any() for r, c in walls)
    # walls are one cell thick: nothing else is occupied
    assert occupied.sum() < 1.1 * 2 * (6.0 + 4.0) / 0.05
    inside = grid.world_to_cell(np.array([[3.0, 2.0], [1.0, 1.0], [5.0, 3.5]]))
    assert all(grid.free()[r, c] for r, c in inside)
    assert grid.unknown()[0, 0]  # the margin corner, beyond the walls


def test_a_passer_by_is_cleared() -> None:
    grid = build_reference_map(_room_log(people=True), 0.05)
    log = _room_log(people=True)
    # the person was 1 m from the robot in the beam at 0.3 rad, seen in 6 of 36 scans
    pose = log.scans[0].reference
    assert pose is not None
    spot = np.array([[pose[0] + math.cos(pose[2] + 0.3), pose[1] + math.sin(pose[2] + 0.3)]])
    ((r, c),) = grid.world_to_cell(spot)
    assert not grid.occupied()[r - 1 : r + 2, c - 1 : c + 2].any()


def test_needs_poses() -> None:
    log = _room_log()
    bare = RobotLog("bare", [Scan(s.timestamp, s.ranges, s.geometry) for s in log.scans])
    with pytest.raises(MapError, match="no scan has a reference pose"):
        build_reference_map(bare)


def test_params_resolution() -> None:
    grid = build_reference_map(_room_log(), 0.1, ReferenceMapParams(hit="endpoint"))
    assert grid.resolution == 0.1
    assert build_reference_map(_room_log(), params=ReferenceMapParams(resolution=0.2)).resolution == 0.2
    assert build_reference_map(_room_log()).resolution == 0.05
    with pytest.raises(MapError, match="resolution must be positive"):
        build_reference_map(_room_log(), 0.0)


def test_fhw_map_shape(real_log: Callable[[str], RobotLog]) -> None:
    log = real_log("fhw")
    grid = build_reference_map(log)
    assert grid.resolution == 0.05
    # the FHW hall is about 28 m x 88 m; the map is its bounding box plus 1 m margins
    assert 20 < grid.width < 40
    assert 70 < grid.height < 100
    assert grid.occupied().sum() > 5000
    assert grid.free().sum() > 10 * grid.occupied().sum()


def test_fhw_map_quality_meets_the_target(real_log: Callable[[str], RobotLog]) -> None:
    """Issue target: median |ray cast - measured| <= 4 cm at 5 cm cells on the FHW log."""
    from tourbot.maps.reference import map_quality

    log = real_log("fhw")
    quality = map_quality(build_reference_map(log), log)
    assert quality["median_abs_error"] <= 0.04
    assert quality["beams"] > 80_000
    # the textbook model (hit = the endpoint's cell) is measurably worse under ray casting
    textbook = map_quality(build_reference_map(log, params=ReferenceMapParams(hit="endpoint")), log)
    assert textbook["median_abs_error"] > quality["median_abs_error"]
