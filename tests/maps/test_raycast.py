"""Ray casters against the numpy reference, and the geometry of simple cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.maps.grid import UNKNOWN, MapError, OccupancyGrid
from tourbot.maps.raycast import (
    DDACaster,
    DistanceCaster,
    cast_circles_reference,
    cast_rays_reference,
)

CASTERS = [DDACaster, DistanceCaster]


def random_grid(
    seed: int, rows: int = 40, cols: int = 50, boxes: int = 12, unknown: bool = True
) -> OccupancyGrid:
    rng = np.random.default_rng(seed)
    prob = np.zeros((rows, cols), dtype=np.float32)
    for _ in range(boxes):
        r, c = rng.integers(0, rows), rng.integers(0, cols)
        prob[r : r + rng.integers(1, 6), c : c + rng.integers(1, 6)] = 1.0
    if unknown:
        r = rng.integers(0, rows - 4)
        prob[r : r + 3, :8] = UNKNOWN
    origin = (rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-np.pi, np.pi))
    return OccupancyGrid(prob, resolution=0.1, origin=origin)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    unknown_blocks=st.booleans(),
    max_range=st.floats(0.3, 9.0),
    cx=st.floats(-0.2, 1.2),
    cy=st.floats(-0.2, 1.2),
)
@pytest.mark.parametrize("caster_cls", CASTERS)
def test_casters_match_reference(
    caster_cls: type[DDACaster], seed: int, unknown_blocks: bool, max_range: float, cx: float, cy: float
) -> None:
    grid = random_grid(seed)
    rng = np.random.default_rng(seed + 1)
    # poses spread over the grid (and a little outside), in grid-fraction coordinates
    local = np.column_stack(
        [
            (cx + rng.normal(0, 0.3, 8)) * grid.width,
            (cy + rng.normal(0, 0.3, 8)) * grid.height,
            rng.uniform(-np.pi, np.pi, 8),
        ]
    )
    poses = grid.grid_to_world(local)
    angles = np.linspace(-np.pi, np.pi, 37)
    caster = caster_cls(grid, max_range, unknown_blocks=unknown_blocks)
    got = caster.cast(poses, angles)
    ref = caster.cast_reference(poses, angles)
    assert got.shape == (8, 37)
    assert got.dtype == np.float32
    np.testing.assert_allclose(got, ref, atol=1e-4)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_distance_caster_agrees_with_dda_on_large_open_grid(seed: int) -> None:
    # big empty areas make the distance caster jump many cells at a time
    grid = random_grid(seed, rows=120, cols=150, boxes=6, unknown=False)
    rng = np.random.default_rng(seed)
    local = np.column_stack(
        [rng.uniform(0, grid.width, 20), rng.uniform(0, grid.height, 20), rng.uniform(-4, 4, 20)]
    )
    poses = grid.grid_to_world(local)
    angles = rng.uniform(-np.pi, np.pi, 50)
    dda = DDACaster(grid, 30.0).cast(poses, angles)
    fast = DistanceCaster(grid, 30.0).cast(poses, angles)
    np.testing.assert_allclose(fast, dda, atol=1e-4)


@pytest.mark.parametrize("caster_cls", CASTERS)
def test_known_ranges_in_a_box_room(caster_cls: type[DDACaster]) -> None:
    # 10 x 10 m room, walls one cell (0.1 m) thick on the border
    prob = np.zeros((100, 100), dtype=np.float32)
    prob[0, :] = prob[-1, :] = prob[:, 0] = prob[:, -1] = 1.0
    grid = OccupancyGrid(prob, resolution=0.1, origin=(-5.0, -5.0, 0.0))
    caster = caster_cls(grid, 20.0)
    ranges = caster.cast(
        np.array([[0.0, 0.0, 0.0], [2.0, 1.0, math.pi / 2]]), np.array([0.0, math.pi / 2, math.pi])
    )
    np.testing.assert_allclose(ranges[0], [4.9, 4.9, 4.9], atol=1e-5)
    np.testing.assert_allclose(ranges[1], [3.9, 6.9, 5.9], atol=1e-5)
    short = caster_cls(grid, 2.0).cast(np.zeros((1, 3)), np.array([0.3]))
    assert short[0, 0] == pytest.approx(2.0)


def test_outside_and_unknown_conventions() -> None:
    prob = np.zeros((10, 10), dtype=np.float32)
    prob[:, 7] = UNKNOWN
    grid = OccupancyGrid(prob, resolution=1.0)
    pose = np.array([[2.5, 5.5, 0.0]])
    assert DDACaster(grid, 50.0).cast(pose, [0.0])[0, 0] == pytest.approx(4.5)  # unknown blocks
    # unknown free: the ray leaves the grid and reads max_range
    assert DDACaster(grid, 50.0, unknown_blocks=False).cast(pose, [0.0])[0, 0] == pytest.approx(50.0)
    # unknown blocks -> the outside blocks: a pose off the grid reads 0, a ray leaving reads the edge
    assert DDACaster(grid, 50.0).cast(np.array([[-3.0, 5.5, 0.0]]), [0.0])[0, 0] == 0.0
    assert DDACaster(grid, 50.0).cast(pose, [math.pi])[0, 0] == pytest.approx(2.5)
    # outside free: a ray from outside enters the grid and hits the unknown column... which is free
    prob[:, 7] = 1.0
    grid2 = OccupancyGrid(prob, resolution=1.0)
    assert DDACaster(grid2, 50.0, unknown_blocks=False).cast(np.array([[-3.0, 5.5, 0.0]]), [0.0])[
        0, 0
    ] == pytest.approx(10.0)


def test_reference_handles_degenerate_rays() -> None:
    blocked = np.zeros((5, 5), dtype=bool)
    blocked[2, 4] = True
    # axis-aligned rays from integer coordinates, zero-length max range
    r = cast_rays_reference(blocked, [0.0, 2.0, 2.5], [2.0, 2.0, 2.5], [0.0, 0.0, math.pi / 2], 10.0)
    np.testing.assert_allclose(r, [4.0, 2.0, 2.5])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), k=st.integers(0, 6))
@pytest.mark.parametrize("caster_cls", CASTERS)
def test_cast_with_circles_matches_reference(caster_cls: type[DDACaster], seed: int, k: int) -> None:
    grid = random_grid(seed, unknown=False)
    rng = np.random.default_rng(seed)
    local = np.column_stack(
        [rng.uniform(0, grid.width, 5), rng.uniform(0, grid.height, 5), rng.uniform(-4, 4, 5)]
    )
    poses = grid.grid_to_world(local)
    centres = grid.grid_to_world(
        np.column_stack([rng.uniform(0, grid.width, k), rng.uniform(0, grid.height, k), np.zeros(k)])
    )[:, :2]
    radii = rng.uniform(0.05, 0.6, k)
    angles = np.linspace(-np.pi / 2, np.pi / 2, 31)
    caster = caster_cls(grid, 8.0)
    got = caster.cast_with_circles(poses, angles, centres, radii)
    plain = caster.cast(poses, angles)
    th = (poses[:, 2:3] + angles[None, :]).ravel()
    circ = cast_circles_reference(
        np.repeat(poses[:, 0], 31), np.repeat(poses[:, 1], 31), th, centres[:, 0], centres[:, 1], radii
    ).reshape(5, 31)
    np.testing.assert_allclose(got, np.minimum(plain, circ), atol=1e-4)


def test_circle_straight_ahead() -> None:
    grid = OccupancyGrid(np.zeros((10, 10), dtype=np.float32), resolution=1.0)
    caster = DDACaster(grid, 50.0, unknown_blocks=False)
    got = caster.cast_with_circles(np.array([[1.0, 5.0, 0.0]]), [0.0, math.pi], [[4.0, 5.0]], [0.5])
    np.testing.assert_allclose(got, [[2.5, 50.0]], atol=1e-6)
    inside = caster.cast_with_circles(np.array([[4.1, 5.0, 0.0]]), [0.0], [[4.0, 5.0]], [0.5])
    assert inside[0, 0] == 0.0


def test_bad_poses_and_angles_are_reported() -> None:
    grid = OccupancyGrid(np.zeros((10, 10), dtype=np.float32), resolution=1.0)
    caster = DistanceCaster(grid, 5.0)
    with pytest.raises(MapError, match="finite"):
        caster.cast(np.array([[1.0, np.nan, 0.0]]), [0.0])
    with pytest.raises(MapError, match="finite"):
        caster.cast(np.zeros((1, 3)), [np.inf])
    with pytest.raises(MapError, match=r"\(N, 3\)"):
        caster.cast(np.zeros(3), [0.0])
    with pytest.raises(MapError, match="radii"):
        caster.cast_with_circles(np.zeros((1, 3)), [0.0], [[1.0, 1.0]], [0.1, 0.2])
    with pytest.raises(MapError):
        DDACaster(grid, 0.0)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), outside_blocks=st.booleans())
def test_reference_matches_dense_sampling(seed: int, outside_blocks: bool) -> None:
    # the oracle itself, checked by walking each ray in 1e-3-cell steps
    rng = np.random.default_rng(seed)
    blocked = rng.random((12, 15)) < 0.15
    m = 30
    ox, oy = rng.uniform(-2, 17, m), rng.uniform(-2, 14, m)
    th = rng.uniform(-np.pi, np.pi, m)
    max_cells = 12.0
    ref = cast_rays_reference(blocked, ox, oy, th, max_cells, outside_blocks)
    s = np.arange(0.0, max_cells, 1e-3)
    px = np.floor(ox[:, None] + s[None, :] * np.cos(th)[:, None]).astype(int)
    py = np.floor(oy[:, None] + s[None, :] * np.sin(th)[:, None]).astype(int)
    inside = (px >= 0) & (px < 15) & (py >= 0) & (py < 12)
    hit = np.full(px.shape, outside_blocks)
    hit[inside] = blocked[py[inside], px[inside]]
    first = np.where(hit.any(axis=1), s[np.argmax(hit, axis=1)], max_cells)
    # sampling can miss a clip of a cell corner shorter than its step, never invent a hit
    assert np.all(ref <= first + 1.1e-3)
    assert np.mean(np.abs(ref - first) <= 1.1e-3) >= 0.9


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), n_beams=st.integers(1, 11))
@pytest.mark.parametrize("caster_cls", CASTERS)
def test_beams_cast_side_by_side_equal_beams_cast_alone(
    caster_cls: type[DDACaster], seed: int, n_beams: int
) -> None:
    # the kernel casts beams four at a time and the rest (fewer than four) one by one: any number
    # of beams gives each beam the range it has alone, to the bit, and the reference's
    grid = random_grid(seed)
    rng = np.random.default_rng(seed + 2)
    local = np.column_stack(
        [rng.uniform(0, grid.width, 5), rng.uniform(0, grid.height, 5), rng.uniform(-np.pi, np.pi, 5)]
    )
    poses = grid.grid_to_world(local)
    angles = rng.uniform(-np.pi, np.pi, n_beams)
    caster = caster_cls(grid, 6.0)
    together = caster.cast(poses, angles)
    alone = np.column_stack([caster.cast(poses, angles[b : b + 1])[:, 0] for b in range(n_beams)])
    assert np.array_equal(together, alone)
    np.testing.assert_allclose(together, caster.cast_reference(poses, angles), atol=1e-4)
