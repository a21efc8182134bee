"""What the hub publishes to every viewer: steady navigation status, no running counters."""

from __future__ import annotations

import json
from typing import Any

from tests.web.fakes import FakeRobot
from tourbot.web.db import Database
from tourbot.web.hub import RobotHub, nav_status
from tourbot.web.link import NavStatus, RobotView


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
