"""What the hub publishes to every viewer: steady navigation status, no running counters."""

from __future__ import annotations

import json
from typing import Any

import pytest

from tests.web.fakes import FakeRobot
from tourbot.web.db import Database
from tourbot.web.hub import RobotClock, RobotHub, nav_status, scene_of
from tourbot.web.link import NavStatus, PersonView, RobotView
from tourbot.web.stream import StreamConfig, StreamEncoder


def _status(state: str, message: str = "", exhibit: str | None = "vase") -> dict[str, Any]:
    return nav_status(
        RobotView(0.0, 1.0, 2.0, 0.0, nav=NavStatus(state=state, exhibit=exhibit, message=message))
    )


def test_running_counts_are_not_part_of_the_status() -> None:
    assert _status("blocked", "waiting: way blocked for 12 s")["message"] == "waiting: way blocked"
    assert _status("moving", "slowed by people for 3 s") == _status("moving", "slowed by people for 4 s")


def test_moving_and_blocked_flips_are_published_once_steady(db: Database) -> None:
    hub = RobotHub("lefkos", FakeRobot(), db, db.robot_id("lefkos"), steady_time=1.5)
    published = []
    flips = [("moving", ""), ("blocked", "slowed by people for 1 s"), ("moving", ""), ("blocked", "")]
    t = 0.0
    for _ in range(5):  # a crowd: slowed and freed every half second
        for state, message in flips:
            hub.nav_status = hub._steady(_status(state, message), t)
            published.append(hub.nav_status["state"])
            t += 0.5
    assert set(published) == {"moving"}  # never steady: the viewers see no flapping
    for _ in range(4):  # blocked from the last flip on: published once it held 1.5 s
        hub.nav_status = hub._steady(_status("blocked"), t)
        published.append(hub.nav_status["state"])
        t += 0.5
    assert published[-5:] == ["moving", "moving", "moving", "blocked", "blocked"]
    hub.nav_status = hub._steady(_status("arrived"), t)  # anything else at once
    assert hub.nav_status["state"] == "arrived"
    hub.nav_status = hub._steady(_status("moving", exhibit="loom"), t)  # a new task at once
    assert hub.nav_status["exhibit"] == "loom"


def test_vision_obstacles_are_published_as_cells_on_change(db: Database) -> None:
    robot = FakeRobot()
    hub = RobotHub("lefkos", robot, db, db.robot_id("lefkos"))
    robot.obstacles = ((3.02, 4.01), (3.04, 3.98), (3.31, 4.0))  # two cells of 10 cm
    hub._publish_obstacles(robot.view(), 10.0)
    assert hub.obstacles_message is not None
    message = json.loads(hub.obstacles_message)
    assert message == {"type": "obstacles", "cell": 0.1, "points": [[3.0, 4.0], [3.3, 4.0]]}
    first = hub.obstacles_message
    robot.obstacles = ((3.03, 4.0), (3.29, 4.02))  # the same cells
    hub._publish_obstacles(robot.view(), 12.0)
    assert hub.obstacles_message is first  # unchanged: no new message for the viewers
    robot.obstacles = ((3.03, 4.0),)
    hub._publish_obstacles(robot.view(), 12.5)
    assert json.loads(hub.obstacles_message or "")["points"] == [[3.0, 4.0]]
    second = hub.obstacles_message
    robot.obstacles = ()
    hub._publish_obstacles(robot.view(), 13.0)  # changed, but within the period of the last message
    assert hub.obstacles_message is second
    hub._publish_obstacles(robot.view(), 13.6)
    assert json.loads(hub.obstacles_message or "")["points"] == []


