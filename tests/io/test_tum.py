"""TUM trajectories: exact round trip, evo's layout, bad input."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.io import TrajectoryFormatError
from tourbot.io.tum import read_tum, write_tum


def test_layout_is_evo_tum(tmp_path: Path) -> None:
    path = tmp_path / "t.txt"
    write_tum(path, [1.5, 2.5], [[1.0, 2.0, math.pi / 2], [3.0, 4.0, 0.0]])
    rows = [line.split() for line in path.read_text().splitlines() if not line.startswith("#")]
    assert len(rows) == 2
    values = np.array(rows, dtype=float)
    assert values.shape == (2, 8)
    np.testing.assert_allclose(values[0], [1.5, 1, 2, 0, 0, 0, math.sqrt(0.5), math.sqrt(0.5)])


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(0, 1e9), st.floats(-1e4, 1e4), st.floats(-1e4, 1e4), st.floats(-3.14159, 3.14159)
        ),
        min_size=1,
        max_size=20,
    )
)
def test_round_trip(rows: list[tuple[float, float, float, float]]) -> None:
    import tempfile

    data = np.array(rows)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "t.txt"
        write_tum(path, data[:, 0], data[:, 1:])
        times, poses = read_tum(path)
    np.testing.assert_array_equal(times, data[:, 0])
    np.testing.assert_array_equal(poses[:, :2], data[:, 1:3])
    np.testing.assert_allclose(poses[:, 2], data[:, 3], atol=1e-12)


@pytest.mark.parametrize(
    ("text", "match", "field"),
    [
        ("1 2 3\n", "3 fields, 8 expected", None),
        ("1 2 x 0 0 0 0 1\n", "not a number", "y"),
        ("1 2 3 0 0 0 0 2\n", "unit length", None),
        ("# only a comment\n", "no poses", None),
    ],
)
def test_bad_files(tmp_path: Path, text: str, match: str, field: str | None) -> None:
    path = tmp_path / "bad.txt"
    path.write_text("# header\n" + text)
    with pytest.raises(TrajectoryFormatError, match=match) as info:
        read_tum(path)
    assert info.value.field == field
    if "expected" in match or field:
        assert info.value.line == 2


def test_mismatched_lengths(tmp_path: Path) -> None:
    with pytest.raises(TrajectoryFormatError, match="2 timestamps for 1 poses"):
        write_tum(tmp_path / "t.txt", [1.0, 2.0], [[0.0, 0.0, 0.0]])
