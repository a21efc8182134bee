"""The viewpoint choice: the pose whose expected beams tell the belief's states apart, near the robot."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from tests.objects.conftest import GEOMETRY
from tourbot.maps.objects import door_shape
from tourbot.maps.raycast import DDACaster
from tourbot.objects.viewpoint import ViewpointConfig, candidate_poses, choose_viewpoint, discrimination
from tourbot.site.model import Site


def test_a_view_through_the_doorway_tells_the_states_apart_a_hidden_one_nothing(room: Site) -> None:
    shape = door_shape(room.doors[0])  # hinge (3.0, 3.975), opening up into the north room
    states = np.linspace(0.0, math.pi / 2, 10)[:, None]
    caster = DDACaster(room.grid, GEOMETRY.max_range)
    cfg = ViewpointConfig()
    front = (3.45, 2.2, math.pi / 2)  # facing the doorway from the south room
    hidden = (0.3, 0.3, 0.0)  # a corner of the south room, the door beyond the wall's end
    oblique = (5.7, 3.7, math.pi)  # along the wall: the leaf seen edge-on at first
    scores, beams = discrimination(shape, states, np.array([front, hidden, oblique]), GEOMETRY, caster, cfg)
    assert scores[0] > 0.9
    assert scores[0] > scores[2]
    assert scores[1] < 0.5 * scores[0]
    assert beams[0] > beams[1]
    # of the rings around the door, the best view sees it well; of two views alike, the nearer wins
    rings = candidate_poses(shape, states, cfg)
    cells = room.grid.world_to_cell(rings[:, :2])
    ok = room.grid.inside(cells)
    inside = np.zeros(len(rings), dtype=bool)
    inside[ok] = room.grid.free()[cells[ok, 0], cells[ok, 1]]
    travel = np.where(inside, 0.0, np.inf)
    best = choose_viewpoint(shape, states, GEOMETRY, caster, travel, rings, cfg)
    assert best is not None
    assert best.discrimination > 0.9
    pair = np.array([front, (front[0], front[1] - 0.4, front[2])])
    near = choose_viewpoint(
        shape, states, GEOMETRY, caster, [9.0, 2.0], pair, replace(cfg, travel_price=0.05)
    )
    assert near is not None
    assert near.pose == pair[1].tolist() or near.travel == 2.0
    assert choose_viewpoint(shape, states, GEOMETRY, caster, [np.inf, np.inf], pair, cfg) is None


def test_the_navigator_goes_to_look_and_the_door_is_then_observed() -> None:
    """An unseen door (its belief the prior over its range): the robot is sent to the viewpoint and
    the estimate, from the scans there, is observed and right."""
    from tourbot.app.simulated import SimulationSettings, simulated_runtime
    from tourbot.localization.mcl import MCLConfig
    from tourbot.objects.estimator import Observation
    from tourbot.objects.runtime import ObjectsEstimator
    from tourbot.objects.viewpoint import inspect_object
    from tourbot.sim.object_scenes import door_tour_site
    from tourbot.snapshot import NavMode

    site = door_tour_site()
    mcl = MCLConfig().with_samples(300)  # MCL's defaults (its measured 5 cm sensor model)
    settings = SimulationSettings(crowd="empty", seed=4, mcl=mcl, objects=True)
    settings = replace(settings, sim=replace(settings.sim, dynamic_objects=False))
    robot = simulated_runtime(site, settings, start=(3.0, 9.0, 0.0), record=False)
    robot.simulator.objects.set_states({0: 0.5})  # the south door half open (-45 degrees)
    rt = robot.runtime
    rt.run(max_time=1.0)
    (objects,) = [e for e in rt.estimators if isinstance(e, ObjectsEstimator)]
    south = objects.estimator.beliefs[0]
    assert south.estimate.quality.status == Observation.UNSEEN  # 7 m away: out of reach
    snap = rt.snapshot()
    assert snap.pose is not None
    view = inspect_object(
        objects.estimator, robot.navigator, "south-door", snap.pose.pose, robot.simulator.laser.geometry
    )
    assert view is not None
    assert view.discrimination > 0.8
    assert robot.navigator.goal == view.pose
    seen = len(objects.history)
    final = rt.run(max_time=60.0, until=lambda s: s.navigation.mode == NavMode.FINISHED)
    assert final.navigation.mode == NavMode.FINISHED
    x, y, _ = robot.simulator.robot.pose
    assert math.hypot(x - view.pose[0], y - view.pose[1]) < 0.4
    rt.run(max_time=2.0)  # looking from there
    there = [e for h in objects.history[seen:] for e in h if e.name == "south-door"][-10:]
    assert sum(e.quality.status == Observation.OBSERVED for e in there) >= 7
    est = south.estimate
    assert abs(est.state[0] - (-math.pi / 4)) < math.radians(5.0)
