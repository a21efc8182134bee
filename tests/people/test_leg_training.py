from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from tests.people.scenes import legs_of, scan_with_circles
from tourbot.people.leg_classifier import BoostConfig
from tourbot.people.leg_training import (
    BACKGROUND_SHARE,
    background_share,
    cross_validate,
    labelled_candidates,
    recall_threshold,
    thinned,
)
from tourbot.people.legs import LegConfig, leg_candidates


def test_a_thinned_scan_is_the_same_scene_with_fewer_beams() -> None:
    scan = scan_with_circles(0.0, (0.0, 0.0, 0.0), legs_of(2.0, 0.5, 1.0, 0.3))
    coarse = thinned(scan, 3, 0.0, np.random.default_rng(0))
    assert coarse.geometry.num_beams == coarse.ranges.shape[0] == -(-scan.geometry.num_beams // 3)
    np.testing.assert_allclose(coarse.geometry.angles, scan.geometry.angles[::3], atol=1e-12)
    cfg = replace(LegConfig(), model=None)
    fine_legs, _ = leg_candidates(scan, cfg, with_features=False)
    coarse_legs, _ = leg_candidates(coarse, cfg, with_features=False)
    assert len(coarse_legs) == len(fine_legs) == 2  # the same two legs, seen with a third of the beams
    d = np.linalg.norm(coarse_legs.points[:, None] - fine_legs.points[None], axis=-1).min(axis=1)
    assert d.max() < 0.03
    noisy = thinned(scan, 1, 0.01, np.random.default_rng(0))
    assert 0.005 < float(np.std(noisy.ranges - scan.ranges)) < 0.015


def test_cross_validation_scores_each_recording_with_a_model_that_did_not_see_it(shared_data: Path) -> None:
    folder = shared_data / "leg_tracker"
    bags = [folder / "positive_1_extracted.bag", folder / "positive_2_extracted.bag"]
    folds = cross_validate(bags, config=BoostConfig(rounds=40), thinning=((1, 0.0),))
    assert [s.held_out for s, _ in folds] == [b.name for b in bags]
    for (score, model), other in zip(folds, reversed(bags), strict=True):
        assert model.trained_on.startswith(other.name)  # trained on the other recording only
        assert score.annotated > 100
        assert 0.0 < score.recall <= 1.0
        assert 0.0 < score.precision <= score.precision_nonleg <= 1.0
        assert 0 < score.unknown < score.candidates
        assert 0.0 < score.threshold < 1.0
        assert 0.0 < score.recall_at_threshold <= 1.0
        # far better than calling every candidate a leg
        assert score.precision_at_90 > 2.0 * score.annotated / score.candidates


def test_the_background_is_where_the_laser_sees_something_in_most_scans() -> None:
    chair = (1.0, -1.5, 0.02)
    scans = [
        scan_with_circles(0.1 * k, (0.0, 0.0, 0.0), [chair, *legs_of(-3.0 + 0.3 * k, 1.0, 0.0, 0.0)])
        for k in range(20)
    ]
    share = background_share(scans, np.array([[1.0, -1.5], [0.0, 0.86], [5.0, 5.0]]))
    assert share[0] == 1.0  # the chair leg, in every scan
    assert 0.0 < share[1] < BACKGROUND_SHARE  # the walker passes there once
    assert share[2] == 0.0  # nothing there ever
    assert background_share([], np.zeros((2, 2))).tolist() == [0.0, 0.0]


def test_the_recall_threshold_keeps_that_share_of_the_annotated_legs() -> None:
    y = np.array([True, True, True, True, False, False])
    p = np.array([0.9, 0.8, 0.7, 0.2, 0.95, 0.1])
    lab = (np.zeros((6, 1)), y, 5, np.zeros(6, dtype=bool))  # one annotated leg was never a candidate
    assert recall_threshold(p, [lab], 0.6) == 0.7  # 3 of 5
    assert recall_threshold(p, [lab], 0.8) == 0.2  # 4 of 5
    assert recall_threshold(p, [lab], 1.0) == 0.0  # out of reach: every candidate


def test_unannotated_candidates_off_the_background_count_neither_way(shared_data: Path) -> None:
    bag = shared_data / "leg_tracker" / "positive_6_extracted.bag"
    _, legs, annotated, unknown = labelled_candidates(bag)
    assert not (legs & unknown).any()
    # the walker outside the annotation rectangle: a few hundred candidates, not the furniture
    assert 50 < int(unknown.sum()) < 0.2 * len(legs)
    assert int(legs.sum()) > 0.9 * annotated
