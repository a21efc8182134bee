from __future__ import annotations

import numpy as np
import pytest

from tourbot.geometry import compose
from tourbot.metrics import relative_pose_error


def test_identical_paths_have_no_error() -> None:
    path = np.c_[np.linspace(0, 5, 20), np.sin(np.linspace(0, 3, 20)), np.linspace(-1, 1, 20)]
    e = relative_pose_error(path, path)
    assert e.trans_mean == pytest.approx(0.0, abs=1e-12)
    assert e.rot_mean == pytest.approx(0.0, abs=1e-12)
    assert e.pairs == 19


def test_global_offset_does_not_count_but_a_step_does() -> None:
    path = np.c_[np.linspace(0, 5, 20), np.zeros(20), np.zeros(20)]
    moved = compose(np.array([3.0, -2.0, 0.7]), path)
    assert relative_pose_error(moved, path).trans_mean == pytest.approx(0.0, abs=1e-9)
    bumped = path.copy()
    bumped[10:, 0] += 0.19
    e = relative_pose_error(bumped, path)
    assert e.trans_mean == pytest.approx(0.19 / 19)


def test_shape_mismatch() -> None:
    with pytest.raises(ValueError, match="same length"):
        relative_pose_error(np.zeros((3, 3)), np.zeros((4, 3)))
