"""Plotting helpers: rigid alignment, path length, a picture that holds the map and the paths."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from tourbot.geometry import compose
from tourbot.maps.grid import UNKNOWN, OccupancyGrid
from tourbot.plotting import Trajectory, align_rigid, path_length, show_log


@settings(max_examples=30, deadline=None)
@given(st.floats(-10, 10), st.floats(-10, 10), st.floats(-3.1, 3.1))
def test_align_rigid_undoes_a_rigid_motion(x: float, y: float, th: float) -> None:
    rng = np.random.default_rng(0)
    target = np.column_stack([rng.uniform(-5, 5, (20, 2)), rng.uniform(-3, 3, 20)])
    moved = compose(np.array([x, y, th]), target)
    back = align_rigid(moved, target)
    np.testing.assert_allclose(back[:, :2], target[:, :2], atol=1e-9)
    np.testing.assert_allclose(np.cos(back[:, 2] - target[:, 2]), 1.0, atol=1e-9)


def test_path_length_skips_nan() -> None:
    poses = np.array([[0, 0, 0], [3, 4, 0], [np.nan, 0, 0], [3, 5, 0]], dtype=float)
    assert path_length(poses) == pytest.approx(6.0)


def test_picture_with_rotated_map(tmp_path: Path) -> None:
    prob = np.full((40, 60), UNKNOWN, dtype=np.float32)
    prob[5:35, 5:55] = 0.0
    prob[5, 5:55] = 1.0
    grid = OccupancyGrid(prob, 0.1, origin=(1.0, 2.0, math.radians(20)))
    path = np.array([[2.0, 3.0, 0.0], [4.0, 4.0, 0.0], [5.0, 5.5, 0.0]])
    out = show_log(None, tmp_path / "p.png", grid=grid, trajectories=[Trajectory("walk", path)], title="t")
    with Image.open(out) as img:
        pixels = np.asarray(img.convert("RGB")).astype(int)
    assert (np.abs(pixels - [0, 114, 178]).sum(axis=2) < 40).sum() > 50  # the path, first colour
    assert (pixels.sum(axis=2) < 60).sum() > 50  # the occupied row, black
