"""Annotated leg scans: reading them, scoring detections against them, and training the leg model.

The ``leg_tracker`` project's ``*_extracted`` bags pair each scan (``/training_scan``) with the
positions of the people's leg clusters in it (``/leg_cluster_positions``, laser frame). A
candidate is a leg when it is matched one-to-one (Hungarian assignment) to an annotation within
``match`` metres.

What is *not* a leg needs care. That project labels every cluster inside a rectangle of the
laser frame as a leg and takes its negatives from other, people-free recordings: outside the
rectangle the extracted bags say nothing, and the walker's legs are there too, before entering
and after leaving it (in these six recordings 12-176 confident unannotated candidates a
recording move like a walker). A candidate counts as not a leg only where the recording's
background is (:func:`background_share`: the laser has a return within ``BACKGROUND_RADIUS`` of
it in at least ``BACKGROUND_SHARE`` of the recording's scans, as furniture does and no passer-by
does); every other unannotated candidate is unknown and counts neither way, in training as in
scoring. :func:`train_leg_model` fits :class:`~tourbot.people.leg_classifier.LegModel` to the
candidates of some bags; score it only on others.
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
    "BACKGROUND_RADIUS",
    "BACKGROUND_SHARE",
    "THINNING",
    "DetectionScore",
    "HeldOutScore",
    "annotated_scans",
    "background_share",
    "cross_validate",
    "labelled_candidates",
    "match_points",
    "recall_threshold",
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

#: A candidate is background (not a leg) when the laser has a return within this many metres of
#: it in at least ``BACKGROUND_SHARE`` of the recording's scans. In the six recordings the
#: annotated legs' places are occupied in at most 0.3 of the scans but for 15 of 1843 (all in
#: the annotation rectangle, the leg_tracker labels there being every cluster), furniture's in
#: nearly all.
BACKGROUND_RADIUS = 0.10
BACKGROUND_SHARE = 0.5


def background_share(
    scans: Sequence[Scan], points: FloatArray, radius: float = BACKGROUND_RADIUS
) -> FloatArray:
    """For each of ``points`` ``(M, 2)`` (laser frame of a standing laser), the share of ``scans``
    with a return within ``radius`` of it: near 1 for the static background, small where people
    only pass."""
    from scipy.spatial import cKDTree

    hits = np.zeros(points.shape[0])
    if not scans or points.shape[0] == 0:
        return hits
    for scan in scans:
        r = np.asarray(scan.ranges, dtype=np.float64)
        g = scan.geometry
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(r) & (r > max(g.min_range, 1e-6)) & (r < g.max_range)
        a = g.angles[ok]
        if not ok.any():
            continue
        tree = cKDTree(np.stack([r[ok] * np.cos(a), r[ok] * np.sin(a)], -1))
        hits += np.isfinite(tree.query(points, distance_upper_bound=radius)[0])
    return hits / len(scans)


# Training copies of each annotated scan: as recorded, half the beams, a third of them with 1 cm
# more range noise (768 beams over 270 degrees -> 384 and 256: the beam counts of common lasers).
THINNING: tuple[tuple[int, float], ...] = ((1, 0.0), (2, 0.0), (3, 0.01))


def labelled_candidates(
    bag: Path, *, match: float = 0.25, every: int = 1, noise: float = 0.0, seed: int = 0
) -> Labelled:
    """The model's candidates of an annotated bag (seen through :func:`thinned` with ``every``
    and ``noise``): their features ``(S, F)``, whether each is an annotated leg
    (:func:`match_points`), the number of annotated legs, and whether each candidate is unknown:
    not matched, and either within ``match`` of an annotated leg all the same (a piece of a leg
    split in two, or the second leg of a blob) or off the recording's background
    (:func:`background_share` below ``BACKGROUND_SHARE``: outside the annotation rectangle, a
    passer-by's leg as likely as not). The rest, background, are the clusters that are not legs."""
    cfg = replace(LegConfig(), model=None)
    rng = np.random.default_rng(seed)
    recorded: list[Scan] = []
    xs: list[FloatArray] = [np.zeros((0, len(FEATURE_NAMES)))]
    ys: list[NDArray[np.bool_]] = [np.zeros(0, dtype=bool)]
    near: list[NDArray[np.bool_]] = [np.zeros(0, dtype=bool)]
    where: list[FloatArray] = [np.zeros((0, 2))]
    annotated = 0
    for scan, truth in annotated_scans(bag):
        recorded.append(scan)
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
        where.append(legs.points)
        annotated += truth.shape[0]
    y = np.concatenate(ys)
    moving = background_share(recorded, np.concatenate(where)) < BACKGROUND_SHARE
    unknown = np.concatenate(near) | (~y & moving)
    return np.concatenate(xs), y, annotated, unknown


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
    # pieces of legs and unlabelled passers-by are neither legs nor clutter: left out of the training
    keep = ~np.concatenate([p[3] for p in parts])
    x, y = x[keep], y[keep]
    names = ", ".join(Path(b).name for b in bags)
    return fit_boosted(x, y, config, trained_on=f"{names}: {int(y.sum())} legs, {int((~y).sum())} background")


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
    """The leg model trained without one recording, scored on it. ``recall`` (of the annotated
    legs) and ``precision_nonleg`` (against the background clusters, the ones known not to be
    legs: see :func:`labelled_candidates`) at P(leg) >= 0.5; ``precision``: against every other
    candidate, the unlabelled passers-by counted as false (the figure before the background
    labels, a lower bound); ``unknown``: candidates counted neither way. At ``threshold``, the
    P(leg) at which the training recordings reach a recall of 0.9 (chosen without the held-out
    one): ``recall_at_threshold`` and ``precision_at_threshold``. ``precision_at_90``: the best
    precision at a recall of at least 0.9, the threshold set on the held-out recording itself (the
    target's operating point, an upper bound of what a fixed threshold gets). ``thin_*``: the
    held-out recording through :func:`thinned` (half the beams, a laser of 384 beams), at 0.5."""

    held_out: str
    recall: float
    precision: float
    precision_nonleg: float
    precision_at_90: float
    thin_recall: float
    thin_precision_nonleg: float
    annotated: int
    candidates: int
    unknown: int = 0
    threshold: float = 0.5
    recall_at_threshold: float = float("nan")
    precision_at_threshold: float = float("nan")


def _at(p: FloatArray, labelled: Labelled, threshold: float) -> tuple[float, float, float]:
    """Recall, precision against the background, and precision against every other candidate,
    of the candidates with P(leg) >= ``threshold``."""
    _, y, annotated, unknown = labelled
    det = p >= threshold
    tp = int((det & y).sum())
    recall = tp / annotated if annotated else float("nan")
    counted = det & ~unknown
    nonleg = tp / int(counted.sum()) if counted.any() else float("nan")
    every = tp / int(det.sum()) if det.any() else float("nan")
    return recall, nonleg, every


def _scores(p: FloatArray, labelled: Labelled) -> tuple[float, float, float, float]:
    _, y, annotated, unknown = labelled
    recall, nonleg, precision = _at(p, labelled, 0.5)
    order = np.argsort(-p, kind="stable")
    order = order[~unknown[order]]
    found = np.cumsum(y[order])
    need = math.ceil(0.9 * annotated)
    i = int(np.searchsorted(found, need))
    at_90 = need / (i + 1) if annotated and i < found.size else 0.0
    return recall, precision, nonleg, at_90


def recall_threshold(p: FloatArray, labelled: Sequence[Labelled], recall: float = 0.9) -> float:
    """The largest P(leg) threshold at which the candidates ``p`` of ``labelled`` (concatenated)
    reach ``recall`` of their annotated legs."""
    y = np.concatenate([lab[1] for lab in labelled])
    annotated = sum(lab[2] for lab in labelled)
    found = np.sort(p[y])[::-1]
    need = math.ceil(recall * annotated)
    return float(found[need - 1]) if 0 < need <= found.size else 0.0


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
        seen = [_labelled(Path(b), 1, 0.0, match, cache) for b in others]
        threshold = recall_threshold(np.concatenate([model.probability(lab[0]) for lab in seen]), seen)
        full = _labelled(Path(held), 1, 0.0, match, cache)
        p = model.probability(full[0])
        recall, precision, nonleg, at_90 = _scores(p, full)
        at_recall, at_precision, _ = _at(p, full, threshold)
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
                    int(full[3].sum()),
                    threshold,
                    at_recall,
                    at_precision,
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
