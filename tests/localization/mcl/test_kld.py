"""KLD-sampling: the bound of Fox 2003, Eq. 13, and the sample count it gives."""

from __future__ import annotations

import math

import numpy as np

from tourbot.localization.mcl.kld import kld_bounds, kld_sample_count


def test_kld_bounds_known_values() -> None:
    # Fox 2003: k = 2 bins, epsilon 0.05, 99 % need about 1e2 samples; the bound grows ~linearly.
    b = kld_bounds(1000, 0.05, 0.99)
    assert b[1] == 1
    assert 40 < b[2] < 120
    assert np.all(np.diff(b[2:]) > 0)
    assert 9000 < b[1000] < 12000


def test_kld_count_grows_with_spread() -> None:
    rng = np.random.default_rng(0)
    tight = rng.normal(0.0, 0.05, (5000, 3))
    wide = np.column_stack([rng.uniform(-20, 20, (5000, 2)), rng.uniform(-math.pi, math.pi, 5000)])
    b = (0.5, 0.5, math.radians(10))
    n_tight = kld_sample_count(tight, b, 0.05, 0.99, 100, 5000)
    n_wide = kld_sample_count(wide, b, 0.05, 0.99, 100, 5000)
    assert n_tight < 300
    assert n_wide == 5000
