"""The paper's experiments as simulated scenes: geometry, drive and the recorded truth."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from tourbot.sim.object_scenes import DOOR_STATES_DEG, corridor_scene, desk_scene, run_scene, ushape_scene


def test_corridor_has_fourteen_doors_in_the_papers_states() -> None:
    scene = corridor_scene()
    assert len(scene.world.doors) == 14
    short = replace(scene, drive=[(0.0, 0.0, 0.0), (3.0, 0.7, 0.0)])
    run = run_scene(short, seed=0)
    assert len(run.truth) == len(run.log.scans) == 30
    angles = np.degrees(np.abs([s[0] for s in run.truth[0]]))
    np.testing.assert_allclose(angles, DOOR_STATES_DEG, atol=1e-9)
    # the robot reached 0.7 m/s along the corridor
    ref = run.log.reference_poses
    speed = (ref[-1, 0] - ref[-2, 0]) / (run.times[-1] - run.times[-2])
    assert abs(speed - 0.7) < 0.01
    assert np.allclose(ref[:, 1], 0.0, atol=1e-6)


def test_the_ushape_turns_after_two_passes() -> None:
    scene = ushape_scene()
    t_turn = scene.changes[0][0]
    assert 2 * 10.0 / 0.7 < t_turn < scene.duration - 10.0 / 0.7
    pose0, pose1 = scene.world.furniture[0].poses
    assert math.isclose(math.degrees(pose1[2] - pose0[2]), 30.0)


def test_desks_are_shifted_twenty_centimetres_from_the_model() -> None:
    scene = desk_scene()
    for world, model in zip(scene.world.furniture, scene.model.furniture, strict=True):
        d = math.hypot(world.poses[0][0] - model.poses[0][0], world.poses[0][1] - model.poses[0][1])
        assert math.isclose(d, 0.2, abs_tol=1e-9)
    # the chair is only in the world
    assert scene.world.grid.occupied().sum() > scene.model.grid.occupied().sum()
