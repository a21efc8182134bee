"""A robot in its own process behind :class:`ProcessLink`: state flows out, commands and their
errors flow back, and closing ends the process."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from tests.web.fakes import FakeFactory, FakeRobot
from tests.web.test_app import connect, new_session, role_is, wait_for
from tourbot.errors import TourbotError
from tourbot.web.app import WebConfig, create_app
from tourbot.web.db import Database
from tourbot.web.link import RobotLink
from tourbot.web.process_link import ProcessLink
from tourbot.web.supervised import RobotProcessError


class _PickyRobot(FakeRobot):
    """Knows one tour only, as a site's tour executor does."""

    def start_tour(self, name: str, exhibits: list[tuple[str, float, float, float]]) -> None:
        if name != "highlights":
            raise TourbotError(f"no tour named {name!r}")
        super().start_tour(name, exhibits)


class _SlowCamera(FakeRobot):
    """Its first picture takes 1.5 s (a large render on a loaded machine), the others none."""

    def __init__(self) -> None:
        super().__init__()
        self.pictures = 0

    def photo(self) -> bytes:
        self.pictures += 1
        if self.pictures == 1:
            time.sleep(1.5)
        return super().photo()


def test_a_picture_may_take_longer_than_a_command() -> None:
    """Rendering the camera's 1280 x 960 picture took more than a command's 10 s on the loaded
    machine (the page's picture never came): a picture has its own, longer wait."""
    link = ProcessLink(_SlowCamera, name="slow", command_timeout=0.5)
    try:
        link.wait_ready(60)
        assert link.photo()[:2] == b"\xff\xd8"  # after 1.5 s, three times a command's wait
    finally:
        link.close()


def test_a_late_answer_is_never_taken_for_the_next_commands() -> None:
    link = ProcessLink(_SlowCamera, name="slow", command_timeout=0.5, photo_timeout=0.5)
    try:
        link.wait_ready(60)
        with pytest.raises(RobotProcessError, match=r"no answer in 0\.5 s"):
            link.photo()
        time.sleep(1.5)  # the late picture's answer arrives meanwhile
        link.send_goal(6.0, 2.0)  # takes its own answer, not the late picture's
        assert link.photo()[:2] == b"\xff\xd8"  # a picture, not the goal's answer
        link.stop()
        _wait(lambda: link.view().nav.state == "stopped")
    finally:
        link.close()


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
        link.around("fresco", 4.0, 2.0, 0.0)
        _wait(lambda: link.view().nav.tour == "around fresco")
        jpeg = link.photo()  # a result comes back from the robot's process
        assert jpeg[:2] == b"\xff\xd8"
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


def test_a_robot_process_that_dies_is_restarted_where_it_was() -> None:
    """kill -9 of the robot's process: within seconds a new one runs, from the last estimated pose,
    and takes commands again."""
    link = ProcessLink(FakeFactory(restart_time=2.0), name="phoenix")  # a real robot takes seconds
    try:
        link.wait_ready(60)
        link.send_goal(9.0, 2.0)
        _wait(lambda: link.view().x > 4.0)
        link._process.kill()
        killed = time.monotonic()
        _wait(lambda: link.view().nav.state == "restarting", limit=5.0)
        before = link.view().x
        _wait(lambda: link.view().nav.state != "restarting" and link._process.is_alive(), limit=30.0)
        assert time.monotonic() - killed < 15.0
        after = link.view()
        assert after.x == pytest.approx(before, abs=0.2)  # not back at the start (2, 2)
        assert after.x > 4.0
        link.send_goal(after.x + 1.0, 2.0)
        _wait(lambda: link.view().x > after.x + 0.5)
        assert len(link.restarts) == 1
    finally:
        link.close()
    assert not link._process.is_alive()


def test_a_robot_process_that_dies_too_often_shows_as_failed() -> None:
    link = ProcessLink(FakeRobot, name="fragile", max_restarts=0)
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


def test_slots_and_queue_outlive_a_restarted_robot(db: Database, tmp_path: Path) -> None:
    """The server keeps the holder and the queue while the robot's process is killed and restarted;
    the holder drives the new process."""
    link = ProcessLink(FakeFactory(restart_time=2.0), name="lefkos")
    link.wait_ready(60)
    try:
        with TestClient(create_app({"lefkos": link}, db, None, WebConfig(speech_dir=tmp_path))) as client:
            holder, queued = new_session(client), new_session(client)
            with connect(client, holder) as a, connect(client, queued) as b:
                a.send_text(json.dumps({"type": "book"}))
                wait_for(a, role_is("holder"))
                b.send_text(json.dumps({"type": "book"}))
                wait_for(b, role_is("queued"))
                link._process.kill()
                wait_for(a, lambda m: m["type"] == "status" and m["nav"]["state"] == "restarting")
                wait_for(a, lambda m: m["type"] == "status" and m["nav"]["state"] == "idle", limit=2000)
                hub = client.app.state.hubs["lefkos"]  # type: ignore[attr-defined]
                assert hub.arbiter.holder == client.app.state.lookup(holder).session  # type: ignore[attr-defined]
                assert len(hub.arbiter.queue) == 1
                a.send_text(json.dumps({"type": "goto", "x": 5.0, "y": 2.0}))
                wait_for(a, lambda m: m["type"] == "ack")
                _wait(lambda: link.view().x > 2.5)
    finally:
        link.close()


def test_an_interpreter_that_exits_without_closing_does_not_restart_its_robot() -> None:
    # A server that exits (Ctrl-C, end of a script) before closing its links: multiprocessing's exit
    # handler stops the robot's process, and the link must not take that for a crash and start a
    # new robot while the interpreter goes away (a spawned child then dies with a traceback).
    script = (
        "from tests.web.fakes import FakeRobot\n"
        "from tourbot.web.process_link import ProcessLink\n"
        "link = ProcessLink(FakeRobot, name='lefkos')\n"
        "link.wait_ready(60)\n"
        "print('ready', flush=True)\n"
    )
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), str(root / "src")])}
    done = subprocess.run(
        [sys.executable, "-c", script],
        check=False,
        cwd=root,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert "ready" in done.stdout
    assert "Traceback" not in done.stderr, done.stderr
    assert "stopped" not in done.stderr, done.stderr
