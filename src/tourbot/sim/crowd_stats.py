"""How people walk, measured the same way on recorded pedestrians and on the simulated crowd.

From :class:`~tourbot.io.pedestrians.Trajectories` sampled at the recordings' 2.5 Hz: walking
speeds (displacement between consecutive frames), distances to the nearest neighbour in the same
frame, groups (people who stay close and walk in parallel for a while, as the group detectors of
the pedestrian literature define them: Moussaïd et al. 2010, "The walking behaviour of pedestrian
social groups and its impact on crowd dynamics", PLoS ONE 5(4), e10047, where members walk
0.6-1.0 m apart side by side) and standing bouts (runs of frames below a walking speed). The
comparison with a recording is the Wasserstein (earth mover's) distance and the two-sample
Kolmogorov-Smirnov statistic of each distribution (:func:`compare`).

:func:`sample_crowd` steps a :class:`~tourbot.sim.crowd.Crowd` and records it at the same rate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats
from scipy.spatial import cKDTree

from tourbot.io.pedestrians import FRAME_PERIOD, Trajectories
from tourbot.union_find import components

__all__ = [
    "GroupRule",
    "compare",
    "group_sizes",
    "nearest_neighbour_distances",
    "sample_crowd",
    "speeds",
    "standing_bouts",
    "velocities",
]

FloatArray = NDArray[np.float64]

#: Below this speed (m/s over one 0.4 s frame) a person stands.
STANDING_SPEED = 0.2


@dataclass(frozen=True)
class GroupRule:
    """When two people walk together: for at least ``min_frames`` frames in which both walk
    (faster than ``moving``), they are within ``distance`` metres with headings within
    ``heading`` radians, and that holds in at least ``share`` of the frames in which both walk
    and either is within 2 m of the other (Moussaïd et al. 2010: group members 0.6-1.0 m apart,
    side by side; the 4 s at 2.5 Hz keep crossings out)."""

    distance: float = 1.5
    heading: float = np.radians(30.0)
    moving: float = 0.3
    min_frames: int = 10
    share: float = 0.75


def _runs(tr: Trajectories) -> NDArray[np.bool_]:
    """``(M,)``: sample ``k`` and ``k + 1`` are the same person in consecutive frames."""
    same = (tr.ids[1:] == tr.ids[:-1]) & (tr.frames[1:] == tr.frames[:-1] + 1)
    return np.asarray(same, dtype=bool)


def velocities(tr: Trajectories) -> FloatArray:
    """Per sample ``(M, 2)`` m/s: forward difference to the person's next frame, else backward,
    NaN for a person seen in one frame only."""
    out = np.full((len(tr), 2), np.nan)
    if len(tr) < 2:
        return out
    same = _runs(tr)
    step = (tr.xy[1:] - tr.xy[:-1]) / tr.period
    fwd = np.flatnonzero(same)
    out[fwd] = step[fwd]
    back = np.flatnonzero(np.isnan(out[1:, 0]) & same) + 1
    out[back] = step[back - 1]
    return out


def speeds(tr: Trajectories) -> FloatArray:
    """Speeds between consecutive frames of the same person, m/s (every pair once)."""
    if len(tr) < 2:
        return np.zeros(0)
    same = _runs(tr)
    return np.asarray(np.linalg.norm(tr.xy[1:] - tr.xy[:-1], axis=1)[same] / tr.period)


def _frames(tr: Trajectories) -> list[NDArray[np.int64]]:
    """Sample indices of each frame with at least two people."""
    order = np.argsort(tr.frames, kind="stable")
    f = tr.frames[order]
    cuts = np.flatnonzero(np.diff(f)) + 1
    return [g for g in np.split(order, cuts) if len(g) >= 2]


def nearest_neighbour_distances(tr: Trajectories) -> FloatArray:
    """For every sample in a frame with others: the distance to the nearest other person, m."""
    out = [cKDTree(tr.xy[g]).query(tr.xy[g], k=2)[0][:, 1] for g in _frames(tr)]
    return np.concatenate(out) if out else np.zeros(0)


def group_sizes(tr: Trajectories, rule: GroupRule | None = None) -> NDArray[np.int64]:
    """The size of each group of people walking together (singles are groups of 1), by the pairs
    that pass ``rule`` joined transitively."""
    rule = rule or GroupRule()
    vel = velocities(tr)
    speed = np.linalg.norm(vel, axis=1)
    people, person = np.unique(tr.ids, return_inverse=True)
    n = len(people)
    near_keys: list[NDArray[np.int64]] = []
    good_keys: list[NDArray[np.int64]] = []
    for g in _frames(tr):
        pairs = cKDTree(tr.xy[g]).query_pairs(2.0, output_type="ndarray")
        if not len(pairs):
            continue
        a, b = g[pairs[:, 0]], g[pairs[:, 1]]
        walking = (speed[a] > rule.moving) & (speed[b] > rule.moving)
        a, b = a[walking], b[walking]
        d = np.linalg.norm(tr.xy[a] - tr.xy[b], axis=1)
        cos = np.sum(vel[a] * vel[b], axis=1) / (speed[a] * speed[b])
        together = (d <= rule.distance) & (cos >= np.cos(rule.heading))
        pa, pb = np.minimum(person[a], person[b]), np.maximum(person[a], person[b])
        key = pa * n + pb
        near_keys.append(key)
        good_keys.append(key[together])
    if not near_keys:
        return np.ones(n, dtype=np.int64)
    near, near_count = np.unique(np.concatenate(near_keys), return_counts=True)
    good, good_count = np.unique(np.concatenate(good_keys), return_counts=True)
    total = near_count[np.searchsorted(near, good)]
    keep = (good_count >= rule.min_frames) & (good_count >= rule.share * total)
    edges = np.stack([good[keep] // n, good[keep] % n], axis=-1)
    return np.asarray(np.bincount(components(n, edges)), dtype=np.int64)


def standing_bouts(tr: Trajectories, threshold: float = STANDING_SPEED, min_frames: int = 3) -> FloatArray:
    """Durations (s) of the runs of consecutive frames in which a person moves slower than
    ``threshold`` m/s, runs of at least ``min_frames`` frames (shorter ones are the jitter of a
    walker's annotated position)."""
    if len(tr) < 2:
        return np.zeros(0)
    same = _runs(tr)
    slow = same & (np.linalg.norm(tr.xy[1:] - tr.xy[:-1], axis=1) / tr.period < threshold)
    # Runs of True in `slow`.
    padded = np.concatenate([[False], slow, [False]]).astype(np.int8)
    starts = np.flatnonzero(np.diff(padded) == 1)
    ends = np.flatnonzero(np.diff(padded) == -1)
    length = ends - starts
    return np.asarray(length[length >= min_frames] * tr.period, dtype=np.float64)


def standing_share(tr: Trajectories, threshold: float = STANDING_SPEED) -> float:
    """Share of the frame-to-frame steps slower than ``threshold`` m/s."""
    v = speeds(tr)
    return float(np.mean(v < threshold)) if len(v) else float("nan")


def compare(sim: ArrayLike, recorded: ArrayLike) -> tuple[float, float]:
    """Wasserstein-1 distance and two-sample Kolmogorov-Smirnov statistic between two samples."""
    a = np.asarray(sim, dtype=np.float64)
    b = np.asarray(recorded, dtype=np.float64)
    if not len(a) or not len(b):
        return float("nan"), float("nan")
    return float(stats.wasserstein_distance(a, b)), float(stats.ks_2samp(a, b).statistic)


def sample_crowd(
    crowd: object,
    duration: float,
    rng: np.random.Generator,
    robot_pose: ArrayLike,
    period: float = FRAME_PERIOD,
    step: float = 0.1,
) -> Trajectories:
    """Step ``crowd`` (a :class:`~tourbot.sim.crowd.Crowd`) for ``duration`` seconds with the
    robot standing at ``robot_pose`` and record everyone every ``period`` seconds."""
    from tourbot.sim.crowd import Crowd

    assert isinstance(crowd, Crowd)
    pose = np.asarray(robot_pose, dtype=np.float64)
    per_frame = max(1, round(period / step))
    frames, ids, xy = [], [], []
    for k in range(round(duration / period)):
        for _ in range(per_frame):
            crowd.step(period / per_frame, pose, rng)
        n = crowd.num_people
        frames.append(np.full(n, k))
        ids.append(np.arange(n))
        xy.append(crowd.positions)
    if not frames:
        return Trajectories(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 2)), period)
    return Trajectories(np.concatenate(frames), np.concatenate(ids), np.concatenate(xy), period, "sim")
