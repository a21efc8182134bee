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

from tourbot.people.leg_classifier import FEATURE_NAMES, BoostConfig, LegModel, fit_boosted
from tourbot.people.legs import LegConfig, LegFeatures, detect_legs, leg_candidates
from tourbot.records import Scan

__all__ = [
    "THINNING",
    "DetectionScore",
    "HeldOutScore",
    "annotated_scans",
    "cross_validate",
    "labelled_candidates",
    "match_points",
    "score_detector",
    "thinned",
    "train_leg_model",
]

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


def thinned(scan: Scan, every: int, noise: float, rng: np.random.Generator) -> Scan:
    """``scan`` as a coarser, noisier laser would see it: every ``every``-th beam, ``noise`` (m)
    of Gaussian range noise added (another laser's beam count, angular resolution and noise)."""
    g = scan.geometry
    r = np.asarray(scan.ranges, dtype=np.float64)[::every].copy()
    if noise > 0.0:
        r = r + rng.normal(0.0, noise, r.shape)
    geometry = replace(g, num_beams=r.shape[0], angle_increment=g.angle_increment * every)
    return replace(scan, ranges=r, geometry=geometry)


Labelled = tuple[FloatArray, NDArray[np.bool_], int, NDArray[np.bool_]]

# Training copies of each annotated scan: as recorded, half the beams, a third of them with 1 cm
# more range noise (768 beams over 270 degrees -> 384 and 256: the beam counts of common lasers).
THINNING: tuple[tuple[int, float], ...] = ((1, 0.0), (2, 0.0), (3, 0.01))


def labelled_candidates(
    bag: Path, *, match: float = 0.25, every: int = 1, noise: float = 0.0, seed: int = 0
) -> Labelled:
    """The model's candidates of an annotated bag (seen through :func:`thinned` with ``every``
    and ``noise``): their features ``(S, F)``, whether each is an annotated leg
    (:func:`match_points`), the number of annotated legs, and whether each candidate that is not
    matched lies within ``match`` of an annotated leg all the same (a piece of a leg split in two,
    or the second leg of a blob: a leg, though not the annotated cluster)."""
    cfg = replace(LegConfig(), model=None)
    rng = np.random.default_rng(seed)
    xs: list[FloatArray] = [np.zeros((0, len(FEATURE_NAMES)))]
    ys: list[NDArray[np.bool_]] = [np.zeros(0, dtype=bool)]
    near: list[NDArray[np.bool_]] = [np.zeros(0, dtype=bool)]
    annotated = 0
    for scan, truth in annotated_scans(bag):
        seen = thinned(scan, every, noise, rng) if every > 1 or noise > 0.0 else scan
        legs, features = leg_candidates(seen, cfg)
        # the segments the model scores (fewer points: the width/contrast rule decides)
        shaped = features[:, FEATURE_NAMES.index("points")] >= math.log(cfg.model_min_points) - 1e-9
        legs = LegFeatures(legs.points[shaped], legs.width[shaped], legs.probability[shaped])
        features = features[shaped]
        xs.append(features)
        hit = match_points(legs.points, truth, match)
        ys.append(hit)
        d = np.linalg.norm(legs.points[:, None, :] - truth[None, :, :], axis=-1)
        near.append(~hit & (d.min(axis=1) <= match if truth.shape[0] else np.zeros(len(hit), dtype=bool)))
        annotated += truth.shape[0]
    return np.concatenate(xs), np.concatenate(ys), annotated, np.concatenate(near)


def train_leg_model(
    bags: Sequence[Path],
    *,
    match: float = 0.25,
    config: BoostConfig | None = None,
    thinning: Sequence[tuple[int, float]] = THINNING,
    cache: dict[tuple[str, int, float], Labelled] | None = None,
) -> LegModel:
    """Fit the leg model to the candidates of annotated ``bags``, labelled by :func:`match_points`,
    each scan seen as recorded and through the coarser lasers of ``thinning`` (:func:`thinned`).
    ``cache`` keeps the labelled candidates of each (bag, thinning) for the next call."""
    parts = [_labelled(Path(b), every, noise, match, cache) for b in bags for every, noise in thinning]
    x = np.concatenate([p[0] for p in parts])
    y = np.concatenate([p[1] for p in parts])
    # pieces of legs are neither legs nor clutter: left out of the training
    keep = ~np.concatenate([p[3] for p in parts])
    x, y = x[keep], y[keep]
    names = ", ".join(Path(b).name for b in bags)
    return fit_boosted(x, y, config, trained_on=f"{names}: {int(y.sum())} legs, {int((~y).sum())} others")


def _labelled(
    bag: Path, every: int, noise: float, match: float, cache: dict[tuple[str, int, float], Labelled] | None
) -> Labelled:
    key = (str(bag), every, noise)
    if cache is not None and key in cache:
        return cache[key]
    out = labelled_candidates(bag, match=match, every=every, noise=noise)
    if cache is not None:
        cache[key] = out
    return out


@dataclass(frozen=True)
class HeldOutScore:
    """The leg model trained without one recording, scored on it at P(leg) >= 0.5: recall (of
    the annotated legs), precision against every other candidate, and precision against the
    clusters that are not legs (``precision_nonleg``: a candidate within the match distance of an
    annotated leg but not matched to it is a piece of a leg, neither right nor wrong), and the
    best precision against the non-leg clusters at a recall of at least 0.9 (the threshold set on
    the held-out recording itself: the target's operating point), as recorded and through
    :func:`thinned` (``thin_*``: half the beams, a laser of 384 beams)."""

    held_out: str
    recall: float
    precision: float
    precision_nonleg: float
    precision_at_90: float
    thin_recall: float
    thin_precision_nonleg: float
    annotated: int
    candidates: int


def _scores(p: FloatArray, labelled: Labelled) -> tuple[float, float, float, float]:
    _, y, annotated, near = labelled
    det = p >= 0.5
    tp = int((det & y).sum())
    recall = tp / annotated if annotated else float("nan")
    precision = tp / int(det.sum()) if det.any() else float("nan")
    counted = det & ~near
    nonleg = tp / int(counted.sum()) if counted.any() else float("nan")
    order = np.argsort(-p, kind="stable")
    order = order[~near[order]]
    found = np.cumsum(y[order])
    need = math.ceil(0.9 * annotated)
    i = int(np.searchsorted(found, need))
    at_90 = need / (i + 1) if annotated and i < found.size else 0.0
    return recall, precision, nonleg, at_90


def cross_validate(
    bags: Sequence[Path],
    *,
    match: float = 0.25,
    config: BoostConfig | None = None,
    thinning: Sequence[tuple[int, float]] = THINNING,
) -> list[tuple[HeldOutScore, LegModel]]:
    """Leave-one-recording-out: for each bag, the model trained on the others, scored on it."""
    cache: dict[tuple[str, int, float], Labelled] = {}
    out = []
    for held in bags:
        others = [b for b in bags if b != held]
        model = train_leg_model(others, match=match, config=config, thinning=thinning, cache=cache)
        full = _labelled(Path(held), 1, 0.0, match, cache)
        recall, precision, nonleg, at_90 = _scores(model.probability(full[0]), full)
        thin = _labelled(Path(held), 2, 0.0, match, cache)
        thin_recall, _, thin_nonleg, _ = _scores(model.probability(thin[0]), thin)
        out.append(
            (
                HeldOutScore(
                    Path(held).name,
                    recall,
                    precision,
                    nonleg,
                    at_90,
                    thin_recall,
                    thin_nonleg,
                    full[2],
                    int(full[1].size),
                ),
                model,
            )
        )
    return out


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
