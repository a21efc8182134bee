"""The fused Eq. 10 kernel against the numpy references."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.maps.beam_model import BeamModel
from tourbot.objects.likelihood import log_likelihoods, log_likelihoods_reference


@settings(max_examples=50, deadline=None)
@given(
    seed=st.integers(0, 100_000),
    n=st.integers(1, 4),
    s=st.integers(1, 6),
    b=st.integers(1, 25),
    short=st.floats(0.0, 0.5),
)
def test_fused_kernel_matches_the_reference(seed: int, n: int, s: int, b: int, short: float) -> None:
    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(-math.pi, math.pi, n)])
    angles = rng.uniform(-math.pi, math.pi, b)
    segs = rng.uniform(-3, 3, (s, 4, 4))
    base = rng.uniform(0.5, 8.0, (n, b))
    measured = np.where(rng.random(b) < 0.1, 8.0, rng.uniform(0.0, 8.0, b))
    model = BeamModel(z_hit=0.8, z_short=short, z_max=0.05, z_rand=0.05, sigma_hit=0.05, lambda_short=0.5)
    fast = log_likelihoods(poses, angles, segs, base, measured, model, 8.0)
    ref = log_likelihoods_reference(poses, angles, segs, base, measured, model, 8.0)
    assert fast.shape == (n, s)
    # the kernel rounds the expected range to float32 as segment_ranges does
    np.testing.assert_allclose(fast, ref, rtol=1e-3, atol=0.05 * b)


def test_the_true_state_is_the_likeliest() -> None:
    from tourbot.maps.objects import ObjectShape

    shape = ObjectShape(
        "d",
        "door",
        np.array([[0, -0.02], [1, -0.02], [1, 0.02], [0, 0.02]]),
        hinge=(2.0, -0.5),
        closed_direction=math.pi / 2,
        low=0.0,
        high=math.pi / 2,
    )
    states = np.radians(np.arange(0, 91, 10.0))[:, None]
    angles = np.radians(np.arange(-40, 41, 1.0))
    base = np.full((1, angles.size), 6.0)
    from tourbot.maps.objects import segment_ranges

    truth = segment_ranges(np.zeros((1, 3)), angles, shape.segments(states[3:4]), base)[0, 0].astype(
        np.float64
    )
    ll = log_likelihoods(
        np.zeros((1, 3)), angles, shape.segments(states), base, truth, BeamModel(sigma_hit=0.03), 10.0
    )
    assert int(np.argmax(ll[0])) == 3
