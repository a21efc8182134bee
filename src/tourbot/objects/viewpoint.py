"""Where to look from: the viewpoint that best tells an uncertain object's states apart.

Beyond Schulz and Burgard (2001, their future work): when an object's estimate is poor (never
seen, occluded, seen edge-on), the robot can go and look. Candidate robot poses stand on rings
around the object, facing it. For each, the sensor simulation of :mod:`tourbot.maps.objects`
(the static map's cast lowered to the object's outline) gives the expected ranges of the beams
on the object in each of a few of its belief's state samples; the view's *discrimination* is the
share of pairs of those states that at least ``min_beams`` beams tell apart by more than
``tolerance``: 1 when every state the belief still holds would read differently, 0 when the
object is hidden behind a wall or the states look alike from there. The chosen viewpoint
maximises discrimination less a small price per metre of travel on the navigator's plan (one
Dijkstra from the robot), so of two views alike the nearer wins. :func:`inspect_object` hands
it to the navigator as a goal.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose
from tourbot.maps.objects import ObjectShape, beam_window, distance_to_segments, segment_ranges
from tourbot.maps.raycast import RayCaster
from tourbot.navigation.navigator import SiteNavigator
from tourbot.objects.estimator import ObjectStateEstimator
from tourbot.records import LaserGeometry

__all__ = [
    "Viewpoint",
    "ViewpointConfig",
    "candidate_poses",
    "choose_viewpoint",
    "discrimination",
    "inspect_object",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ViewpointConfig:
    """``distances`` (m) and ``bearings`` of the candidate rings around the object's centre;
    ``states``: belief samples compared (pairs: states * (states - 1) / 2); ``tolerance`` (m) and
    ``min_beams``: two states are told apart when that many beams differ by more than that (the
    estimator's 3 sigma is 9 cm; more here, for the pose error on arrival); ``travel_price``:
    discrimination given up per metre of travel; ``clearance`` (m): a candidate this close to the
    object in any of the states is left out (the robot would stand in a door's swing)."""

    distances: tuple[float, ...] = (1.2, 1.8, 2.6, 3.3)
    bearings: int = 24
    states: int = 16
    tolerance: float = 0.12
    min_beams: int = 5
    travel_price: float = 0.01
    clearance: float = 0.7


@dataclass(frozen=True)
class Viewpoint:
    """A robot pose to look from, the share of state pairs it tells apart, its beams on the object
    (those whose expected range differs between the states) and the travel to get there (m)."""

    pose: tuple[float, float, float]
    discrimination: float
    beams: int
    travel: float


def candidate_poses(shape: ObjectShape, states: FloatArray, config: ViewpointConfig) -> FloatArray:
    """Poses ``(K, 3)`` on rings around the centre of the states' outlines, each facing it, at least
    ``clearance`` from the object in every state."""
    boxes = shape.boxes(states)
    cx = 0.5 * (boxes[:, 0].min() + boxes[:, 2].max())
    cy = 0.5 * (boxes[:, 1].min() + boxes[:, 3].max())
    bearing = np.linspace(-math.pi, math.pi, config.bearings, endpoint=False)
    d = np.asarray(config.distances, dtype=np.float64)
    b, r = np.meshgrid(bearing, d)
    x, y = cx + r.ravel() * np.cos(b.ravel()), cy + r.ravel() * np.sin(b.ravel())
    edges = shape.segments(states)
    clear = np.array(
        [distance_to_segments(px, py, edges) >= config.clearance for px, py in zip(x, y, strict=True)]
    )
    x, y = x[clear], y[clear]
    return np.column_stack([x, y, np.arctan2(cy - y, cx - x)])


def discrimination(
    shape: ObjectShape,
    states: FloatArray,
    poses: FloatArray,
    geometry: LaserGeometry,
    caster: RayCaster,
    config: ViewpointConfig,
) -> tuple[FloatArray, NDArray[np.int64]]:
    """Per robot pose ``(K, 3)``: the share of pairs of ``states`` ``(S, dim)`` that the view tells
    apart, and the number of beams on the object whose expected range differs between states."""
    s = np.asarray(states, dtype=np.float64).reshape(-1, shape.dim)
    lasers = compose(np.asarray(poses, dtype=np.float64).reshape(-1, 3), np.asarray(geometry.offset))
    segs = shape.segments(s)
    boxes = shape.boxes(s)
    pairs = np.triu(np.ones((s.shape[0], s.shape[0]), dtype=bool), k=1)
    n_pairs = max(1, int(pairs.sum()))
    scores = np.zeros(lasers.shape[0])
    beams = np.zeros(lasers.shape[0], dtype=np.int64)
    for k, laser in enumerate(lasers):
        window = beam_window(
            laser[None], boxes, geometry.angle_min, geometry.angle_increment, geometry.num_beams
        )
        if window.size == 0:
            continue
        angles = geometry.angles[window]
        base = caster.cast(laser[None], angles).astype(np.float64)
        expected = segment_ranges(laser[None], angles, segs, base)[0].astype(np.float64)  # (S, W)
        differ = np.abs(expected[:, None, :] - expected[None, :, :]) > config.tolerance  # (S, S, W)
        told = differ.sum(axis=2) >= config.min_beams
        scores[k] = float((told & pairs).sum()) / n_pairs
        beams[k] = int(((expected.max(axis=0) - expected.min(axis=0)) > config.tolerance).sum())
    return scores, beams


def choose_viewpoint(
    shape: ObjectShape,
    states: FloatArray,
    geometry: LaserGeometry,
    caster: RayCaster,
    travel: Sequence[float] | FloatArray,
    candidates: FloatArray,
    config: ViewpointConfig | None = None,
) -> Viewpoint | None:
    """The best of ``candidates`` ``(K, 3)`` (``travel`` ``(K,)`` metres to each, inf where it
    cannot be reached); None when none is reachable or none sees the object at all."""
    cfg = config or ViewpointConfig()
    cost = np.asarray(travel, dtype=np.float64)
    ok = np.isfinite(cost)
    if not ok.any():
        return None
    poses = np.asarray(candidates, dtype=np.float64)[ok]
    scores, beams = discrimination(shape, states, poses, geometry, caster, cfg)
    if not (beams > 0).any():
        return None
    utility = scores - cfg.travel_price * cost[ok]
    utility[beams == 0] = -np.inf
    k = int(np.argmax(utility))
    pose = (float(poses[k, 0]), float(poses[k, 1]), float(poses[k, 2]))
    return Viewpoint(pose, float(scores[k]), int(beams[k]), float(cost[ok][k]))


def inspect_object(
    estimator: ObjectStateEstimator,
    navigator: SiteNavigator,
    name: str,
    robot: Sequence[float],
    geometry: LaserGeometry,
    config: ViewpointConfig | None = None,
    seed: int = 0,
) -> Viewpoint | None:
    """Choose where to look at object ``name`` from (its belief's states, the navigator's map and
    plan from the robot's estimated pose ``robot``) and send the navigator there; None (and no
    goal) when no reachable pose sees it."""
    cfg = config or ViewpointConfig()
    names = [s.name for s in estimator.shapes]
    if name not in names:
        from tourbot.errors import TourbotError

        raise TourbotError(f"no object named {name!r}; the site has {', '.join(names) or 'none'}")
    i = names.index(name)
    shape, belief = estimator.shapes[i], estimator.beliefs[i]
    rng = np.random.default_rng(seed)
    pick = rng.choice(belief.samples.shape[0], size=min(cfg.states, belief.samples.shape[0]), replace=False)
    states = belief.samples[pick]
    candidates = candidate_poses(shape, states, cfg)
    costmap = navigator.costmap
    field = costmap.field(np.asarray(robot, dtype=np.float64)[:2])  # cost-to-go from the robot (symmetric)
    travel = np.full(candidates.shape[0], np.inf)
    for k, c in enumerate(candidates):
        if costmap.traversable(c):
            r, col = costmap.cell(c)
            travel[k] = field[r, col] * costmap.resolution
    view = choose_viewpoint(shape, states, geometry, estimator.caster, travel, candidates, cfg)
    if view is not None:
        navigator.send_goal(view.pose)
    return view
