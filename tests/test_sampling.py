from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from tourbot.sampling import (
    systematic_resample,
    systematic_resample_reference,
    systematic_resample_rows,
    systematic_resample_rows_reference,
)


@settings(max_examples=100, deadline=None)
@given(
    arrays(np.float64, st.integers(1, 60), elements=st.floats(0.0, 1.0)),
    st.integers(1, 80),
    st.floats(0, 0.999),
    st.booleans(),
)
def test_kernel_matches_reference(w: np.ndarray, n: int, u0: float, sparse: bool) -> None:
    w = w.copy()
    if sparse:
        w[w < 0.7] = 0.0
    w[0] += 1e-3
    idx = systematic_resample(w, n, u0)
    np.testing.assert_array_equal(idx, systematic_resample_reference(w, n, u0))
    assert np.all(w[idx] > 0.0)  # a sample without weight is never drawn


def test_draws_are_proportional_to_the_weights() -> None:
    w = np.array([0.1, 0.0, 0.6, 0.3])
    counts = np.bincount(systematic_resample(w, 1000, 0.37), minlength=4)
    assert counts.tolist() == [100, 0, 600, 300]


def test_unnormalised_weights_are_fine() -> None:
    np.testing.assert_array_equal(systematic_resample([2.0, 2.0], 4, 0.5), [0, 0, 1, 1])


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**16), k=st.integers(1, 3), n=st.integers(1, 40), sparse=st.booleans())
def test_rows_match_reference(seed: int, k: int, n: int, sparse: bool) -> None:
    rng = np.random.default_rng(seed)
    w = rng.uniform(0.0, 1.0, (k, n))
    if sparse:
        w[rng.uniform(size=(k, n)) < 0.7] = 0.0
        w[:, 0] += 1e-3
    w /= w.sum(axis=1, keepdims=True)
    offsets = rng.uniform(0.0, 1.0, k)
    idx = systematic_resample_rows(w, offsets)
    np.testing.assert_array_equal(idx, systematic_resample_rows_reference(w, offsets))
    assert np.all(np.take_along_axis(w, idx, axis=1) > 0.0)


def test_a_row_keeps_its_only_weighted_sample() -> None:
    w = np.zeros((1, 5))
    w[0, 3] = 1.0
    assert systematic_resample_rows(w, np.array([0.7])).tolist() == [[3, 3, 3, 3, 3]]
