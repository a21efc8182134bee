from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.union_find import components, components_reference


@settings(max_examples=100, deadline=None)
@given(
    st.integers(1, 40).flatmap(
        lambda n: st.tuples(
            st.just(n), st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=60)
        )
    )
)
def test_kernel_matches_reference(case: tuple[int, list[tuple[int, int]]]) -> None:
    n, edges = case
    e = np.array(edges, dtype=np.int64).reshape(-1, 2)
    np.testing.assert_array_equal(components(n, e), components_reference(n, e))


def test_labels_in_order_of_first_appearance() -> None:
    labels = components(6, [[4, 5], [1, 3], [3, 5]])
    assert labels.tolist() == [0, 1, 2, 1, 1, 1]
    assert components(3, np.zeros((0, 2))).tolist() == [0, 1, 2]
