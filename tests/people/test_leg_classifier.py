from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.people.scenes import legs_of, scan_with_circles
from tourbot.people.leg_classifier import (
    FEATURE_NAMES,
    MODEL_FEATURES,
    LegModel,
    fit_logistic,
    segment_features,
    segment_features_reference,
)
from tourbot.people.legs import LegConfig, detect_legs, leg_candidates, leg_segments


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**16), beams=st.integers(3, 200), holes=st.floats(0.0, 0.4))
def test_kernel_matches_reference(seed: int, beams: int, holes: float) -> None:
    rng = np.random.default_rng(seed)
    r = np.repeat(rng.uniform(0.5, 8.0, beams // 4 + 1), 4)[:beams] + rng.normal(0.0, 0.01, beams)
    valid = rng.uniform(size=beams) >= holes
    angles = np.linspace(-np.pi / 2, np.pi / 2, beams)
    *_, first, last = leg_segments(r, angles, valid, replace(LegConfig(), model=None, min_probability=0.0))
    np.testing.assert_allclose(
        segment_features(r, angles, valid, first, last),
        segment_features_reference(r, angles, valid, first, last),
        rtol=1e-7,
        atol=1e-9,
    )


def test_a_leg_bulges_towards_the_laser_and_fits_a_circle() -> None:
    scan = scan_with_circles(0.0, (0.0, 0.0, 0.0), [(1.5, 0.0, 0.06)])
    legs, f = leg_candidates(scan, replace(LegConfig(), model=None))
    assert len(legs) == 1
    row = dict(zip(FEATURE_NAMES, f[0], strict=True))
    assert row["bulge"] > 0.01
    assert row["circle_rms"] < 0.005
    assert abs(row["radius"] - 0.06) < 0.02


def test_logistic_fit_separates_and_round_trips(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(400, len(FEATURE_NAMES)))
    col = FEATURE_NAMES.index(MODEL_FEATURES[0])
    y = x[:, col] > 0.3
    model = fit_logistic(x, y, trained_on="synthetic")
    p = model.probability(x)
    assert ((p > 0.5) == y).mean() > 0.95
    model.save(tmp_path / "m.json")
    again = LegModel.load(tmp_path / "m.json")
    np.testing.assert_allclose(again.probability(x), p)
    assert again.trained_on == "synthetic"


def test_a_model_for_other_features_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "m.json"
    path.write_text('{"features": ["width"], "mean": [0], "scale": [1], "weights": [0, 0, 0]}')
    with pytest.raises(ValueError, match="other features"):
        LegModel.load(path)


def test_the_shipped_model_keeps_simulated_legs() -> None:
    scan = scan_with_circles(0.0, (0.0, 0.0, 0.0), legs_of(2.0, 0.5, 1.0, 0.3))
    legs = detect_legs(scan)
    assert LegConfig().model is not None
    assert len(legs) == 2
    assert legs.probability.min() > 0.5


def test_model_from_one_bag_is_more_precise_on_the_other(shared_data: Path) -> None:
    from tourbot.people.leg_training import score_detector, train_leg_model

    folder = shared_data / "leg_tracker"
    model = train_leg_model([folder / "positive_4_extracted.bag"])
    rule = score_detector(folder / "positive_1_extracted.bag", replace(LegConfig(), model=None))
    learnt = score_detector(
        folder / "positive_1_extracted.bag", replace(LegConfig(), model=model), threshold=0.5
    )
    assert learnt.precision > 2.0 * rule.precision
    assert learnt.recall > 0.6
