"""The CDDT caster: its kernel against the numpy reference, and its ranges against the DDA's."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.maps.test_raycast import random_grid
from tourbot.maps.cddt import CDDTCaster, build_lanes
from tourbot.maps.grid import UNKNOWN, MapError, OccupancyGrid
from tourbot.maps.raycast import DDACaster, cast_rays_reference


def spread_poses(grid: OccupancyGrid, rng: np.random.Generator, n: int, margin: float = 0.2) -> np.ndarray:
    """World poses over the grid and a little outside it."""
    local = np.column_stack(
        [
            rng.uniform(-margin, 1 + margin, n) * grid.width,
            rng.uniform(-margin, 1 + margin, n) * grid.height,
            rng.uniform(-4.0, 4.0, n),
        ]
    )
    return grid.grid_to_world(local)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    unknown_blocks=st.booleans(),
    max_range=st.floats(0.3, 9.0),
    directions=st.sampled_from([4, 16, 64, 256]),
    lane_width=st.sampled_from([1.0, 0.5, 1.5]),
    aim_range=st.sampled_from([None, 0.0, 2.5]),
)
def test_kernel_matches_reference(
    seed: int,
    unknown_blocks: bool,
    max_range: float,
    directions: int,
    lane_width: float,
    aim_range: float | None,
) -> None:
    grid = random_grid(seed)
    rng = np.random.default_rng(seed + 1)
    poses = spread_poses(grid, rng, 10)
    angles = np.concatenate([np.linspace(-np.pi, np.pi, 37), rng.uniform(-20, 20, 5)])
    caster = CDDTCaster(grid, max_range, unknown_blocks, directions, lane_width, aim_range)
    got = caster.cast(poses, angles)
    assert got.shape == (10, 42)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, caster.cast_cddt_reference(poses, angles))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), ring=st.booleans(), directions=st.sampled_from([4, 32, 256]))
def test_lanes_are_sorted_runs_between_sentinels(seed: int, ring: bool, directions: int) -> None:
    rng = np.random.default_rng(seed)
    blocked = rng.random((rng.integers(1, 30), rng.integers(1, 30))) < rng.uniform(0.0, 0.6)
    t = build_lanes(blocked, directions, ring, lane_width=float(rng.choice([0.5, 1.0, 1.5])))
    assert t.ptr[-1] == t.bounds.size
    for g in range(t.ptr.size - 1):
        lane = t.bounds[t.ptr[g] : t.ptr[g + 1]].astype(np.int64)
        assert lane.size >= 2
        assert lane.size % 2 == 0
        assert lane[0] == 0
        assert lane[-1] == 65535
        assert np.all(np.diff(lane) >= 0)  # sorted: the binary search needs it
        runs = lane[1:-1]
        assert np.all(runs >= 1)
        assert np.all(runs <= 65534)
        assert np.all(runs[1::2] > runs[0::2])  # no empty run


def lane_rays(caster: CDDTCaster, poses: np.ndarray, angles: np.ndarray) -> tuple[np.ndarray, ...]:
    """The ray each beam is cast along, in grid cell units (as ``cast_rays_reference`` takes them):
    the heading of its bin, from the laser moved sideways onto the centre line of the lane the
    beam is in ``aim`` cells out; and the laser's own position."""
    g = caster.grid.world_to_grid(poses)
    x = np.repeat(g[:, 0] / caster.grid.resolution, angles.size)
    y = np.repeat(g[:, 1] / caster.grid.resolution, angles.size)
    t = caster.lanes
    step = 2 * math.pi / t.directions
    half = t.directions // 2
    heading = np.repeat(np.mod(g[:, 2], 2 * math.pi), angles.size)
    fb = (heading / step + 0.5) + np.tile(np.mod(angles, 2 * math.pi), len(poses)) / step
    d = np.floor(fb).astype(np.int64)
    k = d % half
    phi = k * step
    c, s = np.cos(phi), np.sin(phi)
    v = -x * s + y * c
    v_min = -t.params[k, 5] * t.lane_width
    sway = caster.aim_cells * (fb - 0.5 - d) * step * np.where((d % t.directions) >= half, -1.0, 1.0)
    v_lane = v_min + (np.floor((v + sway - v_min) / t.lane_width) + 0.5) * t.lane_width
    return x - (v_lane - v) * s, y + (v_lane - v) * c, d * step, x, y


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    unknown_blocks=st.booleans(),
    directions=st.sampled_from([16, 64, 256]),
    lane_width=st.sampled_from([1.0, 0.5, 1.5]),  # lane centres never on grid lines
    aim_range=st.sampled_from([None, 0.0, 1.5]),
)
def test_range_is_the_exact_range_of_the_lane_ray(
    seed: int, unknown_blocks: bool, directions: int, lane_width: float, aim_range: float | None
) -> None:
    # the stated tolerance: a CDDT range is the exact (DDA) range of the ray along the beam's
    # heading bin from the laser moved sideways onto its lane's centre line, within 1/16 cell
    grid = random_grid(seed)
    rng = np.random.default_rng(seed + 2)
    poses = spread_poses(grid, rng, 12)
    angles = rng.uniform(-np.pi, np.pi, 30)
    caster = CDDTCaster(grid, 4.0, unknown_blocks, directions, lane_width, aim_range)
    got = caster.cast(poses, angles).ravel() / grid.resolution
    lx, ly, phi, x, y = lane_rays(caster, poses, angles)
    expected = cast_rays_reference(caster.blocked, lx, ly, phi, caster.max_cells, unknown_blocks)
    rows, cols = grid.shape
    in_grid = (x >= 0) & (x < cols) & (y >= 0) & (y < rows)
    if unknown_blocks:
        # a laser in a blocking cell or off the grid reads 0 (the lane ray may start elsewhere)
        cell_blocked = np.ones(x.shape, dtype=bool)
        ix, iy = np.floor(x[in_grid]).astype(int), np.floor(y[in_grid]).astype(int)
        cell_blocked[in_grid] = caster.blocked[iy, ix]
        expected = np.where(cell_blocked, 0.0, expected)
    else:
        ix, iy = np.floor(x[in_grid]).astype(int), np.floor(y[in_grid]).astype(int)
        in_blocked = np.zeros(x.shape, dtype=bool)
        in_blocked[in_grid] = caster.blocked[iy, ix]
        expected = np.where(in_blocked, 0.0, expected)
    # runs are stored to 1/16 cell, rounded outwards: a lane ray starting within 1/16 cell past
    # the end of a run may still read 0
    behind = cast_rays_reference(caster.blocked, lx, ly, phi + np.pi, 1.0, unknown_blocks)
    near = behind <= 1 / 16 + 1e-6
    ok = np.abs(got - expected) <= 1 / 16 + 1e-4
    assert np.all(ok | (near & (got == 0.0))), np.flatnonzero(~ok)


