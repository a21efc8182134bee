"""Local NCC from box filters, and the patch NCC of the epipolar search."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.vision.correlation import local_ncc, patch_ncc


def test_local_ncc_is_one_for_a_gain_and_offset_and_minus_one_inverted() -> None:
    rng = np.random.default_rng(1)
    a = rng.normal(100, 20, (50, 50)).astype(np.float32)
    ncc, sa, sb = local_ncc(a, 1.3 * a + 7.0, 9)
    assert np.allclose(ncc[5:-5, 5:-5], 1.0, atol=1e-3)
    assert np.allclose(sb[5:-5, 5:-5], 1.3 * sa[5:-5, 5:-5], rtol=1e-3)
    inv, _, _ = local_ncc(a, -a, 9)
    assert np.allclose(inv[5:-5, 5:-5], -1.0, atol=1e-3)


@given(st.integers(0, 10_000))
@settings(max_examples=25, deadline=None)
def test_patch_ncc_agrees_with_the_direct_formula(seed: int) -> None:
    rng = np.random.default_rng(seed)
    a = rng.normal(0, 1, (3, 25)).astype(np.float32)
    b = rng.normal(0, 1, (3, 4, 25)).astype(np.float32)
    got = patch_ncc(a, b)
    for m in range(3):
        for k in range(4):
            ref = np.corrcoef(a[m], b[m, k])[0, 1]
            assert abs(got[m, k] - ref) < 1e-4


def test_local_ncc_matches_patch_ncc_at_a_pixel() -> None:
    rng = np.random.default_rng(2)
    a = rng.normal(0, 1, (30, 30)).astype(np.float32)
    b = (a + rng.normal(0, 1, (30, 30))).astype(np.float32)
    ncc, _, _ = local_ncc(a, b, 5)
    pa = a[10:15, 10:15].reshape(1, 25)
    pb = b[10:15, 10:15].reshape(1, 1, 25)
    assert abs(float(ncc[12, 12]) - float(patch_ncc(pa, pb)[0, 0])) < 1e-3