def test_the_hub_writes_each_state_to_its_viewers_and_a_slow_one_catches_up(db: Database) -> None:
    """Every viewer that can take a frame gets the one shared delta frame; a joining viewer gets a
    keyframe at once; a viewer that could not take a frame (its buffer full) is skipped and then
    gets one keyframe of the latest state, never the states it missed."""
    import asyncio

    from tourbot.web.hub import StreamViewer
    from tourbot.web.stream import StreamDecoder

    robot = FakeRobot()
    # refreshed by the test only (the ticker's first tick is far away)
    hub = RobotHub("lefkos", robot, db, db.robot_id("lefkos"), drive=False, rate_hz=1e-3)
    got: dict[str, list[bytes]] = {"fast": [], "slow": []}
    busy = {"fast": False, "slow": False}

    def writer(name: str) -> StreamViewer:
        def write(message: bytes, frame: bytes) -> bool:
            if busy[name]:
                return False
            assert frame.endswith(message)
            got[name].append(frame)
            return True

        return StreamViewer(write)

    async def run() -> None:
        await hub.start()
        fast, slow = writer("fast"), writer("slow")
        hub.watch(fast)
        hub.watch(slow)
        assert [f[2] for f in got["fast"] + got["slow"]] == [1, 1]  # keyframes at once
        for k in range(6):
            robot.x += 0.5  # a jump no viewer predicts: a delta at every state
            busy["slow"] = k in (1, 2, 3)
            await hub.refresh()
        await hub.close()

    asyncio.run(run())
    assert [f[2] for f in got["fast"]] == [1, 2, 2, 2, 2, 2, 2]
    for a, b in zip(got["fast"][1:], got["fast"][2:], strict=False):
        assert a is not b
    assert got["slow"][1] is got["fast"][1]  # the same bytes, framed once
    assert [f[2] for f in got["slow"]] == [1, 2, 1, 2]  # three states missed: one keyframe
    assert got["slow"][3] is got["fast"][6]
    fast_view, slow_view = StreamDecoder(), StreamDecoder()
    for frame in got["fast"]:
        fast_view.feed(frame[2:])
    for frame in got["slow"]:
        slow_view.feed(frame[2:])
    assert slow_view.scene().robot.x == fast_view.scene().robot.x


def test_the_robot_clock_rate_follows_a_robot_that_falls_behind() -> None:
    clock = RobotClock(window=2.0)
    assert clock.rate(100.0, 5.0) == 1.0  # nothing seen yet: taken as real time
    rates = [clock.rate(100.0 + 0.2 * k, 5.0 + 0.1 * k) for k in range(1, 30)]  # half the wall's pace
    assert rates[-1] == pytest.approx(0.5)
    stalled = [clock.rate(105.8 + 0.2 * k, 7.9) for k in range(1, 16)]  # the robot stands still 3 s
    assert stalled[0] == pytest.approx(0.45)  # 0.2 s of the 2 s window
    assert stalled[-1] == 0.0  # its avatars stand still too
    assert clock.rate(106.2, 0.0) == 1.0  # the robot's process restarted: its clock went back


def _walkers(t: float, rate: float) -> RobotView:
    """A robot and 10 people walking at 1 m/s of the robot's clock, which runs at ``rate``."""
    robot_t = rate * t
    people = tuple(PersonView(i + 1, 2.0 * i + robot_t, float(i), 1.0, 0.0) for i in range(10))
    return RobotView(robot_t, robot_t, 0.0, 0.0, v=1.0, people=people)


def _streamed(rate: float, scaled: bool) -> tuple[int, float]:
    """Bytes of 30 s of the walkers' stream at 5 Hz of the wall, and the shown people's mean error."""
    clock = RobotClock()
    encoder = StreamEncoder(StreamConfig(bitrate=1e9))
    sent = 0
    for k in range(150):
        t = 1000.0 + 0.2 * k
        view = _walkers(t - 1000.0, rate)
        scene = scene_of(view, t, rate=clock.rate(t, view.t)) if scaled else scene_of(view, t)
        message = encoder.encode(scene)
        sent += 0 if message is None else len(message)
    return sent, encoder.fidelity.mean


@pytest.mark.parametrize("rate", [0.5, 0.25])
def test_the_stream_costs_the_same_when_the_robot_falls_behind_the_wall(rate: float) -> None:
    """The stream runs on the wall clock: a robot whose clock runs at half or a quarter of the
    wall's (a simulated robot on a loaded machine) has its velocities streamed per wall second, so
    that the viewers' dead reckoning keeps up and it costs about what it costs at real time (the
    walkers resent as their 3 s horizon ends); at the view's own velocities every body overshoots
    and is resent far more often."""
    real_time, _ = _streamed(1.0, scaled=True)
    sent, error = _streamed(rate, scaled=True)
    assert sent <= 1.25 * real_time
    assert error < 0.1
    unscaled, _ = _streamed(rate, scaled=False)
    assert unscaled > 2 * sent
