from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.mapping.free_space import free_sectors, free_sectors_reference
from tourbot.mapping.incremental import IncrementalMapper, MapperParams
from tourbot.records import LaserGeometry, Scan


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    beams=st.integers(0, 40),
    full=st.booleans(),
    width=st.sampled_from([math.inf, 0.5, 2.0]),
    cap=st.sampled_from([math.inf, 8.0, 20.0]),
)
def test_free_sectors_kernel_matches_numpy_reference(
    seed: int, beams: int, full: bool, width: float, cap: float
) -> None:
    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(1, 40)), int(rng.integers(1, 40)))
    ox, oy = rng.uniform(-5, 45, 2)
    step = 2 * math.pi / beams if full and beams else float(rng.uniform(0.01, 0.2))
    theta0 = float(rng.uniform(-4, 4))
    lengths = np.where(rng.random(beams) < 0.1, 0.0, rng.uniform(0, 40, beams))
    margin = float(rng.uniform(0, 3))
    fast = free_sectors(shape, ox, oy, theta0, step, lengths, margin=margin, width=width, cap=cap)
    slow = free_sectors_reference(shape, ox, oy, theta0, step, lengths, margin=margin, width=width, cap=cap)
    assert np.array_equal(fast, slow)


def test_a_sector_is_free_up_to_the_nearer_beam() -> None:
    # two beams at 0 and 10 deg from (0.5, 0.5): 30 and 20 cells long
    free = free_sectors((40, 40), 0.5, 0.5, 0.0, math.radians(10), np.array([30.0, 20.0]), margin=2.0)
    r = np.hypot(*np.meshgrid(np.arange(40.0), np.arange(40.0), indexing="xy"))
    assert free[1, 10]  # between the beams (5.7 deg), 10 cells out
    assert not free[2, 19]  # between them, but beyond the nearer beam less the margin
    assert not free[10, 10]  # 45 deg: outside the sector
    assert not free[r > 18.0].any()


def test_free_sectors_clear_a_leg_that_no_later_beam_crossed() -> None:
    """A leg hit once at 9 m stays in the map when later beams pass it on both sides; with free
    sectors the scan that saw the wall behind it clears it. The wall itself stays."""
    geom = LaserGeometry(61, -math.radians(30), math.radians(1), 30.0)
    wall = 12.0 / np.cos(geom.angles)  # a wall 12 m ahead
    leg = wall.copy()
    leg[30] = 9.0  # one beam on a leg at 9 m straight ahead
    first = Scan(0.0, leg, geom, odom=(0.0, 0.0, 0.0))
    # a later scan from 0.4 m to the side: its beams pass the leg's spot, none through its cell
    side = np.array([0.0, 0.4, 0.0])
    later = Scan(1.0, wall, geom, odom=(0.0, 0.4, 0.0))
    spot = np.array([[9.0 + 0.04, 0.0]])
    wall_cells = np.array([[12.0, y] for y in np.linspace(-3.0, 3.0, 13)])
    results = {}
    for sectors in (False, True):
        mapper = IncrementalMapper(MapperParams(free_sectors=sectors), start=np.zeros(3))
        mapper.integrate(first, np.zeros(3))
        mapper.integrate(later, side)
        results[sectors] = (mapper.evidence(spot)[0], mapper.evidence(wall_cells))
    assert results[False][0] > 0  # no beam of the later scan crossed the leg's cell
    assert results[True][0] < results[False][0]
    occupied = MapperParams().cells.occupied_thresh
    threshold = math.log(occupied / (1 - occupied))
    assert results[True][0] < threshold  # no longer occupied
    assert np.array_equal(results[True][1] > 0, results[False][1] > 0)  # the wall is untouched
