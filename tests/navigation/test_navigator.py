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
