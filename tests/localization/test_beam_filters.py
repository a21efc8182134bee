from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from tourbot.localization.beam_filters import (
    belief_entropy,
    entropy_change,
    entropy_change_reference,
    entropy_filter,
    novelty_filter,
    novelty_filter_cast,
    novelty_probability,
)
from tourbot.maps.beam_model import p_shorter_than_expected
from tourbot.maps.grid import UNKNOWN, OccupancyGrid
from tourbot.maps.raycast import DDACaster, DistanceCaster


@st.composite
def beliefs(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = draw(st.integers(1, 30))
    b = draw(st.integers(1, 12))
    lik = draw(arrays(np.float64, (n, b), elements=st.floats(0.0, 5.0)))
    w = draw(arrays(np.float64, (n,), elements=st.floats(0.01, 1.0)))
    groups = draw(arrays(np.int64, (n,), elements=st.integers(0, 5)))
    return lik, w, groups


@settings(max_examples=100, deadline=None)
@given(beliefs())
def test_entropy_kernel_matches_reference(case: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    lik, w, groups = case
    for g in (None, groups):
        fast = entropy_change(lik, w, g)
        ref = entropy_change_reference(lik, w, g)
        finite = np.isfinite(ref)
        assert np.array_equal(finite, np.isfinite(fast))
        np.testing.assert_allclose(fast[finite], ref[finite], atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(beliefs())
def test_constant_beam_changes_nothing(case: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    _, w, groups = case
    lik = np.full((w.shape[0], 1), 0.3)
    assert entropy_filter(lik, w).tolist() == [True]
    assert entropy_filter(lik, w, groups).tolist() == [True]
    assert abs(entropy_change(lik, w)[0]) < 1e-9


def test_uninformative_beams_are_not_reported_as_integrated() -> None:
    w = np.array([0.5, 0.5, 0.0])
    lik = np.array(
        [
            [0.3, 0.3, 2.0],  # beam 0: the same everywhere; beam 1: the same wherever Bel > 0
            [0.3, 0.3, 1.0],
            [0.3, 9.0, 1.0],
        ]
    )
    assert entropy_filter(lik, w).tolist() == [True, True, True]
    assert entropy_filter(lik, w, informative_only=True).tolist() == [False, False, True]
    # Beam 2 sharpens the belief: Eq. 4 keeps it with or without the flag.
    assert entropy_change(lik, w)[2] > 0


def test_entropy_filter_keeps_confirming_beams_and_drops_confusing_ones() -> None:
    # A belief concentrated on hypothesis 0.
    w = np.array([0.7, 0.1, 0.1, 0.1])
    lik = np.array(
        [
            [5.0, 0.1],  # beam 0 confirms hypothesis 0; beam 1 contradicts it
            [1.0, 5.0],
            [1.0, 5.0],
            [1.0, 5.0],
        ]
    )
    assert entropy_filter(lik, w).tolist() == [True, False]
    assert entropy_change(lik, w)[0] > 0 > entropy_change(lik, w)[1]


def test_entropy_with_groups_is_entropy_of_cell_sums() -> None:
    w = np.array([0.25, 0.25, 0.5])
    assert belief_entropy(w, groups=[7, 7, 3]) == pytest.approx(np.log(2.0))
    assert belief_entropy(w) == pytest.approx(-(0.5 * np.log(0.25) + 0.5 * np.log(0.5)))


def test_impossible_beam_is_dropped() -> None:
    lik = np.array([[0.0, 1.0], [0.0, 2.0]])
    assert entropy_filter(lik, np.ones(2)).tolist() == [False, True]


@settings(max_examples=60, deadline=None)
@given(beliefs())
def test_novelty_is_the_belief_average(case: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    lik, w, _ = case
    p = np.clip(lik / 5.0, 0.0, 1.0)
    pn = novelty_probability(p, w)
    expected = [sum(w[i] * p[i, b] for i in range(len(w))) / w.sum() for b in range(p.shape[1])]
    np.testing.assert_allclose(pn, expected, atol=1e-12)
    assert np.array_equal(novelty_filter(p, w), pn <= 0.99)


def test_novelty_threshold_is_strict() -> None:
    p = np.array([[0.995, 0.98, 0.2], [1.0, 0.98, 0.9]])
    assert novelty_filter(p, np.ones(2)).tolist() == [False, True, True]
    assert novelty_filter(p, np.ones(2), theta=0.6).tolist() == [False, False, True]


def test_bad_shapes() -> None:
    with pytest.raises(ValueError, match="N = 2"):
        novelty_filter(np.ones((3, 4)), np.ones(2))
    with pytest.raises(ValueError, match="positive sum"):
        entropy_filter(np.ones((2, 2)), np.zeros(2))


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(1, 24),
    spread=st.floats(0.0, 1.0),
    crowd=st.floats(0.0, 1.0),
    sigma=st.floats(0.03, 0.3),
    unknown_blocks=st.booleans(),
)
@pytest.mark.parametrize("caster_cls", [DDACaster, DistanceCaster])
def test_novelty_cast_kernel_matches_the_numpy_filter(
    caster_cls: type[DDACaster],
    seed: int,
    n: int,
    spread: float,
    crowd: float,
    sigma: float,
    unknown_blocks: bool,
) -> None:
    """The fused kernel (ray casts + Eq. 5 + Eq. 6 with early exits) against Eq. 5-6 in numpy on
    the caster's ranges for every hypothesis and beam."""
    rng = np.random.default_rng(seed)
    prob = np.zeros((50, 60), dtype=np.float32)
    prob[:2, :] = prob[-2:, :] = prob[:, :2] = prob[:, -2:] = 1.0
    for _ in range(8):
        r, c = rng.integers(0, 50), rng.integers(0, 60)
        prob[r : r + rng.integers(1, 6), c : c + rng.integers(1, 6)] = 1.0
    prob[rng.integers(5, 40) :][:3, 10:20] = UNKNOWN
    origin = (rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-3, 3))
    grid = OccupancyGrid(prob, resolution=0.1, origin=origin)
    max_range = 4.0
    caster = caster_cls(grid, max_range, unknown_blocks=unknown_blocks)
    centre = grid.grid_to_world(np.array([rng.uniform(1, 5), rng.uniform(1, 4), rng.uniform(-np.pi, np.pi)]))
    laser = centre + rng.normal(0.0, 1.0, (n, 3)) * spread * np.array([0.3, 0.3, 0.3])
    w = rng.uniform(0.01, 1.0, n)
    w = np.sort(w)[::-1]
    angles = np.linspace(-np.pi / 2, np.pi / 2, 37)
    # readings: the first hypothesis's ranges with noise, a share of them shortened (people)
    z = caster.cast(laser[:1], angles)[0].astype(np.float64) + rng.normal(0.0, sigma, angles.size)
    people = rng.random(angles.size) < crowd
    z[people] *= rng.uniform(0.1, 0.9, int(people.sum()))
    z = np.clip(z, 0.0, max_range + 0.5)  # some readings at or beyond the maximum range
    expected = caster.cast(laser, angles)
    p = p_shorter_than_expected(expected, z[None, :], sigma, max_range)
    p_n = novelty_probability(p, w)
    fast = novelty_filter_cast(caster, laser, w, angles, z, sigma, max_range, 0.99)
    decided = np.abs(p_n - 0.99) > 1e-9  # a sum within rounding of theta may go either way
    np.testing.assert_array_equal(fast[decided], novelty_filter(p, w, 0.99)[decided])
