from __future__ import annotations

from typing import Any, cast

import pytest

from tourbot.runtime.loop import Runtime
from tourbot.snapshot import (
    GroundTruth,
    NavigationStatus,
    NavMode,
    PersonState,
    PoseEstimate,
    StateSnapshot,
)
from tourbot.web.runtime_link import RuntimeLink, view_of


def _snapshot(mode: NavMode = NavMode.NAVIGATING, **nav: Any) -> StateSnapshot:
    return StateSnapshot(
        time=12.0,
        step=3,
        source="sim",
        pose=PoseEstimate(1.0, 2.0, 0.5, ((0.01, 0, 0), (0, 0.02, 0), (0, 0, 0.003))),
        people=(PersonState(4, 3.0, 3.0, 0.5, 0.0), PersonState(5, 9.0, 9.0, confirmed=False)),
        navigation=NavigationStatus(mode=mode, path=((1.0, 2.0), (3.0, 2.0)), speed=0.4, **nav),
        truth=GroundTruth(pose=(1.1, 2.0, 0.5), people=(PersonState(77, 0.0, 0.0),)),
    )


def test_view_shows_the_estimate_and_the_confirmed_tracks() -> None:
    view = view_of(_snapshot(blocked_time=4.0, current_exhibit="vase", goal=(3.0, 2.0, 0.0)))
    assert (view.x, view.y, view.theta, view.v) == (1.0, 2.0, 0.5, 0.4)
    assert view.covariance == (0.01, 0.02, 0.003)
    assert [p.id for p in view.people] == [4]  # tentative tracks and the truth are not shown
    assert view.nav.state == "moving"
    assert view.nav.exhibit == "vase"
    assert view.nav.blocked_time == 4.0
    assert view.nav.path == ((1.0, 2.0), (3.0, 2.0))


def test_the_simulators_people_are_never_the_perceived_people() -> None:
    """Without a tracker the view has no people; the simulator's people are debug truth only."""
    snapshot = _snapshot()
    bare = StateSnapshot(
        time=snapshot.time, step=1, source="sim", pose=snapshot.pose, truth=snapshot.truth,
        navigation=NavigationStatus(mode=NavMode.DWELLING, current_exhibit="vase"),
    )  # fmt: skip
    view = view_of(bare)
    assert view.people == ()
    assert [p.id for p in view.truth] == [77]
    assert "simulator" not in view.nav.message
    assert view.nav.state == "arrived"
    assert [p.id for p in view_of(snapshot).truth] == [77]


class _Runtime:
    """Only what RuntimeLink calls (test stand-in)."""

    def __init__(self) -> None:
        self.calls: list[tuple[Any, ...]] = []
        self.mode = NavMode.NAVIGATING

    def step(self) -> StateSnapshot:
        return self.snapshot()

    def snapshot(self) -> StateSnapshot:
        return _snapshot(self.mode)

    def send_goal(self, x: float, y: float, theta: float = 0.0) -> None:
        self.calls.append(("goal", x, y, theta))
        self.mode = NavMode.NAVIGATING

    def start_tour(self, tour: str) -> None:
        self.calls.append(("tour", tour))

    def stop(self) -> None:
        self.calls.append(("stop",))


def test_site_tours_run_on_the_robot_and_web_tours_as_goals() -> None:
    fake = _Runtime()
    link = RuntimeLink(cast(Runtime, fake), site_tours=frozenset({"classic"}), dwell=0.0)
    link.start_tour("classic", [("a", 1.0, 1.0, 0.0)])
    assert fake.calls == [("tour", "classic")]
    link.start_tour("web-only", [("a", 1.0, 1.0, 0.0), ("b", 2.0, 2.0, 1.0)])
    assert fake.calls[-1] == ("goal", 1.0, 1.0, 0.0)
    assert link.view().nav.tour == "web-only"
    assert link.view().nav.exhibit == "a"
    fake.mode = NavMode.FINISHED
    link.step()  # dwell 0: on to the next stop
    assert fake.calls[-1] == ("goal", 2.0, 2.0, 1.0)
    assert link.view().nav.tour_progress == (1, 2)
    fake.mode = NavMode.FINISHED
    link.step()
    assert link.view().nav.tour is None  # done
    link.send_goal(5.0, 5.0, None, "vase")
    assert fake.calls[-1] == ("goal", 5.0, 5.0, 0.0)
    link.stop()
    assert fake.calls[-1:] == [("stop",)]


@pytest.mark.slow
def test_the_simulated_robot_moves_around_an_exhibit() -> None:
    """In the simulated FHW museum (no visitors), "move around this exhibit" takes the robot to
    each viewpoint around the trireme model in turn, facing it, on its own estimate."""
    import math

    from tourbot.app.simulated import SimulationSettings, simulated_runtime
    from tourbot.localization.mcl import MCLConfig
    from tourbot.navigation.around import AroundConfig, exhibit_centre, viewpoints_around
    from tourbot.navigation.navigator import SiteNavigator
    from tourbot.site.default import default_site

    site = default_site()
    exhibit = next(e for e in site.exhibits if e.name == "trireme-model")
    settings = SimulationSettings(crowd="empty", seed=1, mcl=MCLConfig().with_samples(300))
    robot = simulated_runtime(site, settings, start=exhibit.viewing_pose, record=False)
    config = AroundConfig(dwell=0.0)
    link = RuntimeLink(robot.runtime, around_config=config)
    assert isinstance(robot.navigator, SiteNavigator)
    views = viewpoints_around(exhibit.viewing_pose, robot.navigator.costmap, config)
    assert len(views) >= 4
    link.around(exhibit.name, *exhibit.viewing_pose)
    assert link.view().nav.tour == f"around {exhibit.name}"
    reached: list[int] = []  # the viewpoint each arrival was at, in order
    estimate_error: list[float] = []
    while robot.simulator.time < 240.0 and link.view().nav.tour is not None:
        link.step()
        snap = robot.runtime.snapshot()
        if snap.navigation.mode != NavMode.FINISHED:  # arrived at a viewpoint (seen once each)
            continue
        true = robot.simulator.robot.pose
        k = min(range(len(views)), key=lambda i: math.dist(views[i][:2], true[:2]))
        reached.append(k)
        assert snap.pose is not None
        estimate_error.append(math.dist(snap.pose.pose[:2], true[:2]))
        assert math.dist(views[k][:2], true[:2]) < 0.4, (k, true)
        centre = exhibit_centre(exhibit.viewing_pose, config.distance)
        facing = math.atan2(centre[1] - true[1], centre[0] - true[0])
        assert abs(math.remainder(true[2] - facing, 2 * math.pi)) < 0.35
    assert link.view().nav.tour is None, "the robot did not finish going around"
    assert reached == list(range(len(views)))  # every viewpoint, in the sweep's order
    assert max(estimate_error) < 0.3
    print(f"around {exhibit.name}: {len(views)} viewpoints in {robot.simulator.time:.1f} s simulated")
