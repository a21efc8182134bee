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
