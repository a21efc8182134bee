from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.people.motion import WalkingModel, predict_samples, predict_samples_reference

NO_NOISE = np.array([[[0.0, 0.0, 0.0, 0.0, 1.0]]])  # no acceleration, no jitter, no manoeuvre


@settings(max_examples=40, deadline=None)
@given(
    k=st.integers(1, 4),
    n=st.integers(1, 30),
    dt=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**16),
    accel=st.floats(0.0, 3.0),
    share=st.floats(0.0, 1.0),
)
def test_kernel_matches_reference(k: int, n: int, dt: float, seed: int, accel: float, share: float) -> None:
    rng = np.random.default_rng(seed)
    samples = rng.normal(0.0, 2.0, (k, n, 4))
    model = WalkingModel(accel_std=accel, max_speed=1.5, manoeuvre_probability=share)
    noise = model.noise(rng, (k, n))
    np.testing.assert_allclose(
        predict_samples(samples, noise, dt, model),
        predict_samples_reference(samples, noise, dt, model),
        rtol=1e-12,
        atol=1e-12,
    )


def test_without_noise_people_keep_walking() -> None:
    samples = np.array([[[1.0, 2.0, 0.5, -1.0]]])
    out = predict_samples(samples, NO_NOISE, 0.4, WalkingModel())
    np.testing.assert_allclose(out[0, 0], [1.2, 1.6, 0.5, -1.0])


def test_speed_is_capped() -> None:
    samples = np.array([[[0.0, 0.0, 5.0, 0.0]]])
    out = predict_samples(samples, NO_NOISE, 0.1, WalkingModel(max_speed=2.0))
    assert np.hypot(out[0, 0, 2], out[0, 0, 3]) == np.float64(2.0)


def test_samples_spread_out_without_correction() -> None:
    rng = np.random.default_rng(0)
    model = WalkingModel()
    s = np.zeros((1, 500, 4))
    spreads = []
    for _ in range(10):
        s = predict_samples(s, model.noise(rng, (1, 500)), 0.1, model)
        spreads.append(float(s[0, :, 0:2].std()))
    assert all(b > a for a, b in itertools.pairwise(spreads))


def test_manoeuvring_samples_take_the_larger_acceleration() -> None:
    samples = np.zeros((1, 2, 4))
    noise = np.array([[[1.0, 0.0, 0.0, 0.0, 0.05], [1.0, 0.0, 0.0, 0.0, 0.5]]])
    model = WalkingModel(accel_std=1.0, manoeuvre_probability=0.1, manoeuvre_accel_std=5.0)
    out = predict_samples(samples, noise, 0.1, model)
    np.testing.assert_allclose(out[0, :, 2], [0.5, 0.1])


def test_a_share_of_samples_manoeuvres() -> None:
    rng = np.random.default_rng(1)
    model = WalkingModel(manoeuvre_probability=0.1, manoeuvre_accel_std=5.0)
    out = predict_samples(np.zeros((1, 20000, 4)), model.noise(rng, (1, 20000)), 0.5, model)
    speed = np.hypot(out[0, :, 2], out[0, :, 3])
    # In 0.5 s a smooth walker passes 1.9 m/s with probability e^-7.2, a manoeuvring one 0.75.
    assert 0.05 < np.mean(speed > 1.9) < 0.12
