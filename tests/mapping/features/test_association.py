from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from tourbot.mapping.features.association import string_match, string_match_reference


@settings(max_examples=150, deadline=None)
@given(
    arrays(
        np.float64,
        st.tuples(st.integers(1, 5), st.integers(1, 5)),
        elements=st.one_of(st.just(-np.inf), st.floats(0.01, 10.0)),
    )
)
def test_string_match_is_the_best_order_preserving_pairing(gain: np.ndarray) -> None:
    pairs = string_match(gain)
    i = [a for a, _ in pairs]
    j = [b for _, b in pairs]
    assert i == sorted(set(i))  # one-to-one and order preserving
    assert j == sorted(set(j))
    assert all(np.isfinite(gain[a, b]) and gain[a, b] > 0 for a, b in pairs)
    total = sum(gain[a, b] for a, b in pairs)
    assert np.isclose(total, string_match_reference(gain))


def test_string_match_refuses_a_crossing() -> None:
    # scan features 0, 1 look like map features 1, 0: only one of the crossing pairs can be taken
    gain = np.array([[-np.inf, 5.0], [4.0, -np.inf]])
    assert string_match(gain) == [(0, 1)]
    gain = np.array([[3.0, 1.0, -np.inf], [-np.inf, 3.0, 1.0], [-np.inf, -np.inf, 3.0]])
    assert string_match(gain) == [(0, 0), (1, 1), (2, 2)]


def test_string_match_of_nothing() -> None:
    assert string_match(np.zeros((0, 3))) == []
    assert string_match(np.full((2, 2), -np.inf)) == []
