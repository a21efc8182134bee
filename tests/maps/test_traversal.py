"""The grid traversal: its two modes walk the same cells, and the axis conventions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.raycast import DDACaster, DistanceCaster
from tourbot.maps.traversal import AXIS, axis, cast_ray, trace_ray


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    jumps=st.booleans(),
    outside_blocks=st.booleans(),
    max_cells=st.floats(1.0, 80.0),
)
def test_a_cast_traced_back_hits_the_blocking_cell_through_free_cells(
    seed: int, jumps: bool, outside_blocks: bool, max_cells: float
) -> None:
    """Cast mode stops where trace mode enters the first blocking cell (the same floats)."""
    rng = np.random.default_rng(seed)
    rows, cols = 30, 40
    prob = np.where(rng.random((rows, cols)) < 0.04, 1.0, 0.0).astype(np.float32)
    prob[rng.integers(0, rows), :] = 0.0  # an empty row and column: long rays
    prob[:, rng.integers(0, cols)] = 0.0
    grid = OccupancyGrid(prob, resolution=1.0)
    caster = (DistanceCaster if jumps else DDACaster)(grid, max_cells, unknown_blocks=outside_blocks)
    blocked = caster.blocked
    for _ in range(30):
        ox, oy = rng.uniform(0.0, cols), rng.uniform(0.0, rows)
        if rng.random() < 0.2:  # some rays from grid lines and corners
            ox, oy = float(math.floor(ox)), float(math.floor(oy))
        theta = rng.choice([rng.uniform(-math.pi, math.pi), rng.integers(-4, 5) * math.pi / 4])
        dx, dy = math.cos(theta), math.sin(theta)
        r = cast_ray(caster.table, cols + 2, rows, cols, ox, oy, dx, dy, caster.max_cells, outside_blocks)
        hits = np.zeros((rows, cols), dtype=np.int32)
        misses = np.zeros((rows, cols), dtype=np.int32)
        if r >= caster.max_cells:  # nothing blocks: every cell up to max_cells is free
            trace_ray(ox, oy, dx, dy, r, False, True, rows, cols, hits, misses)
            assert not (misses.astype(bool) & blocked).any()
            continue
        trace_ray(ox, oy, dx, dy, r, True, True, rows, cols, hits, misses)
        assert not (misses.astype(bool) & blocked).any()
        if hits.any():  # the hit is the blocking cell where the cast stopped
            assert hits.sum() == 1
            assert blocked[hits.astype(bool)].all()
        else:  # it stopped where the ray leaves the grid (outside blocks)
            assert outside_blocks
            ex, ey = ox + r * dx, oy + r * dy
            assert min(ex, ey, cols - ex, rows - ey) < 1e-6


def test_axis_conventions() -> None:
    assert axis(0.5) == (1, 1, 2.0)
    assert axis(-0.5) == (-1, 0, -2.0)
    step, ahead, inv = axis(AXIS / 2)  # a hair off the axis: along it
    assert (step, ahead) == (0, 1)
    assert inv > 1e200


@pytest.mark.parametrize("theta", [0.0, math.pi / 2, math.pi, -math.pi / 2])
def test_a_ray_along_a_grid_line_walks_one_side_of_it(theta: float) -> None:
    """From a cell corner along an axis, the ray walks the cells on the side of larger index."""
    hits = np.zeros((6, 6), dtype=np.int32)
    misses = np.zeros((6, 6), dtype=np.int32)
    trace_ray(3.0, 3.0, math.cos(theta), math.sin(theta), 2.5, False, True, 6, 6, hits, misses)
    rows, cols = np.nonzero(misses)
    assert misses.sum() == 3  # 2.5 cells from a grid line: three cells, each once
    along_x = abs(math.cos(theta)) > 0.5
    assert set((rows if along_x else cols).tolist()) == {3}
