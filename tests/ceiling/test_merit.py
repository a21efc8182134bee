"""The merit function (Alg. 2, Eq. 5): its association conditions, and the compiled kernel
against the numpy reference."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.ceiling.camera import KannalaBrandt
from tourbot.ceiling.merit import associate, merit, merit_fast
from tourbot.ceiling.rig import CeilingCamera

LIGHTS = np.array([[0.0, 0.0, 6.0], [3.0, 0.0, 6.0], [0.0, 4.0, 3.2], [-5.0, -2.0, 10.0]])


def test_association_conditions() -> None:
    proj = np.array([[[10.0, 10.0], [30.0, 10.0], [500.0, 500.0]]])
    seen = np.array([[True, True, True]])
    det = np.array([[11.0, 10.0], [12.0, 10.0], [31.0, 10.0], [200.0, 200.0]])
    match, dist = associate(proj, seen, det, threshold=5.0)
    # detection 0 is the nearest to light 0; detection 1 is not (condition 2); detection 3 is too far
    assert match[0].tolist() == [0, -1, 1, -1]
    assert dist[0, 0] == pytest.approx(1.0)


def test_merit_is_eq_5_with_the_threshold_for_unmatched_detections() -> None:
    cam = CeilingCamera()
    pose = np.array([[0.5, 0.2, 0.3]])
    uv, seen = cam.project_lights(pose, LIGHTS)
    det = np.vstack([uv[0][seen[0]] + [1.0, 0.0], [[5.0, 5.0]]])
    m = merit(cam, LIGHTS, det, pose, threshold=20.0)
    n = int(seen.sum())
    assert m.n[0] == n
    assert m.error[0] == pytest.approx(n * 1.0 + 20.0)
    assert m.value[0] == pytest.approx((n + 20.0) / n)
    far = merit(cam, LIGHTS, det, np.array([[40.0, 40.0, 0.0]]), threshold=20.0)
    assert far.n[0] == 0
    assert math.isinf(far.value[0])


@given(
    x=st.floats(-6.0, 6.0),
    y=st.floats(-6.0, 6.0),
    th=st.floats(-math.pi, math.pi),
    noise=st.floats(0.0, 30.0),
    seed=st.integers(0, 1000),
    kb=st.booleans(),
    pitch=st.floats(-0.3, 0.3),
)
@settings(max_examples=60, deadline=None)
def test_kernel_matches_the_numpy_reference(
    x: float, y: float, th: float, noise: float, seed: int, kb: bool, pitch: float
) -> None:
    model = KannalaBrandt(fx=150.0, fy=152.0, cx=320.0, cy=240.0, k1=0.01) if kb else CeilingCamera().model
    cam = CeilingCamera(model=model, pitch=pitch)
    rng = np.random.default_rng(seed)
    truth = np.array([[x, y, th]])
    uv, seen = cam.project_lights(truth, LIGHTS)
    det = np.vstack(
        [uv[0][seen[0]] + rng.normal(0.0, noise, (int(seen.sum()), 2)), rng.uniform(0, 480, (2, 2))]
    )
    poses = np.vstack([truth, truth + rng.normal(0.0, 0.5, (20, 3))])
    ref = merit(cam, LIGHTS, det, poses, threshold=25.0)
    n, err, value = merit_fast(cam, LIGHTS, det, poses, threshold=25.0)
    assert n.tolist() == ref.n.tolist()
    assert np.allclose(err, ref.error)
    assert np.allclose(value, ref.value)
