"""The robots' state fanned out through a real Redis broker to follower servers."""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.web.fakes import FakeRobot
from tests.web.test_app import connect, new_session
from tourbot.web.app import WebConfig, create_app
from tourbot.web.db import Database, open_database
from tourbot.web.fanout import BrokerError, FollowerLink, PublishingLink, channel, decode_view, encode_view
from tourbot.web.fanout import connect as broker_connect
from tourbot.web.link import NavStatus, ObjectView, PersonView, RobotLink, RobotView
from tourbot.web.serve import ServeSettings, followed_links, published_links
from tourbot.web.stream import StreamDecoder


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="module")
def broker() -> Iterator[str]:
    """A Redis server of its own on loopback, no persistence."""
    server = shutil.which("redis-server")
    if server is None:
        pytest.skip("redis-server is not installed (scripts/test-services.sh installs it)")
    port = _free_port()
    process = subprocess.Popen(
        [server, "--port", str(port), "--bind", "127.0.0.1", "--save", "", "--appendonly", "no"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    url = f"redis://127.0.0.1:{port}/0"
    deadline = time.monotonic() + 20.0
    while True:
        try:
            broker_connect(url)
            break
        except BrokerError:
            if time.monotonic() > deadline:
                process.kill()
                raise
            time.sleep(0.1)
    yield url
    process.terminate()
    process.wait(10)


finite = st.floats(-1e4, 1e4, allow_nan=False)
people = st.lists(st.builds(PersonView, st.integers(1, 65535), finite, finite, finite, finite), max_size=5)


@settings(max_examples=40, deadline=None)
@given(
    pose=st.tuples(finite, finite, finite, finite, finite),
    tracked=people,
    truth=people,
    state=st.sampled_from(["idle", "moving", "blocked"]),
    exhibit=st.none() | st.text(max_size=12),
    path=st.lists(st.tuples(finite, finite), max_size=4),
)
def test_a_view_survives_the_wire(
    pose: tuple[float, ...],
    tracked: list[PersonView],
    truth: list[PersonView],
    state: str,
    exhibit: str | None,
    path: list[tuple[float, float]],
) -> None:
    nav = NavStatus(state, exhibit, (1.0, 2.0), tuple(path), 3.5, "highlights", (1, 4), "on the way")
    x, y, theta, v, omega = pose
    view = RobotView(
        100.25, x, y, theta, v, omega, (0.01, 0.02, 0.003), tuple(tracked), nav, tuple(truth),
        obstacles=((1.5, 2.25),), objects=(ObjectView("door-1", "door", ((0.0, 0.0), (0.9, 0.05))),),
    )  # fmt: skip
    back = decode_view(encode_view(view))
    assert back.nav == nav
    assert back.obstacles == view.obstacles
    assert back.objects == view.objects
    assert back.x == pytest.approx(view.x, abs=1e-4)
    assert back.theta == pytest.approx(view.theta, abs=1e-4)
    assert [p.id for p in back.people] == [p.id for p in tracked]
    for a, b in zip(back.people + back.truth, view.people + view.truth, strict=True):
        assert (a.x, a.y, a.vx, a.vy) == pytest.approx((b.x, b.y, b.vx, b.vy), abs=1e-3)


@pytest.mark.parametrize("bad", [b"", b"[]", b'{"t": 1}', b"\xff\xfe", json.dumps({"nav": 3}).encode()])
def test_anything_else_on_the_channel_is_refused(bad: bytes) -> None:
    with pytest.raises(BrokerError, match="not a robot view"):
        decode_view(bad)


def test_an_absent_broker_is_one_line() -> None:
    with pytest.raises(BrokerError, match=r"cannot reach the broker at redis://127\.0\.0\.1:\d+/0"):
        broker_connect(f"redis://127.0.0.1:{_free_port()}/0")
    with pytest.raises(BrokerError, match="not a broker URL"):
        broker_connect("http://example")


def _wait(test: object, seconds: float = 10.0) -> None:
    deadline = time.monotonic() + seconds
    while not test():  # type: ignore[operator]
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.05)


def test_a_follower_sees_what_the_robot_publishes_and_says_when_it_stops(broker: str) -> None:
    robot = FakeRobot()
    client = broker_connect(broker)
    name = channel("test", f"lefkos-{_free_port()}")
    follower = FollowerLink(client, name, controlled_at="http://control:8000/", stale_after=0.6)
    published = PublishingLink(robot, client, name)
    try:
        robot.send_goal(5.0, 2.0)
        for _ in range(10):
            robot.step()
            published.view()
            time.sleep(0.05)
        follower.wait_ready(10.0)
        _wait(lambda: follower.view().x == pytest.approx(robot.view().x, abs=1e-3))
        shown = follower.view()
        assert shown.nav.state == "moving"
        assert len(shown.people) == 7
        with pytest.raises(BrokerError, match="only shows the robot"):
            follower.send_goal(1.0, 1.0)
        time.sleep(1.0)  # the controlling server stopped publishing
        assert follower.view().nav.state == "failed"
        assert follower.view().v == 0.0
        published.view()
        _wait(lambda: follower.view().nav.state == "moving")
    finally:
        published.close()
        follower.close()


def _stream_x(ws: object, decoder: StreamDecoder, seconds: float = 10.0) -> float:
    """The robot's x as the page shows it now (dead-reckoned from the last stream message)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        message = ws.receive()  # type: ignore[attr-defined]
        if message.get("bytes"):
            decoder.feed(message["bytes"])
        if decoder.epoch is not None:
            return decoder.scene(time.time()).robot.x
    raise AssertionError("no stream message")


def test_viewers_of_a_follower_server_see_the_robot_and_are_sent_to_control_it_elsewhere(
    broker: str, db: Database, tmp_path: Path
) -> None:
    site = f"museum{_free_port()}"
    robot = FakeRobot()
    settings_ = ServeSettings(site=site, broker=broker, host="127.0.0.1", port=8123)
    links: dict[str, RobotLink] = published_links(settings_, site, {"lefkos": robot})
    config = WebConfig(site_name="Test museum", speech_dir=tmp_path / "speech")
    follower_db = open_database(f"sqlite:///{tmp_path / 'follower.db'}")
    with TestClient(create_app(links, db, None, config)) as primary:
        # the controlling server drives the robot; the follower is started after it
        followed = followed_links(ServeSettings(site=site, follow=broker), site)
        assert list(followed) == ["lefkos"]
        follower_config = WebConfig(site_name="Test museum", speech_dir=tmp_path / "s2", drive_robots=False)
        with TestClient(create_app(followed, follower_db, None, follower_config)) as follower:
            with connect(follower, new_session(follower)) as ws:
                assert json.loads(ws.receive_text())["type"] == "hello"
                decoder = StreamDecoder()
                first = _stream_x(ws, decoder)
                assert first == pytest.approx(2.0, abs=0.01)  # the robot at rest where it starts
                robot.send_goal(8.0, 2.0)  # as its own server would have it drive
                _wait(lambda: _stream_x(ws, decoder) > 4.0)
                ws.send_text(json.dumps({"type": "book"}))
                for _ in range(100):
                    message = ws.receive()
                    if message.get("text") and json.loads(message["text"])["type"] == "error":
                        error = json.loads(message["text"])
                        break
                else:
                    raise AssertionError("the booking was not refused")
                assert "go to http://127.0.0.1:8123/" in error["message"]
            # the primary still takes bookings
            with connect(primary, new_session(primary)) as ws:
                assert json.loads(ws.receive_text())["type"] == "hello"
                ws.send_text(json.dumps({"type": "book"}))
                for _ in range(100):
                    message = ws.receive()
                    if message.get("text") and json.loads(message["text"]).get("command") == "book":
                        break
                else:
                    raise AssertionError("the primary did not take the booking")
        for link in followed.values():
            link.close()  # type: ignore[attr-defined]


def test_a_follower_without_a_controlling_server_says_what_to_start(broker: str) -> None:
    with pytest.raises(BrokerError, match="start the controlling server first"):
        followed_links(ServeSettings(site="nowhere", follow=broker), "nowhere")
