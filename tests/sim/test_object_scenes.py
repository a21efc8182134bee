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


def test_the_door_halls_join_by_two_doors_and_the_long_way_round() -> None:
    from tourbot.maps.objects import shapes_of_site
    from tourbot.navigation.planner import CostMap
    from tourbot.objects.world import ObjectWorld
    from tourbot.sim.object_scenes import door_tour_site

    site = door_tour_site(period=20.0)
    assert [d.name for d in site.doors] == ["south-door", "north-door"]
    assert all(d.schedule.random and d.schedule.period == 20.0 for d in site.doors)
    assert len(site.tour("crossings").exhibits) == 8
    open_plan = CostMap(site.grid).plan((3.0, 2.6), (17.0, 2.6))
    assert len(open_plan) * 0.1 < 16.0  # straight through the south doorway
    # both doors drawn shut: the only way left is the far passage
    world = ObjectWorld(site.grid, shapes_of_site(site.doors, site.furniture))
    world.drawn = {"south-door": (0.0,), "north-door": (0.0,)}
    shut = CostMap(world.draw()).plan((3.0, 2.6), (17.0, 2.6))
    assert shut[:, 1].max() > 10.4
