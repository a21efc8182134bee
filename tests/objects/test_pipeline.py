"""The Table 1 replay and the odometry rebuilt from the increments of a re-anchored stream."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np

from tourbot.geometry import compose, relative
from tourbot.interfaces import ScanShare
from tourbot.maps.objects import shapes_of_site
from tourbot.objects.pipeline import estimate_log, rebuilt_odometry
from tourbot.records import LaserGeometry, Odometry, RobotLog, Scan
from tourbot.sim.object_scenes import corridor_scene, run_scene


def test_rebuilt_odometry_drops_the_reanchoring_jumps() -> None:
    """A straight drive at 1 m/s with drifting wheels; after each scan the stream restarts at the
    corrected pose (as in the corrected CARMEN logs). The rebuild keeps the drift, drops the jumps."""
    g = LaserGeometry(num_beams=3, angle_min=-0.1, angle_increment=0.1, max_range=10.0)
    odometry, scans = [], []
    raw = np.zeros(3)
    step = np.array([0.1, 0.0, math.radians(0.5)])  # the wheels drift 0.5 deg per 0.1 s
    for i in range(1, 101):
        t = 0.1 * i
        raw = compose(raw, step)
        odometry.append(
            Odometry(t, (float(raw[0]), float(raw[1]), float(raw[2])), tv=1.0, rv=math.radians(5.0))
        )
        if i % 10 == 5:
            truth = (t + 0.01, 0.0, 0.0)
            scans.append(Scan(t + 0.01, np.ones(3), g, odom=tuple(raw), reference=truth))  # type: ignore[arg-type]
            raw = np.array(truth)  # re-anchored onto the corrected pose
    log = RobotLog(source="x", scans=scans, odometry=odometry)
    rebuilt = rebuilt_odometry(log)
    heading = [s.odom[2] for s in rebuilt.scans if s.odom is not None]
    # the heading drift accumulates (0.5 deg a reading), instead of being reset at every scan
    assert heading[-1] > math.radians(40.0)
    odoms = [np.asarray(s.odom) for s in rebuilt.scans]
    steps = [relative(a, b) for a, b in itertools.pairwise(odoms)]
    assert all(abs(float(np.hypot(s[0], s[1])) - 1.0) < 0.05 for s in steps)


def test_replay_with_the_reference_and_with_mcl() -> None:
    scene = corridor_scene(states_deg=(0, 45, 90, 30))
    run = run_scene(replace(scene, drive=[(0.5, 0.0, 0.0), (9.0, 0.7, 0.0)]), seed=1)
    shapes = shapes_of_site(scene.model.doors, scene.model.furniture)
    given = estimate_log(run.log, shapes, scene.model.grid, trajectory=run.log.reference_poses)
    alternate = estimate_log(run.log, shapes, scene.model.grid, share=ScanShare.ALTERNATE)
    every = estimate_log(run.log, shapes, scene.model.grid, share=ScanShare.ALL)
    assert len(every.updates) > 1.5 * len(alternate.updates)
    for result in (given, alternate, every):
        d2 = result.final[1]
        assert abs(abs(d2.state[0]) - math.radians(45.0)) < math.radians(4.0), d2
    # the estimated path follows the corridor
    path = np.array(alternate.path)
    assert np.abs(path[:, 2]).max() < 0.1
