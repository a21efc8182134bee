from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.mapping.confirmation import ConfirmationParams, confirmed_beams, confirming_scans

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
