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
    BoostConfig,
    LegModel,
    LegModelError,
    default_model,
    fit_boosted,
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


def test_boosted_fit_separates_and_round_trips(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(600, len(FEATURE_NAMES)))
    a, b = (FEATURE_NAMES.index(n) for n in MODEL_FEATURES[:2])
    y = (x[:, a] > 0.3) & (x[:, b] < 0.5)  # an interaction a logistic model of the features misses
    model = fit_boosted(x, y, BoostConfig(rounds=60), trained_on="synthetic")
    p = model.probability(x)
    assert ((p > 0.5) == y).mean() > 0.95
    model.save(tmp_path / "m.json")
    again = LegModel.load(tmp_path / "m.json")
    np.testing.assert_allclose(again.probability(x), p)
    assert again.trained_on == "synthetic"


def test_the_model_reads_the_named_features_only() -> None:
    # P(leg) does not depend on the number of points or the range: they are no part of the model.
    model = default_model()
    assert model is not None
    rng = np.random.default_rng(1)
    x = rng.normal(size=(50, len(FEATURE_NAMES)))
    y = x.copy()
    y[:, FEATURE_NAMES.index("points")] += 3.0
    y[:, FEATURE_NAMES.index("range")] += 5.0
    np.testing.assert_array_equal(model.probability(x), model.probability(y))


def test_a_model_for_other_features_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "m.json"
    path.write_text('{"features": ["width"], "kind": "boosted-trees"}')
    with pytest.raises(LegModelError, match="other features") as exc:
        LegModel.load(path)
    assert exc.value.path == str(path)
    assert exc.value.field == "features"


def _shipped_doc() -> dict[str, object]:
    import json

    from tourbot.people.leg_classifier import DEFAULT_MODEL

    doc = json.loads(DEFAULT_MODEL.read_text())
    assert isinstance(doc, dict)
    return doc


@pytest.mark.parametrize(
    ("change", "field", "message"),
    [
        ({"kind": "logistic"}, "kind", "not a boosted-trees leg model"),
        ({"depth": 0}, "depth", "integer from 1 to 8"),
        ({"bias": "x"}, "bias", "finite number"),
        ({"leaf_value": [[0.0, 1.0]]}, "leaf_value", "trees of {leaves} numbers"),
        ({"split_feature": None}, "split_feature", "feature indices"),
        ({"split_value": None}, "split_value", "trees of {internal} numbers"),
        ({"features": None}, "features", "other features"),
    ],
)
def test_a_bad_model_file_names_the_file_and_field(
    tmp_path: Path, change: dict[str, object], field: str, message: str
) -> None:
    import json

    path = tmp_path / "m.json"
    doc = _shipped_doc() | change
    depth = doc["depth"] if isinstance(doc["depth"], int) and doc["depth"] > 0 else 1
    internal = 2**depth - 1
    if field == "split_feature":  # as many trees as the other tables, an index out of range
        trees = doc["leaf_value"]
        assert isinstance(trees, list)
        doc["split_feature"] = [[99] * internal for _ in trees]
    path.write_text(json.dumps(doc))
    with pytest.raises(LegModelError, match=message.format(leaves=internal + 1, internal=internal)) as exc:
        LegModel.load(path)
    assert exc.value.path == str(path)
    assert exc.value.field == field


def test_a_model_file_that_is_not_json_names_the_line(tmp_path: Path) -> None:
    path = tmp_path / "m.json"
    path.write_text('{\n "features": [\n oops')
    with pytest.raises(LegModelError, match="not JSON") as exc:
        LegModel.load(path)
    assert exc.value.line == 3
    with pytest.raises(LegModelError, match="no such leg model file"):
        LegModel.load(tmp_path / "missing.json")


def test_save_writes_whole_and_leaves_no_partial_file(tmp_path: Path) -> None:
    model = default_model()
    assert model is not None
    out = tmp_path / "sub" / "m.json"
    model.save(out)
    assert [p.name for p in out.parent.iterdir()] == ["m.json"]
    assert LegModel.load(out) == model


def test_a_stricter_model_from_a_file_changes_the_detections(tmp_path: Path) -> None:
    """A model loaded from a file, not the shipped one, decides P(leg) when given to LegConfig."""
    shipped = default_model()
    assert shipped is not None
    # the same trees from far lower log odds: no segment is a leg any more
    strict = replace(shipped, bias=shipped.bias - 40.0, trained_on="strict")
    strict.save(tmp_path / "strict.json")
    loaded = LegModel.load(tmp_path / "strict.json")
    assert loaded == strict
    scan = scan_with_circles(0.0, (0.0, 0.0, 0.0), legs_of(2.0, 0.5, 1.0, 0.3))
    assert len(detect_legs(scan)) == 2
    assert len(detect_legs(scan, replace(LegConfig(), model=loaded))) == 0


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
