"""The Table 1 replay and the odometry rebuilt from the increments of a re-anchored stream."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from tourbot.interfaces import PoseBelief, ScanShare
from tourbot.maps.objects import shapes_of_site
from tourbot.objects.pipeline import estimate_log
from tourbot.records import Scan
from tourbot.runtime.localizers import MCLLocalizer
from tourbot.sim.object_scenes import corridor_scene, run_scene


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
    # each pose of the path names its scan and has the spread of the belief it summarises
    n = len(run.log.scans)
    assert given.path_scans == list(range(n))
    assert np.all(np.array(given.path_covariances) == 0.0)  # a given trajectory: one sample
    for result in (alternate, every):
        assert result.path_scans == sorted(result.path_scans)
        assert len(result.path_scans) == len(result.path) == len(result.path_covariances) >= n - 1
        times = [run.log.scans[k].timestamp for k in result.path_scans]
        assert times == [p[0] for p in result.path]
        cov = np.array(result.path_covariances)
        assert np.all(cov[:, [0, 1, 2], [0, 1, 2]] > 0.0)
        assert np.allclose(cov, cov.transpose(0, 2, 1))
        assert np.sqrt(cov[:, 0, 0]).max() < 0.3


def test_the_loop_closed_hands_mcl_the_doors_as_estimated() -> None:
    scene = corridor_scene(states_deg=(0, 90, 0, 90))
    run = run_scene(replace(scene, drive=[(0.5, 0.0, 0.0), (9.0, 0.7, 0.0)]), seed=2)
    shapes = shapes_of_site(scene.model.doors, scene.model.furniture)
    static = estimate_log(run.log, shapes, scene.model.grid, seed=2)
    closed = estimate_log(run.log, shapes, scene.model.grid, seed=2, world=True)
    assert static.redraws == 0
    # the doors were drawn once observed, and not redrawn at every scan
    assert 1 <= closed.redraws < len(closed.updates) / 4
    ref = run.log.reference_poses
    for result in (static, closed):
        path = np.array(result.path)
        assert np.hypot(*(path[-1, 1:3] - ref[-1, :2])) < 0.1


def test_the_path_is_the_localizers_estimate_and_recoverys_guesses_stay_out(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The bench's pose error is MCL's: the estimate it reports, not the mean of its samples
    (recovery's guesses far away pulled that mean metres off a track that was right)."""
    from tourbot.objects import pipeline

    scene = corridor_scene(states_deg=(0, 45, 90, 30))
    run = run_scene(replace(scene, drive=[(0.5, 0.0, 0.0), (9.0, 0.7, 0.0)]), seed=1)
    ref = run.log.reference_poses
    reported: list[tuple[float, float, float]] = []

    class Recording(MCLLocalizer):
        def on_scan(self, scan: Scan) -> PoseBelief | None:
            if len(reported) == 5:  # guesses offered 6 m ahead, in the corridor's free space
                self.mcl.inject(np.tile([ref[5, 0] + 6.0, 0.0, 0.0], (400, 1)))
            belief = super().on_scan(scan)
            assert belief is not None
            e = belief.estimate
            reported.append((e.x, e.y, e.theta))
            return belief

    monkeypatch.setattr(pipeline, "MCLLocalizer", Recording)
    result = estimate_log(run.log, shapes_of_site(scene.model.doors, []), scene.model.grid, seed=1)
    path = np.array(result.path)[:, 1:]
    assert np.allclose(path, np.array(reported), atol=1e-9)
    assert np.hypot(*(path[:, :2] - ref[: len(path), :2]).T).max() < 0.2
