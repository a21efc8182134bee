"""A robot in its own process behind :class:`ProcessLink`: state flows out, commands and their
errors flow back, and closing ends the process."""

from __future__ import annotations

import time

import pytest

from tests.web.fakes import FakeRobot
from tourbot.errors import TourbotError
from tourbot.web.link import RobotLink
from tourbot.web.process_link import ProcessLink, RobotProcessError


class _PickyRobot(FakeRobot):
    """Knows one tour only, as a site's tour executor does."""

    def start_tour(self, name: str, exhibits: list[tuple[str, float, float, float]]) -> None:
        if name != "highlights":
            raise TourbotError(f"no tour named {name!r}")
        super().start_tour(name, exhibits)


def _broken() -> RobotLink:
    raise TourbotError("the site file is missing")


def _wait(condition: object, limit: float = 20.0) -> None:
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        if callable(condition) and condition():
            return
        time.sleep(0.05)
    pytest.fail("condition not met in time")


def test_state_goes_out_and_commands_come_back() -> None:
    link = ProcessLink(_PickyRobot, name="picky")
    try:
        link.wait_ready(60)
        assert isinstance(link, RobotLink)
        assert link.period == pytest.approx(0.05)
        start = link.view()
        assert (start.x, start.y) == (2.0, 2.0)
        link.send_goal(6.0, 2.0, exhibit="fresco")
        _wait(lambda: link.view().x > 2.5)  # the robot moves in its own process
        assert link.view().nav.exhibit == "fresco"
        with pytest.raises(TourbotError, match="no tour named 'nope'"):
            link.start_tour("nope", [])
        link.start_tour("highlights", [("a", 3.0, 3.0, 0.0)])
        _wait(lambda: link.view().nav.tour == "highlights")
        link.stop()
        _wait(lambda: link.view().nav.state == "stopped")
        link.step()  # nothing to do: the robot steps itself
    finally:
        link.close()
    assert not link._process.is_alive()
    link.close()  # idempotent
    with pytest.raises(RobotProcessError, match="picky"):
        link.stop()


def test_a_robot_that_cannot_start_says_why() -> None:
    link = ProcessLink(_broken, name="broken")
    with pytest.raises(RobotProcessError, match="could not start: TourbotError: the site file is missing"):
        link.wait_ready(60)
    assert not link._process.is_alive()


def test_a_robot_process_that_dies_shows_as_failed() -> None:
    link = ProcessLink(FakeRobot, name="fragile")
    try:
        link.wait_ready(60)
        assert link.view().nav.state == "idle"
        link._process.kill()
        _wait(lambda: link.view().nav.state == "failed")
        assert "the robot stopped" in link.view().nav.message
        with pytest.raises(RobotProcessError, match="fragile"):
            link.send_goal(1.0, 1.0)
    finally:
        link.close()