def box_room() -> OccupancyGrid:
    # 10 x 10 m room, walls one cell (0.1 m) thick on the border
    prob = np.zeros((100, 100), dtype=np.float32)
    prob[0, :] = prob[-1, :] = prob[:, 0] = prob[:, -1] = 1.0
    return OccupancyGrid(prob, resolution=0.1, origin=(-5.0, -5.0, 0.0))


def test_walls_corners_and_max_range_in_a_box_room() -> None:
    grid = box_room()
    caster = CDDTCaster(grid, 20.0)
    dda = DDACaster(grid, 20.0)
    poses = np.array([[0.05, 0.05, 0.0], [2.05, 1.05, math.pi / 2]])  # cell centres
    # along the axes, from cell centres, the lane ray is the ray: exact to 1/16 cell
    got = caster.cast(poses, [0.0, math.pi / 2, math.pi])
    expected = [[4.85, 4.85, 4.95], [3.85, 6.95, 5.95]]
    np.testing.assert_allclose(got, expected, atol=0.1 / 16 + 1e-6)
    np.testing.assert_allclose(got, dda.cast(poses, [0.0, math.pi / 2, math.pi]), atol=0.1 / 16 + 1e-6)
    # into the corners, at 45 degrees to the walls: up to half a lane sideways, tan(45) = 1
    corners = np.array([-math.pi / 4, 3 * math.pi / 4])
    diff = np.abs(caster.cast(poses, corners) - dda.cast(poses, corners))
    assert np.all(diff <= 0.5 * 0.1 + 0.1 / 16 + 1e-6)
    # beams off their bins' centres onto a wall face (incidence |a| at most 0.2 rad): the bin's
    # half width and half a lane sideways, seen at that incidence
    off = np.array([0.004, -0.006, 0.013, 0.2])
    r = dda.cast(np.zeros((1, 3)), off)[0]
    half_bin = math.pi / 256
    bound = (0.05 + r * math.sin(half_bin)) * np.tan(np.abs(off) + half_bin) + r * (
        1 / math.cos(half_bin) - 1
    )
    assert np.all(np.abs(caster.cast(np.zeros((1, 3)), off)[0] - r) <= bound + 0.1 / 16 + 1e-6)
    # max range
    short = CDDTCaster(grid, 2.0).cast(np.zeros((1, 3)), np.array([0.3, 2.0]))
    np.testing.assert_array_equal(short, [[2.0, 2.0]])


