from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.mapping.confirmation import (
    ConfirmationParams,
    confirmed_beams,
    confirming_scans,
    continues_structure,
)

RES = 0.05


def _at(cells: list[tuple[int, int]]) -> np.ndarray:
    """World points at the centres of cells given as (x, y) cell indices."""
    return (np.asarray(cells, dtype=np.float64).reshape(-1, 2) + 0.5) * RES


def test_distinct_other_scans_are_counted() -> None:
    left = _at([(10, 10), (40, 40)])
    left_scans = np.array([0, 0])
    # scan 1 ends twice next to the first end (one scan), scan 2 in its cell, scan 0 (its own
    # scan) beside it, scan 3 two cells away (outside a radius of 1)
    kept = _at([(10, 11), (11, 11), (10, 10), (9, 10), (12, 10)])
    kept_scans = np.array([1, 1, 2, 0, 3])
    n = confirming_scans(left, left_scans, kept, kept_scans, RES, radius=1)
    assert n.tolist() == [2, 0]
    assert confirming_scans(left, left_scans, kept, kept_scans, RES, radius=2).tolist() == [3, 0]
    assert confirmed_beams(left, left_scans, kept, kept_scans, RES, ConfirmationParams(1, 2)).tolist() == [
        True,
        False,
    ]
    assert not confirmed_beams(left, left_scans, kept, kept_scans, RES, ConfirmationParams(1, 3)).any()
    assert len(confirming_scans(np.zeros((0, 2)), np.zeros(0, np.int64), kept, kept_scans, RES)) == 0
    assert confirming_scans(left, left_scans, np.zeros((0, 2)), np.zeros(0, np.int64), RES).tolist() == [0, 0]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), radius=st.integers(0, 2))
def test_confirming_scans_match_a_plain_count(seed: int, radius: int) -> None:
    rng = np.random.default_rng(seed)
    left = rng.uniform(-0.3, 0.3, (int(rng.integers(1, 20)), 2))
    kept = rng.uniform(-0.3, 0.3, (int(rng.integers(1, 60)), 2))
    left_scans = rng.integers(0, 6, len(left))
    kept_scans = rng.integers(0, 6, len(kept))
    n = confirming_scans(left, left_scans, kept, kept_scans, RES, radius)
    lc, kc = np.floor(left / RES).astype(int), np.floor(kept / RES).astype(int)
    for i in range(len(left)):
        near = np.abs(kc - lc[i]).max(axis=1) <= radius
        assert n[i] == len(set(kept_scans[near].tolist()) - {int(left_scans[i])})


def test_an_end_in_a_line_of_structure_continues_it_but_not_one_beside_a_wall() -> None:
    occupied = np.zeros((20, 20), dtype=bool)
    occupied[10, 2:8] = True  # a wall along row 10, with a gap of three cells
    occupied[10, 11:18] = True
    occupied[2, 2:18] = True  # a straight wall along row 2
    cells = np.array(
        [
            [10, 9],  # in the gap: the wall 2 cells away on both sides
            [10, 18],  # at the wall's end, continuing it: the wall on one side only
            [5, 9],  # in the open: nothing within 2 cells
            [4, 9],  # 2 cells in front of the straight wall: on one side (corners 90 deg apart)
            [3, 9],  # 1 cell in front of it: wall cells up to 127 deg apart
            [-5, -5],  # outside the grid
        ]
    )
    yes, no = True, False
    assert continues_structure(occupied, cells, 2, 90.0).tolist() == [yes, no, no, yes, yes, no]
    assert continues_structure(occupied, cells, 2, 135.0).tolist() == [yes, no, no, no, no, no]
    assert continues_structure(occupied, cells, 1, 90.0).tolist() == [no, no, no, no, yes, no]
    assert len(continues_structure(occupied, np.zeros((0, 2), np.int64))) == 0


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    radius=st.integers(1, 3),
    angle=st.sampled_from([45.0, 90.0, 135.0, 180.0]),
)
def test_continues_structure_matches_a_plain_loop(seed: int, radius: int, angle: float) -> None:
    rng = np.random.default_rng(seed)
    occupied = rng.random((12, 9)) < 0.15
    cells = rng.integers(-2, 14, (int(rng.integers(1, 30)), 2))
    got = continues_structure(occupied, cells, radius, angle)
    for i, (r, c) in enumerate(cells.tolist()):
        dirs = [
            (dr, dc)
            for dr in range(-radius, radius + 1)
            for dc in range(-radius, radius + 1)
            if (dr, dc) != (0, 0) and 0 <= r + dr < 12 and 0 <= c + dc < 9 and occupied[r + dr, c + dc]
        ]
        wide = any(
            np.degrees(np.arccos(np.clip((a[0] * b[0] + a[1] * b[1]) / np.hypot(*a) / np.hypot(*b), -1, 1)))
            >= angle - 1e-6
            for a in dirs
            for b in dirs
        )
        assert got[i] == wide
