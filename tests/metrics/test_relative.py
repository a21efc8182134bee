from __future__ import annotations

import numpy as np
import pytest

from tourbot.geometry import compose, relative
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


def _loop(n: int = 400) -> np.ndarray:
    """Two laps around a 10 m x 6 m rectangle-ish loop (revisits on the second lap)."""
    t = np.linspace(0, 4 * np.pi, n)
    return np.c_[5 * np.cos(t), 3 * np.sin(t), t + np.pi / 2]


def test_pairs_are_reproducible_and_cover_separations_and_revisits() -> None:
    from tourbot.metrics.relative import PairSampling, path_length, sample_pairs

    ref = _loop()
    a, b = sample_pairs(ref), sample_pairs(ref)
    for key in ("separation", "revisit", "consecutive"):
        assert np.array_equal(a[key], b[key])
    along = path_length(ref)
    gaps = along[a["separation"][:, 1]] - along[a["separation"][:, 0]]
    assert gaps.min() >= 1.0
    assert 30.0 < gaps.max() < 50.5
    rev = a["revisit"]
    assert len(rev) > 0
    assert np.all(np.hypot(*(ref[rev[:, 0], :2] - ref[rev[:, 1], :2]).T) < 1.0)
    assert np.all(along[rev[:, 1]] - along[rev[:, 0]] >= 10.0)
    other = sample_pairs(ref, PairSampling(seed=1))
    assert not np.array_equal(other["separation"], a["separation"])


def test_revisit_pairs_see_drift_that_consecutive_pairs_hide() -> None:
    from tourbot.metrics.relative import relation_error, sample_pairs

    ref = _loop()
    drift = ref.copy()
    # a slow heading drift: each step's error is tiny, the loop does not close
    inc = relative(ref[:-1], ref[1:])
    inc[:, 2] += 0.002
    for i in range(1, len(ref)):
        drift[i] = compose(drift[i - 1], inc[i - 1])
    pairs = sample_pairs(ref)
    consecutive = relation_error(drift, ref, pairs["consecutive"]).trans_mean
    revisit = relation_error(drift, ref, pairs["revisit"]).trans_mean
    assert consecutive < 0.01
    assert revisit > 20 * consecutive


def test_ate_ignores_a_rigid_motion_and_sees_a_bend() -> None:
    from tourbot.metrics.relative import align_se2, aligned_trajectory_error

    ref = _loop()
    moved = compose(np.array([4.0, -1.0, 1.1]), ref)
    t = align_se2(moved, ref)
    back = compose(t, moved)
    assert np.allclose(back[:, :2], ref[:, :2], atol=1e-9)
    assert np.allclose(np.cos(back[:, 2] - ref[:, 2]), 1.0)
    assert aligned_trajectory_error(moved, ref).rmse == pytest.approx(0.0, abs=1e-9)
    bent = moved.copy()
    bent[200:, 0] += 1.0
    assert aligned_trajectory_error(bent, ref).rmse > 0.3


def test_map_agreement_within_tolerance() -> None:
    from tourbot.maps.grid import OccupancyGrid
    from tourbot.metrics.maps import map_agreement

    prob = np.zeros((40, 40), np.float32)
    prob[20, 5:35] = 1.0
    ref = OccupancyGrid(prob, 0.05)
    near = OccupancyGrid(np.roll(prob, 1, axis=0), 0.05)  # 5 cm off: within 10 cm
    far = OccupancyGrid(np.roll(prob, 4, axis=0), 0.05)  # 20 cm off
    assert map_agreement(near, ref) == {"precision": 1.0, "recall": 1.0}
    assert map_agreement(far, ref)["precision"] == 0.0
