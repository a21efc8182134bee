"""Table 1 of Schulz and Burgard (2001) over a whole log: localization and object states together.

:func:`estimate_log` replays a log: every scan goes to both Monte Carlo localization and the
object estimator (``ScanShare.ALL``, the default: measured better, docs/results/objects.md), or
scan ``k`` goes to localization when ``k`` is even and to the objects when it is odd
(``ScanShare.ALTERNATE``, the paper's loop). MCL integrates every beam of every scan it gets.
The object estimator integrates over MCL's pose samples (the belief, Eq. 8), carried from the
last localization update to the object scan by the odometry in between (the prediction of Eq. 7
without its noise: one scan period of motion). With a given
trajectory instead (``trajectory``), each scan's pose is one sample of weight one. With
``world=True`` the loop is closed: MCL localizes on the map with the objects drawn in their
latest well-observed states (:class:`~tourbot.objects.world.ObjectWorld`, MCL's ``set_map``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose, relative
from tourbot.interfaces import ScanShare
from tourbot.localization.mcl import MCLConfig, MonteCarloLocalization
from tourbot.localization.mcl.clustering import weighted_mean_cov
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.objects import ObjectShape
from tourbot.maps.raycast import DistanceCaster
from tourbot.objects.estimator import ObjectEstimate, ObjectEstimatorConfig, ObjectStateEstimator
from tourbot.objects.world import ObjectWorld
from tourbot.records import RobotLog
from tourbot.runtime.localizers import MCLLocalizer, UpdatePolicy

__all__ = ["ObjectRun", "estimate_log"]

FloatArray = NDArray[np.float64]


@dataclass
class ObjectRun:
    """What a replay produced: every object update, the robot's estimated path, the costs."""

    updates: list[tuple[int, ObjectEstimate]] = field(default_factory=list)  # (scan index, estimate)
    # (t, x, y, theta): the localizer's estimate, carried to the scan by the odometry
    path: list[tuple[float, float, float, float]] = field(default_factory=list)
    path_scans: list[int] = field(default_factory=list)  # the scan index of each pose of ``path``
    path_covariances: list[FloatArray] = field(default_factory=list)  # (3, 3) of x, y, theta, per pose
    update_seconds: list[float] = field(default_factory=list)
    final: list[ObjectEstimate] = field(default_factory=list)
    redraws: int = 0  # how often the world handed MCL a new map (``world=True``)


def estimate_log(
    log: RobotLog,
    shapes: Sequence[ObjectShape],
    grid: OccupancyGrid,
    *,
    config: ObjectEstimatorConfig | None = None,
    share: ScanShare = ScanShare.ALL,
    trajectory: FloatArray | None = None,
    start: Sequence[float] | None = None,
    mcl_config: MCLConfig | None = None,
    seed: int = 0,
    world: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> ObjectRun:
    """Replay ``log``; ``trajectory`` ``(S, 3)`` (one pose per scan) replaces localization.

    Without a trajectory MCL tracks from ``start`` (default: the first scan's reference pose).
    """
    if not log.scans:
        from tourbot.errors import InputError

        raise InputError(f"{log.source}: the log has no scans")
    max_range = max(float(s.geometry.max_range) for s in log.scans)
    caster = DistanceCaster(grid, max_range)
    estimator = ObjectStateEstimator(shapes, caster, config, seed=seed)
    run = ObjectRun()
    localizer: MCLLocalizer | None = None
    objects: ObjectWorld | None = None
    if trajectory is None:
        if start is None:
            start = log.scans[0].reference
        if start is None:
            from tourbot.errors import InputError

            raise InputError(f"{log.source}: no start pose (the log has no reference poses; give one)")
        mcl = MonteCarloLocalization(grid, mcl_config or MCLConfig(), seed=seed)
        mcl.reset_tracking(
            np.asarray(start, dtype=np.float64), np.diag([0.05**2, 0.05**2, math.radians(2.0) ** 2])
        )
        policy = UpdatePolicy(beam_step=1, min_travel=0.0, min_turn=0.0, max_interval=0.0)
        localizer = MCLLocalizer(mcl, policy, seed=seed)
        if world:
            objects = ObjectWorld(grid, shapes, [mcl])
    samples: FloatArray | None = None
    weights: FloatArray | None = None
    track: FloatArray | None = None  # the localizer's estimate at its last update
    belief_odom: FloatArray | None = None
    n = len(log.scans)
    for k, scan in enumerate(log.scans):
        odom = np.asarray(scan.odom if scan.odom is not None else (0.0, 0.0, 0.0), dtype=np.float64)
        for_pose = share == ScanShare.ALL or k % 2 == 0 or samples is None
        for_objects = share == ScanShare.ALL or k % 2 == 1
        if trajectory is not None:
            samples, weights, belief_odom = trajectory[k][None, :], np.ones(1), odom
            track = trajectory[k]
        elif for_pose and localizer is not None:
            belief = localizer.on_scan(scan)
            if belief is not None:
                samples, weights, belief_odom = belief.samples, belief.weights, odom
                e = belief.estimate
                track = np.array([e.x, e.y, e.theta])
        if samples is None or weights is None or belief_odom is None or track is None:
            continue
        # the belief carried to this scan by the odometry since its update (Eq. 7, no noise)
        step = relative(belief_odom, odom)
        here = compose(samples, step) if trajectory is None else samples
        # the path is what the localizer reports (its track), not the mean of its samples
        pose = compose(track, step) if trajectory is None else track
        run.path.append((scan.timestamp, float(pose[0]), float(pose[1]), float(pose[2])))
        run.path_scans.append(k)
        run.path_covariances.append(weighted_mean_cov(here, weights)[1])
        if for_objects:
            before = len(estimator.update_seconds)
            updated = estimator.update(scan, here, weights)
            run.updates.extend((k, est) for est in updated)
            run.update_seconds.extend(estimator.update_seconds[before:])
            if objects is not None and updated:
                objects.update(updated)
        if progress is not None:
            progress(k + 1, n)
    run.final = estimator.estimates()
    run.redraws = objects.redraws if objects is not None else 0
    return run