def test_outside_and_unknown_conventions() -> None:
    prob = np.zeros((10, 10), dtype=np.float32)
    prob[:, 7] = UNKNOWN
    grid = OccupancyGrid(prob, resolution=1.0)
    pose = np.array([[2.5, 5.5, 0.0]])
    for kwargs in ({}, {"unknown_blocks": False}):
        cddt, dda = CDDTCaster(grid, 50.0, **kwargs), DDACaster(grid, 50.0, **kwargs)
        for p in (pose, np.array([[-3.0, 5.5, 0.0]]), np.array([[2.5, 7.5, 0.0]])):
            for a in (0.0, math.pi, math.pi / 2):
                assert cddt.cast(p, [a])[0, 0] == pytest.approx(dda.cast(p, [a])[0, 0], abs=1 / 16)
    assert CDDTCaster(grid, 50.0).cast(pose, [0.0])[0, 0] == pytest.approx(4.5)  # unknown blocks
    assert CDDTCaster(grid, 50.0, unknown_blocks=False).cast(pose, [0.0])[0, 0] == 50.0
    assert CDDTCaster(grid, 50.0).cast(np.array([[-3.0, 5.5, 0.0]]), [0.0])[0, 0] == 0.0  # off the grid
    prob[:, 7] = 1.0
    walled = CDDTCaster(OccupancyGrid(prob, resolution=1.0), 50.0, unknown_blocks=False)
    # outside empty: a ray from off the grid enters it and hits the wall
    assert walled.cast(np.array([[-3.0, 5.5, 0.0]]), [0.0])[0, 0] == pytest.approx(10.0)
    assert walled.cast(np.array([[-3.0, 5.5, 0.0]]), [math.pi])[0, 0] == 50.0


def test_agrees_with_dda_on_an_open_map() -> None:
    # few obstacles: most beams end on a wall face, where the approximation is small
    grid = random_grid(7, rows=120, cols=150, boxes=6, unknown=False)
    rng = np.random.default_rng(3)
    local = np.column_stack(
        [rng.uniform(0, grid.width, 50), rng.uniform(0, grid.height, 50), rng.uniform(-4, 4, 50)]
    )
    poses = grid.grid_to_world(local)
    angles = np.linspace(-np.pi, np.pi, 90, endpoint=False)
    got = CDDTCaster(grid, 30.0, directions=1024).cast(poses, angles)
    ref = DDACaster(grid, 30.0).cast(poses, angles)
    assert np.mean(np.abs(got - ref) <= grid.resolution) >= 0.9


def test_bad_parameters() -> None:
    grid = box_room()
    with pytest.raises(MapError, match="power of two"):
        CDDTCaster(grid, 5.0, directions=360)
    with pytest.raises(MapError, match="lane_width"):
        CDDTCaster(grid, 5.0, lane_width=3.0)
    with pytest.raises(MapError, match="finite"):
        CDDTCaster(grid, 5.0).cast(np.array([[1.0, np.nan, 0.0]]), [0.0])
    with pytest.raises(MapError, match="aim_range"):
        CDDTCaster(grid, 5.0, aim_range=-1.0)
    # the default aim: the mean range from the free cells (all beams reach the walls of the room)
    room = CDDTCaster(grid, 20.0)
    assert 1.0 / 0.1 < room.aim_cells < 7.1 / 0.1
    assert 4.0 < CDDTCaster(grid, 0.5).aim_cells <= 5.0 + 1e-6  # capped at max_range (0.5 m)
    solid = OccupancyGrid(np.ones((4, 4), dtype=np.float32), 1.0)
    assert CDDTCaster(solid, 5.0).aim_cells == 0.0
    empty = build_lanes(np.zeros((3, 4), dtype=bool), 8, ring=False)
    assert empty.runs == 0
    r = CDDTCaster(OccupancyGrid(np.zeros((3, 4), dtype=np.float32), 1.0), 5.0, unknown_blocks=False)
    np.testing.assert_array_equal(r.cast(np.array([[1.5, 1.5, 0.3]]), [0.0, 1.0]), [[5.0, 5.0]])
