"""Annotated leg scans: reading them, scoring detections against them, and training the leg model.

The ``leg_tracker`` project's ``*_extracted`` bags pair each scan (``/training_scan``) with the
positions of the people's leg clusters in it (``/leg_cluster_positions``, laser frame). A
candidate is a leg when it is matched one-to-one (Hungarian assignment) to an annotation within
``match`` metres. :func:`train_leg_model` fits :class:`~tourbot.people.leg_classifier.LegModel` to
the candidates of some bags; score it only on others.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tourbot.people.leg_classifier import FEATURE_NAMES, LegModel, fit_logistic
from tourbot.people.legs import LegConfig, detect_legs, leg_candidates
from tourbot.records import Scan

__all__ = ["DetectionScore", "annotated_scans", "match_points", "score_detector", "train_leg_model"]

FloatArray = NDArray[np.float64]
SCAN_TOPIC = "/training_scan"
ANNOTATION_TOPIC = "/leg_cluster_positions"


def annotated_scans(bag: Path) -> Iterator[tuple[Scan, FloatArray]]:
    """Each scan of an annotated bag with its leg positions ``(L, 2)`` (laser frame); scans
    without an annotation stamped within 1 ms are skipped."""
    from tourbot.io.rosbag import read_bag, read_pose_arrays

    log = read_bag(bag, scan_topic=SCAN_TOPIC)
    notes = read_pose_arrays(bag, ANNOTATION_TOPIC)
    times = np.array([t for t, _ in notes])
    for scan in log.scans:
        if times.size == 0:
            return
        i = int(np.argmin(np.abs(times - scan.timestamp)))
        if abs(times[i] - scan.timestamp) <= 1e-3:
            yield scan, notes[i][1]


def match_points(found: FloatArray, truth: FloatArray, match: float) -> NDArray[np.bool_]:
    """Which of ``found`` ``(M, 2)`` are matched one-to-one to ``truth`` ``(L, 2)`` within ``match``."""
    from scipy.optimize import linear_sum_assignment

    hit = np.zeros(found.shape[0], dtype=bool)
    if found.shape[0] and truth.shape[0]:
        d = np.linalg.norm(found[:, None, :] - truth[None, :, :], axis=-1)
        r, c = linear_sum_assignment(d)
        hit[r[d[r, c] <= match]] = True
    return hit


def train_leg_model(bags: Sequence[Path], *, match: float = 0.25, ridge: float = 1.0) -> LegModel:
    """Fit the leg model to the candidates of annotated ``bags`` that have a shape (at least
    ``LegConfig.model_min_points`` points), labelled by :func:`match_points`."""
    cfg = replace(LegConfig(), model=None)
    xs: list[FloatArray] = []
    ys: list[NDArray[np.bool_]] = []
    for bag in bags:
        for scan, truth in annotated_scans(bag):
            legs, features = leg_candidates(scan, cfg)
            # only the segments the model will score (the others keep the width/contrast rule)
            shaped = features[:, FEATURE_NAMES.index("points")] >= math.log(cfg.model_min_points)
            xs.append(features[shaped])
            ys.append(match_points(legs.points, truth, match)[shaped])
    x = np.concatenate(xs)
    y = np.concatenate(ys)
    names = ", ".join(Path(b).name for b in bags)
    return fit_logistic(
        x, y, ridge=ridge, trained_on=f"{names}: {int(y.sum())} legs, {int((~y).sum())} others"
    )


@dataclass(frozen=True)
class DetectionScore:
    """Precision and recall of a leg detector on one annotated bag."""

    precision: float
    recall: float
    detections: int
    annotated: int
    scans: int


def score_detector(
    bag: Path, config: LegConfig | None = None, *, match: float = 0.25, threshold: float = 0.0
) -> DetectionScore:
    """Precision and recall of :func:`~tourbot.people.legs.detect_legs` with ``config`` on an
    annotated bag, counting detections with P(leg) >= ``threshold``."""
    tp = n_det = n_true = scans = 0
    for scan, truth in annotated_scans(bag):
        legs = detect_legs(scan, config)
        found = legs.points[legs.probability >= threshold]
        n_det += found.shape[0]
        n_true += truth.shape[0]
        tp += int(match_points(found, truth, match).sum())
        scans += 1
    return DetectionScore(
        precision=tp / n_det if n_det else float("nan"),
        recall=tp / n_true if n_true else float("nan"),
        detections=n_det,
        annotated=n_true,
        scans=scans,
    )
