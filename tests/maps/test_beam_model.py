"""The beam model's kernels against its numpy component densities; the novelty filter's Eq. 5."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate

from tourbot.maps.beam_model import (
    BeamModel,
    BeamModelError,
    p_hit,
    p_short,
    p_shorter_than_expected,
)

MAX = 8.0

models = st.builds(
    BeamModel,
    z_hit=st.floats(0.01, 1.0),
    z_short=st.floats(0.0, 1.0),
    z_max=st.floats(0.0, 1.0),
    z_rand=st.floats(0.0, 1.0),
    sigma_hit=st.floats(0.02, 1.0),
    lambda_short=st.floats(0.01, 3.0),
)


@settings(max_examples=60, deadline=None)
@given(model=models, seed=st.integers(0, 10_000))
def test_kernel_matches_reference(model: BeamModel, seed: int) -> None:
    rng = np.random.default_rng(seed)
    expected = rng.uniform(0.0, MAX, (7, 25)).astype(np.float32)
    measured = rng.uniform(-0.5, MAX + 1.0, 25)
    measured[:3] = MAX  # no-return readings
    got = model.probabilities(expected, measured, MAX)
    ref = model.probabilities_reference(expected.astype(np.float64), measured, MAX)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-12)
    nov = model.prob_shorter(expected, measured, MAX)
    nov_ref = p_shorter_than_expected(expected.astype(np.float64), measured, model.sigma_hit, MAX)
    np.testing.assert_allclose(nov, nov_ref, atol=1e-9)


@pytest.mark.parametrize("expected", [0.3, 4.0, 7.9])
def test_mixture_integrates_to_one(expected: float) -> None:
    model = BeamModel()
    dens, _ = integrate.quad(
        lambda z: float(model.probabilities_reference(expected, z, MAX)),
        0.0,
        MAX,
        points=[expected],
        limit=200,
    )
    point_mass = model.weights[2]  # p_max at z = MAX
    assert dens + point_mass == pytest.approx(1.0, abs=1e-6)
    assert float(
        integrate.quad(lambda z: float(p_hit(expected, z, 0.2, MAX)), 0, MAX, points=[expected])[0]
    ) == (pytest.approx(1.0, abs=1e-6))
    assert float(integrate.quad(lambda z: float(p_short(expected, z, 0.5)), 0, expected)[0]) == pytest.approx(
        1.0
    )


def test_shorter_than_expected_behaves_like_fig2() -> None:
    # Fox et al. 1998 Fig. 2: ~1 well before the expected distance, ~0 well after, 0.5 at it
    e = np.array([[4.0, 4.0, 4.0, 4.0]], dtype=np.float32)
    z = np.array([1.0, 4.0, 6.0, MAX])
    p = BeamModel(sigma_hit=0.2).prob_shorter(e, z, MAX)[0]
    assert p[0] == pytest.approx(1.0, abs=1e-9)
    assert p[1] == pytest.approx(0.5, abs=1e-6)
    assert p[2] == pytest.approx(0.0, abs=1e-9)
    assert p[3] == 0.0
    # monotone non-increasing in the reading
    zs = np.linspace(0, MAX, 200)
    ps = p_shorter_than_expected(np.full(200, 3.0), zs, 0.3, MAX)
    assert np.all(np.diff(ps) <= 1e-12)


def test_bad_parameters_and_shapes() -> None:
    with pytest.raises(BeamModelError):
        BeamModel(z_hit=-1.0)
    with pytest.raises(BeamModelError):
        BeamModel(sigma_hit=0.0)
    with pytest.raises(BeamModelError):
        BeamModel().probabilities(np.zeros((2, 3)), np.zeros(4), MAX)
