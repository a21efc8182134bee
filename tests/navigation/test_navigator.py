"""The navigator's blocked-time accounting: only what the map does not explain blocks the robot."""

from __future__ import annotations

from dataclasses import replace

import pytest

from tourbot.app.demo import start_pose_for
from tourbot.app.simulated import SimulationSettings, simulated_runtime
from tourbot.localization.mcl import MCLConfig
from tourbot.site.default import default_site
from tourbot.snapshot import NavMode, StateSnapshot


@pytest.mark.slow
def test_an_empty_museum_never_blocks_the_robot() -> None:
    """Setting off from a viewing pose near walls and exhibits is slow, but not blocked by people."""
    site = default_site()
    settings = SimulationSettings(crowd="empty", seed=0, mcl=MCLConfig().with_samples(300))
    settings = replace(settings, navigation=replace(settings.navigation, dwell_scale=0.1))
    robot = simulated_runtime(site, settings, start=start_pose_for(site, "short"), record=False)
    robot.runtime.start_tour("short")
    modes: set[NavMode] = set()

    def finished(snapshot: StateSnapshot) -> bool:
        mode = snapshot.navigation.mode
        modes.add(mode)
        return mode in (NavMode.FINISHED, NavMode.FAILED)

    final = robot.runtime.run(max_time=300.0, until=finished)
    assert final.navigation.mode == NavMode.FINISHED
    assert NavMode.BLOCKED not in modes
    assert final.navigation.total_blocked_time == 0.0


def test_published_obstacles_enter_the_plan_and_the_hand_drawn_map_is_optional() -> None:
    from dataclasses import replace as dc_replace

    import numpy as np

    from tourbot.navigation.navigator import NavigationConfig, SiteNavigator
    from tourbot.snapshot import PoseEstimate

    site = default_site()
    with_map = SiteNavigator(site)
    without = SiteNavigator(site, NavigationConfig(hand_drawn=False))
    inv = site.invisible_mask()
    assert with_map.costmap.blocked.sum() > without.costmap.blocked.sum()
    assert inv.any()
    # a wall of published obstacles across the way from A to B makes the path go round it
    start, goal = (1.33, 7.45, 0.95), (2.42, 19.4, 0.0)
    without.send_goal(goal)
    snap = StateSnapshot(time=0.0, step=0, source="test", pose=PoseEstimate(*start))
    without.control(snap, None, 0.1)
    assert without.path is not None
    straight = without.path.copy()
    mid = straight[len(straight) // 2]
    wall = np.array([[mid[0] + dx, mid[1]] for dx in np.arange(-0.6, 0.61, 0.05)])
    blocked = dc_replace(snap, estimators={"vision": {"obstacles": tuple(map(tuple, wall))}})
    without.path = None
    without.control(blocked, None, 0.1)
    assert without.path is not None
    d = np.hypot(*(without.path[:, None, :] - wall[None, :, :]).transpose(2, 0, 1)).min()
    assert d > 0.3  # not through the published obstacles


def test_a_door_found_closed_is_planned_around_and_the_static_map_is_the_fallback() -> None:
    """set_map (the world with the doors as estimated): the plan takes the other doorway; with
    every way shut on the estimated map, the static map's plan (go and look) instead of giving up."""
    import math

    import numpy as np

    from tourbot.maps.grid import OccupancyGrid
    from tourbot.maps.objects import shapes_of_site
    from tourbot.navigation.navigator import SiteNavigator
    from tourbot.objects.estimator import ObjectEstimate, Observation, Quality
    from tourbot.objects.world import ObjectWorld
    from tourbot.sim.object_scenes import door_tour_site
    from tourbot.snapshot import PoseEstimate

    site = door_tour_site()
    nav = SiteNavigator(site)
    world = ObjectWorld(site.grid, shapes_of_site(site.doors, site.furniture), [nav])
    start, goal = (3.0, 2.6, 0.0), (17.0, 2.6, 0.0)
    snap = StateSnapshot(time=0.0, step=0, source="test", pose=PoseEstimate(*start))

    def crossing() -> float:
        """Where the plan crosses the dividing wall (y at x = 10)."""
        assert nav.path is not None
        i = int(np.argmin(np.abs(nav.path[:, 0] - 10.0)))
        return float(nav.path[i, 1])

    nav.send_goal(goal)
    nav.control(snap, None, 0.1)
    assert 2.0 < crossing() < 3.3  # the south door: the short way

    def seen(name: str, angle: float) -> ObjectEstimate:
        return ObjectEstimate(
            name, "door", 0.0, (angle,), (0.01,), Quality(Observation.OBSERVED, 20, 20, 0), 1
        )

    assert world.update([seen("south-door", 0.0), seen("north-door", -math.pi / 2)])
    assert nav.map_changes == 1
    assert nav.path is None  # replans at the next cycle
    nav.control(snap, None, 0.1)
    assert 5.0 < crossing() < 6.3  # the north door
    # the north door closed too: the long way round, by the open passage
    world.update([seen("north-door", 0.0)])
    nav.control(snap, None, 0.1)
    assert crossing() > 10.4
    # every way shut on the estimated map (a wall across the passage as well): the static plan
    blocked = world.grid.prob.copy()
    rc = site.grid.world_to_cell(np.array([[10.02, y] for y in np.arange(10.3, 11.8, 0.02)]))
    blocked[rc[:, 0], rc[:, 1]] = 1.0

    g = world.grid
    nav.set_map(OccupancyGrid(blocked, g.resolution, g.origin, g.occupied_thresh, g.free_thresh))
    nav.control(snap, None, 0.1)
    assert nav.mode != NavMode.FAILED
    assert 2.0 < crossing() < 3.3
