"""The one grid Dijkstra: the numba kernel against its heapq twin, unit costs, walls, the cut-off."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.maps.dijkstra import grid_dijkstra, grid_dijkstra_reference, unit_costs


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    rows=st.integers(1, 12),
    cols=st.integers(1, 12),
    density=st.floats(0.0, 0.5),
    max_cost=st.sampled_from([np.inf, 3.0, 8.5]),
    unit=st.booleans(),
)
def test_kernel_matches_reference(
    seed: int, rows: int, cols: int, density: float, max_cost: float, unit: bool
) -> None:
    rng = np.random.default_rng(seed)
    cost = np.ones((rows, cols)) if unit else rng.uniform(1.0, 3.0, size=(rows, cols))
    cost[rng.random((rows, cols)) < density] = np.inf
    r, c = int(rng.integers(rows)), int(rng.integers(cols))
    fast = grid_dijkstra(cost, r, c, max_cost)
    ref = grid_dijkstra_reference(cost, r, c, max_cost)
    assert np.array_equal(np.isinf(fast), np.isinf(ref))
    finite = np.isfinite(ref)
    np.testing.assert_allclose(fast[finite], ref[finite], rtol=1e-12)
    assert (fast[finite] <= max_cost).all()


def test_unit_costs_give_geodesic_distances_around_a_wall() -> None:
    walkable = np.ones((10, 10), dtype=bool)
    walkable[:8, 5] = False  # a wall with an opening at the bottom rows 8-9
    d = grid_dijkstra(unit_costs(walkable), 0, 0, 100.0)
    assert np.isinf(d[0, 5])
    assert d[0, 9] > 9.0 + 7.0  # down, through the opening, and back up
    assert d[0, 4] == 4.0
    assert d[3, 3] == np.float64(3 * np.sqrt(2.0))


def test_a_source_off_the_grid_or_forbidden_reaches_nothing() -> None:
    cost = np.ones((4, 4))
    cost[1, 1] = np.inf
    assert np.isinf(grid_dijkstra(cost, 1, 1)).all()
    assert np.isinf(grid_dijkstra(cost, -1, 0)).all()
    assert np.isinf(grid_dijkstra(cost, 0, 4)).all()
