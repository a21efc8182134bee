from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from hypothesis import given
from hypothesis import strategies as st
from starlette.testclient import WebSocketTestSession
from starlette.websockets import WebSocketDisconnect

from tests.web.fakes import FakeRobot
from tests.web.live import LiveServer
from tourbot.web.app import COOKIE, WebConfig, create_app, pooled, wall_boxes
from tourbot.web.db import Database
from tourbot.web.guard import GuardConfig
from tourbot.web.slots import SlotConfig
from tourbot.web.stream import StreamDecoder

ORIGIN = {"origin": "http://testserver"}
PAIRING = "pair-this-screen-0123"


@pytest.fixture
def robot() -> FakeRobot:
    return FakeRobot()


@pytest.fixture
def client(robot: FakeRobot, db: Database, tmp_path: Path) -> Iterator[TestClient]:
    config = WebConfig(
        site_name="Test museum",
        speech_dir=tmp_path / "speech",
        onboard_token=PAIRING,
        guard=GuardConfig(commands_per_second=5.0, burst=10),
    )
    with TestClient(create_app({"lefkos": robot}, db, None, config)) as c:
        yield c


def new_session(client: TestClient) -> str:
    client.cookies.clear()
    response = client.get("/api/session")
    token = response.cookies.get(COOKIE)
    assert token
    client.cookies.clear()
    return token


def connect(client: TestClient, token: str, robot: str = "lefkos", query: str = "") -> WebSocketTestSession:
    headers = {**ORIGIN, "cookie": f"{COOKIE}={token}"}
    return client.websocket_connect(f"/ws/{robot}{query}", headers=headers)


def wait_for(
    ws: WebSocketTestSession, test: Callable[[dict[str, Any]], bool], limit: int = 200
) -> dict[str, Any]:
    """Read messages until a JSON one passes ``test`` (binary frames are skipped)."""
    for _ in range(limit):
        message = ws.receive()
        if message.get("text"):
            data = json.loads(message["text"])
            if test(data):
                return data
    raise AssertionError("expected message never came")


def answering(
    ws: WebSocketTestSession, test: Callable[[dict[str, Any]], bool], seconds: float
) -> dict[str, Any]:
    """As :func:`wait_for`, for up to ``seconds``, pinging twice a second as a page does."""
    deadline = time.monotonic() + seconds
    pinged = 0.0
    while time.monotonic() < deadline:
        if time.monotonic() - pinged > 0.5:
            ws.send_text(json.dumps({"type": "ping"}))
            pinged = time.monotonic()
        message = ws.receive()
        if message.get("text"):
            data = json.loads(message["text"])
            if test(data):
                return data
    raise AssertionError("expected message never came")


def role_is(role: str) -> Callable[[dict[str, Any]], bool]:
    return lambda m: m["type"] == "status" and m["slot"]["role"] == role


def test_pages_set_a_session_cookie_and_a_strict_policy(client: TestClient) -> None:
    response = client.get("/")
    assert response.status_code == 200
    assert COOKIE in response.cookies
    policy = response.headers["content-security-policy"]
    assert "script-src 'self' 'sha256-" in policy
    assert "unsafe-eval" not in policy
    site = client.get("/api/site").json()
    assert site["robots"] == ["lefkos"]
    assert [e["slug"] for e in site["exhibits"]] == ["amphora", "loom"]
    assert site["tours"][0]["exhibits"] == ["amphora", "loom"]


def test_stream_starts_with_a_keyframe_of_robot_and_people(client: TestClient) -> None:
    with connect(client, new_session(client)) as ws:
        assert json.loads(ws.receive_text())["type"] == "hello"
        decoder = StreamDecoder()
        for _ in range(20):
            message = ws.receive()
            if message.get("bytes"):
                decoder.feed(message["bytes"])
                break
        scene = decoder.scene()
        assert scene.robot.x == pytest.approx(2.0, abs=0.01)
        assert len(scene.people) == 7


@pytest.mark.parametrize("origin", [None, "http://evil.example", "null"])
def test_websocket_from_a_foreign_origin_is_refused(client: TestClient, origin: str | None) -> None:
    token = new_session(client)
    headers = {"cookie": f"{COOKIE}={token}"}
    if origin is not None:
        headers["origin"] = origin
    with (
        pytest.raises(WebSocketDisconnect) as refused,
        client.websocket_connect("/ws/lefkos", headers=headers),
    ):
        pass
    assert refused.value.code == 1008


def test_websocket_without_session_is_refused(client: TestClient) -> None:
    with pytest.raises(WebSocketDisconnect), client.websocket_connect("/ws/lefkos", headers=ORIGIN):
        pass
    with (
        pytest.raises(WebSocketDisconnect),
        client.websocket_connect("/ws/lefkos", headers={**ORIGIN, "cookie": f"{COOKIE}=forged"}),
    ):
        pass


def test_only_the_slot_holder_moves_the_robot(client: TestClient, robot: FakeRobot) -> None:
    first, second = new_session(client), new_session(client)
    with connect(client, first) as a, connect(client, second) as b:
        b.send_text(json.dumps({"type": "goto", "x": 1.0, "y": 1.0}))
        error = wait_for(b, lambda m: m["type"] == "error")
        assert "book a slot" in error["message"]
        a.send_text(json.dumps({"type": "book"}))
        wait_for(a, role_is("holder"))
        b.send_text(json.dumps({"type": "book"}))
        queued = wait_for(b, role_is("queued"))
        assert queued["slot"]["position"] == 1
        assert queued["slot"]["time_left"] == pytest.approx(600.0, abs=2.0)
        b.send_text(json.dumps({"type": "exhibit", "exhibit": "amphora"}))
        assert "number 1 in the queue" in wait_for(b, lambda m: m["type"] == "error")["message"]
        assert robot.commands == []
        a.send_text(json.dumps({"type": "exhibit", "exhibit": "amphora"}))
        wait_for(a, lambda m: m["type"] == "ack")
        assert robot.commands == [("goal", (4.0, 2.0, 0.0, "amphora"))]
        arrived = wait_for(a, lambda m: m["type"] == "status" and m["nav"]["state"] == "arrived")
        assert arrived["nav"]["exhibit"] == "amphora"
        a.send_text(json.dumps({"type": "leave"}))
        wait_for(b, role_is("holder"))
        b.send_text(json.dumps({"type": "tour", "tour": "short"}))
        wait_for(b, lambda m: m["type"] == "ack")
        assert robot.commands[-1] == ("tour", "short")


def hub_of(client: TestClient) -> Any:
    return client.app.state.hubs["lefkos"]  # type: ignore[attr-defined]


def _short_grace_client(robot: FakeRobot, db: Database, tmp_path: Path, grace: float) -> TestClient:
    config = WebConfig(speech_dir=tmp_path, slots=SlotConfig(answer_timeout=grace))
    return TestClient(create_app({"lefkos": robot}, db, None, config))


def test_holder_closing_the_page_hands_over_after_the_grace_time(
    robot: FakeRobot, db: Database, tmp_path: Path
) -> None:
    with _short_grace_client(robot, db, tmp_path, grace=1.5) as client:
        first, second = new_session(client), new_session(client)
        with connect(client, second) as b:
            with connect(client, first) as a:
                a.send_text(json.dumps({"type": "book"}))
                wait_for(a, role_is("holder"))
                b.send_text(json.dumps({"type": "book"}))
                wait_for(b, role_is("queued"))
            closed = time.monotonic()
            answering(b, role_is("holder"), 10.0)
            assert time.monotonic() - closed > 1.0  # not at once: the holder had its grace time
            bookings = db.bookings()
            deadline = time.monotonic() + 5.0  # the rows are written just after the hand-over
            while time.monotonic() < deadline and len(bookings) < 2:
                time.sleep(0.05)
                bookings = db.bookings()
            assert [(row[1], row[4]) for row in bookings] == [(1, "silent"), (2, "")]


def test_a_reload_or_a_second_tab_keeps_the_slot(robot: FakeRobot, db: Database, tmp_path: Path) -> None:
    with _short_grace_client(robot, db, tmp_path, grace=3.0) as client:
        holder, other = new_session(client), new_session(client)
        with connect(client, other) as b:
            with connect(client, holder) as a:
                a.send_text(json.dumps({"type": "book"}))
                wait_for(a, role_is("holder"))
                b.send_text(json.dumps({"type": "book"}))
                wait_for(b, role_is("queued"))
                with connect(client, holder) as tab:  # a second tab of the same browser
                    wait_for(tab, role_is("holder"))
                a.send_text(json.dumps({"type": "goto", "x": 3.0, "y": 2.0}))
                wait_for(a, lambda m: m["type"] == "ack")  # the first tab still drives
            time.sleep(1.0)  # the page reloads: closed, then opened again within the grace time
            with connect(client, holder) as again:
                wait_for(again, role_is("holder"))
                with pytest.raises(AssertionError):  # 4 s, longer than the grace time: still holder
                    answering(again, lambda m: m["type"] == "status" and m["slot"]["role"] != "holder", 4.0)
                again.send_text(json.dumps({"type": "goto", "x": 4.0, "y": 2.0}))
                wait_for(again, lambda m: m["type"] == "ack")
                assert hub_of(client).arbiter.holder == client.app.state.lookup(holder).session  # type: ignore[attr-defined]
    assert robot.commands[-1] == ("goal", (4.0, 2.0, None, None))


@pytest.mark.parametrize(
    ("raw", "expected"),
    [
        ("not json", "not JSON"),
        (json.dumps({"type": "goto", "x": "far"}), "bad command"),
        (json.dumps({"type": "goto", "x": 1, "y": 1, "extra": 1}), "bad command"),
        (json.dumps({"type": "launch"}), "bad command"),
        (json.dumps({"type": "goto", "x": 1e9, "y": 0}), "bad command"),
        (json.dumps([1, 2]), "bad command"),
        ("x" * 5000, "at most 2048"),
    ],
)
def test_malformed_or_oversized_messages_get_an_error_not_a_crash(
    client: TestClient, raw: str, expected: str
) -> None:
    with connect(client, new_session(client)) as ws:
        ws.send_text(raw)
        assert expected in wait_for(ws, lambda m: m["type"] == "error")["message"]
        ws.send_bytes(b"\x00\xff" * 10)
        wait_for(ws, lambda m: m["type"] == "error")
        ws.send_text(json.dumps({"type": "book"}))
        wait_for(ws, lambda m: m["type"] == "ack")


def test_rate_limit_per_client(client: TestClient) -> None:
    with connect(client, new_session(client)) as ws:
        for _ in range(25):
            ws.send_text(json.dumps({"type": "ping"}))
        error = wait_for(ws, lambda m: m["type"] == "error")
        assert "too many" in error["message"]


def test_staff_actions_need_a_login(client: TestClient, robot: FakeRobot) -> None:
    exhibit = {"slug": "lyre", "name": "Lyre", "x": 1.0, "y": 2.0}
    assert client.post("/api/admin/exhibits", json=exhibit).status_code == 401
    assert client.post("/api/robots/lefkos/staff-stop").status_code == 401
    assert client.post("/api/login", json={"username": "curator", "password": "wrong one"}).status_code == 401
    assert (
        client.post("/api/login", json={"username": "curator", "password": "correct horse"}).status_code
        == 200
    )
    assert client.post("/api/admin/exhibits", json=exhibit).status_code == 200
    moved = client.post("/api/admin/exhibits/lyre/place", json={"x": 3.0, "y": 3.0}).json()
    assert (moved["x"], moved["y"]) == (3.0, 3.0)
    tour = {"slug": "music", "name": "Music", "exhibits": ["lyre", "loom"]}
    assert client.post("/api/admin/tours", json=tour).json()["exhibits"] == ["lyre", "loom"]
    bad_tour = {"slug": "bad", "name": "Bad", "exhibits": ["nowhere"]}
    assert client.post("/api/admin/tours", json=bad_tour).status_code == 422
    assert client.post("/api/admin/exhibits", json={**exhibit, "slug": "../x"}).status_code == 422
    assert client.post("/api/robots/lefkos/staff-stop").status_code == 200
    assert robot.commands[-1] == ("stop", None)
    assert client.get("/api/admin/stats").json()["visits"]["lyre"] == 0
    client.post("/api/logout")
    assert client.get("/api/admin/stats").status_code == 401


def test_staff_stop_overrides_the_holder(client: TestClient) -> None:
    token = new_session(client)
    with connect(client, token) as ws:
        ws.send_text(json.dumps({"type": "book"}))
        wait_for(ws, role_is("holder"))
        client.post("/api/login", json={"username": "curator", "password": "correct horse"})
        client.post("/api/robots/lefkos/staff-stop")
        ws.send_text(json.dumps({"type": "goto", "x": 1.0, "y": 1.0}))
        assert "staff" in wait_for(ws, lambda m: m["type"] == "error")["message"]
        client.post("/api/robots/lefkos/staff-release")
        ws.send_text(json.dumps({"type": "goto", "x": 1.0, "y": 1.0}))
        wait_for(ws, lambda m: m["type"] == "ack")


def test_login_attempts_are_limited(client: TestClient) -> None:
    codes = [
        client.post("/api/login", json={"username": "curator", "password": f"guess {i}"}).status_code
        for i in range(6)
    ]
    assert codes[:3] == [401, 401, 401]
    assert 429 in codes


def test_onboard_screen_is_only_for_the_robot_itself(client: TestClient) -> None:
    assert client.get("/onboard").status_code == 403
    with (
        pytest.raises(WebSocketDisconnect),
        connect(client, new_session(client), query="?screen=onboard"),
    ):
        pass


def test_onboard_screen_is_paired_by_its_token_not_by_its_address(
    robot: FakeRobot, db: Database, tmp_path: Path
) -> None:
    """A visitor on the robot's own machine (loopback) is not the on-board screen: only the
    pairing token makes one, and a wrong token is refused."""
    app = create_app({"lefkos": robot}, db, None, WebConfig(speech_dir=tmp_path, onboard_token=PAIRING))
    with TestClient(app, client=("127.0.0.1", 50000)) as local:
        assert local.get("/onboard").status_code == 403
        token = new_session(local)
        with pytest.raises(WebSocketDisconnect), connect(local, token, query="?screen=onboard"):
            pass
        assert local.get("/onboard/pair?token=wrong-token").status_code == 403
        paired = local.get(f"/onboard/pair?token={PAIRING}", follow_redirects=False)
        assert paired.status_code == 303
        screen = paired.cookies[COOKIE]
        assert local.get("/onboard", cookies={COOKIE: screen}).status_code == 200
        with connect(local, screen, query="?screen=onboard") as ws:
            ws.send_text(json.dumps({"type": "goto", "x": 3.0, "y": 3.0}))
            wait_for(ws, lambda m: m["type"] == "ack")
    assert robot.commands == [("goal", (3.0, 3.0, None, None))]


def test_speech_files_cannot_escape_their_folder(client: TestClient) -> None:
    assert client.get("/speech/..%2F..%2Fetc%2Fpasswd").status_code == 404
    assert client.get("/speech/" + "a" * 24 + ".wav").status_code == 404


def test_unknown_robot(client: TestClient) -> None:
    with pytest.raises(WebSocketDisconnect), connect(client, new_session(client), robot="ghost"):
        pass


def test_each_robot_has_its_own_queue(db: Database, tmp_path: Path) -> None:
    lefkos, albert = FakeRobot(), FakeRobot()
    app = create_app({"lefkos": lefkos, "albert": albert}, db, None, WebConfig(speech_dir=tmp_path))
    with TestClient(app) as client:
        first, second = new_session(client), new_session(client)
        with connect(client, first, "lefkos") as a, connect(client, second, "albert") as b:
            a.send_text(json.dumps({"type": "book"}))
            wait_for(a, role_is("holder"))
            b.send_text(json.dumps({"type": "book"}))
            wait_for(b, role_is("holder"))  # not queued behind lefkos' holder
            b.send_text(json.dumps({"type": "goto", "x": 3.0, "y": 3.0}))
            wait_for(b, lambda m: m["type"] == "ack")
    assert albert.commands == [("goal", (3.0, 3.0, None, None))]
    assert lefkos.commands == []


def test_a_visitor_drives_one_robot_at_a_time(db: Database, tmp_path: Path) -> None:
    """Booking another robot gives up the slot at the first: its queue moves on at once."""
    app = create_app({"lefkos": FakeRobot(), "albert": FakeRobot()}, db, None, WebConfig(speech_dir=tmp_path))
    with TestClient(app) as client:
        first, second = new_session(client), new_session(client)
        with (
            connect(client, first, "lefkos") as a,
            connect(client, second, "lefkos") as b,
            connect(client, first, "albert") as a2,
        ):
            a.send_text(json.dumps({"type": "book"}))
            wait_for(a, role_is("holder"))
            b.send_text(json.dumps({"type": "book"}))
            wait_for(b, role_is("queued"))
            a2.send_text(json.dumps({"type": "book"}))
            wait_for(a2, role_is("holder"))
            wait_for(b, role_is("holder"))  # lefkos passed on to the next in its queue
            wait_for(a, role_is("watcher"))
    reasons = [b[4] for b in db.bookings()]
    assert reasons[0] == "left"  # the first visitor's slot at lefkos, given up by booking albert


def test_the_robot_list_shows_each_queue(db: Database, tmp_path: Path) -> None:
    """A visitor choosing a robot sees which are driven and how many wait (no one's identity)."""
    app = create_app({"lefkos": FakeRobot(), "albert": FakeRobot()}, db, None, WebConfig(speech_dir=tmp_path))
    with TestClient(app) as client:
        free = {r["name"]: r for r in client.get("/api/robots").json()["robots"]}
        assert free["lefkos"]["driven"] is False
        assert free["albert"]["waiting"] == 0
        first, second = new_session(client), new_session(client)
        with connect(client, first, "lefkos") as a, connect(client, second, "lefkos") as b:
            a.send_text(json.dumps({"type": "book"}))
            wait_for(a, role_is("holder"))
            b.send_text(json.dumps({"type": "book"}))
            wait_for(b, role_is("queued"))
            robots = {r["name"]: r for r in client.get("/api/robots").json()["robots"]}
        assert robots["lefkos"] == {
            "name": "lefkos", "driven": True, "waiting": 1, "state": "idle", "staff_stop": False
        }  # fmt: skip
        assert robots["albert"]["driven"] is False
        assert str(first) not in json.dumps(robots)


def test_the_robot_list_reaches_the_pages_over_their_connection(db: Database, tmp_path: Path) -> None:
    """The pages are never made to poll ``/api/robots`` (each poll costs the wire): the list comes
    with the connection and again when a queue changes, not at every state."""
    app = create_app({"lefkos": FakeRobot(), "albert": FakeRobot()}, db, None, WebConfig(speech_dir=tmp_path))
    with TestClient(app) as client:
        first, second = new_session(client), new_session(client)
        with connect(client, first, "lefkos") as a:
            listed = wait_for(a, lambda m: m["type"] == "robots")["robots"]
            assert {r["name"]: r["driven"] for r in listed} == {"lefkos": False, "albert": False}
            with connect(client, second, "albert") as b:
                b.send_text(json.dumps({"type": "book"}))
                wait_for(b, role_is("holder"))
                listed = wait_for(a, lambda m: m["type"] == "robots")["robots"]  # albert taken
                assert {r["name"]: r["driven"] for r in listed} == {"lefkos": False, "albert": True}
                hub = hub_of(client)
                before = hub.robots_message
                states = hub.stream.version
                while hub.stream.version < states + 3:  # states go on: the same list, no new message
                    time.sleep(0.05)
                assert hub.robots_message is before


def test_a_busy_queue_sends_each_viewer_at_most_a_status_per_period(client: TestClient) -> None:
    """A visitor joining and leaving the queue 9 times in a row: a watcher's page gets the queue's
    changes folded into one status per ``status_period`` (2 s), and the last state once it passed;
    a visitor's own new role still comes at once."""
    watcher, holder, other = new_session(client), new_session(client), new_session(client)
    with connect(client, watcher) as w, connect(client, holder) as a, connect(client, other) as b:
        wait_for(w, lambda m: m["type"] == "status")
        a.send_text(json.dumps({"type": "book"}))
        wait_for(a, role_is("holder"))
        start = time.monotonic()
        for _ in range(4):  # (the commands' rate limit allows a burst of 10)
            b.send_text(json.dumps({"type": "book"}))
            wait_for(b, role_is("queued"))  # its own role: at once
            b.send_text(json.dumps({"type": "leave"}))
            wait_for(b, lambda m: m.get("command") == "leave")
        b.send_text(json.dumps({"type": "book"}))  # it stays in the queue
        wait_for(b, role_is("queued"))
        churn = time.monotonic() - start
        time.sleep(hub_of(client).status_period + 0.5)  # the last change, once the period passed
        w.send_text("not json")  # an error reply marks the end of what the watcher was sent
        statuses = []
        for _ in range(500):
            message = w.receive()
            data = json.loads(message["text"]) if message.get("text") else {}
            if data.get("type") == "error":
                break
            if data.get("type") == "status":
                statuses.append(data)
        assert len(statuses) <= 2 + churn / hub_of(client).status_period
        assert statuses[-1]["slot"]["queue_length"] == 1


def test_the_text_channel_between_the_holder_and_the_staff(client: TestClient, db: Database) -> None:
    """The holder writes, the message is stored in the site database, the staff read it and answer;
    the answer reaches the holder's page, never a watcher's; a watcher cannot write."""
    holder, watcher = new_session(client), new_session(client)
    with connect(client, holder) as a, connect(client, watcher) as b:
        b.send_text(json.dumps({"type": "chat", "text": "hello?"}))
        assert "only the visitor in control" in wait_for(b, lambda m: m["type"] == "error")["message"]
        a.send_text(json.dumps({"type": "book"}))
        wait_for(a, role_is("holder"))
        a.send_text(json.dumps({"type": "chat", "text": "<img src=x onerror=alert(1)> where is the loom?"}))
        mine = wait_for(a, lambda m: m["type"] == "chat")
        assert mine["sender"] == "visitor"
        assert mine["text"] == "<img src=x onerror=alert(1)> where is the loom?"  # text, the page shows it so
        robot_id = hub_of(client).robot_id
        stored = db.messages(robot_id)
        assert [(m.sender, m.text) for m in stored] == [("visitor", mine["text"])]
        assert client.get("/api/admin/robots/lefkos/chat").status_code == 401
        login(client)
        seen = client.get("/api/admin/robots/lefkos/chat").json()
        assert seen["holder"] is True
        assert [(m["sender"], m["current"]) for m in seen["messages"]] == [("visitor", True)]
        reply = client.post("/api/admin/robots/lefkos/chat", json={"text": "Behind you, on the left."})
        assert reply.status_code == 200
        answer = wait_for(a, lambda m: m["type"] == "chat" and m["sender"] == "staff")
        assert answer["text"] == "Behind you, on the left."
        b.send_text(json.dumps({"type": "ping"}))
        for _ in range(30):  # the watcher's stream goes on, without the conversation
            message = b.receive()
            assert "Behind you" not in str(message.get("text"))
        assert [m.sender for m in db.messages(robot_id, session_id=stored[0].session)] == ["visitor", "staff"]
        a.send_text(json.dumps({"type": "leave"}))
        wait_for(a, role_is("watcher"))
    assert client.post("/api/admin/robots/lefkos/chat", json={"text": "still there?"}).status_code == 409


def test_the_text_channel_is_bounded_and_rate_limited(client: TestClient, db: Database) -> None:
    token = new_session(client)
    with connect(client, token) as ws:
        ws.send_text(json.dumps({"type": "book"}))
        wait_for(ws, role_is("holder"))
        ws.send_text(json.dumps({"type": "chat", "text": "x" * 301}))
        error = wait_for(ws, lambda m: m["type"] == "error")["message"]
        assert "at most 300" in error
        assert "xxxx" not in error
        ws.send_text(json.dumps({"type": "chat", "text": "\u0007 \u200b"}))
        assert "empty" in wait_for(ws, lambda m: m["type"] == "error")["message"]
        for i in range(3):  # the burst
            ws.send_text(json.dumps({"type": "chat", "text": f"message {i}"}))
            wait_for(ws, lambda m: m["type"] == "ack" and m["command"] == "chat")
        ws.send_text(json.dumps({"type": "chat", "text": "one too many"}))
        assert "too many messages" in wait_for(ws, lambda m: m["type"] == "error")["message"]
        assert [m.text for m in db.messages(hub_of(client).robot_id)] == [f"message {i}" for i in range(3)]
        login(client)
        too_long = client.post("/api/admin/robots/lefkos/chat", json={"text": "<b>" * 200})
        assert too_long.status_code == 422
        assert "<b>" not in too_long.text
        assert client.post("/api/admin/robots/lefkos/chat", json={"text": ""}).status_code == 422
        cross = {"origin": "http://evil.example"}
        assert (
            client.post("/api/admin/robots/lefkos/chat", json={"text": "hi"}, headers=cross).status_code
            == 403
        )
        codes = [
            client.post("/api/admin/robots/lefkos/chat", json={"text": f"r{i}"}).status_code for i in range(5)
        ]
        assert codes[:3] == [200, 200, 200]
        assert codes[3:] == [429, 429]


def test_the_onboard_screen_sees_and_answers_the_holder(client: TestClient) -> None:
    holder = new_session(client)
    client.cookies.clear()
    client.get(f"/onboard/pair?token={PAIRING}", follow_redirects=False)
    screen = client.cookies.get(COOKIE)
    client.cookies.clear()
    assert screen
    with connect(client, screen, query="?screen=onboard") as onboard:
        onboard.send_text(json.dumps({"type": "chat", "text": "anyone there?"}))
        assert "no web visitor" in wait_for(onboard, lambda m: m["type"] == "error")["message"]
        with connect(client, holder) as a:
            a.send_text(json.dumps({"type": "book"}))
            wait_for(a, role_is("holder"))
            a.send_text(json.dumps({"type": "chat", "text": "Hello from far away"}))
            got = wait_for(onboard, lambda m: m["type"] == "chat")
            assert (got["sender"], got["text"]) == ("visitor", "Hello from far away")
            onboard.send_text(json.dumps({"type": "chat", "text": "Hello from the museum"}))
            back = wait_for(a, lambda m: m["type"] == "chat" and m["sender"] == "onboard")
            assert back["text"] == "Hello from the museum"


def test_the_holder_asks_to_move_around_an_exhibit(client: TestClient, robot: FakeRobot) -> None:
    first, second = new_session(client), new_session(client)
    with connect(client, first) as a, connect(client, second) as b:
        b.send_text(json.dumps({"type": "around", "exhibit": "amphora"}))
        assert "book a slot" in wait_for(b, lambda m: m["type"] == "error")["message"]
        a.send_text(json.dumps({"type": "book"}))
        wait_for(a, role_is("holder"))
        a.send_text(json.dumps({"type": "around", "exhibit": "nowhere"}))
        assert wait_for(a, lambda m: m["type"] == "error")["message"] == "no such exhibit or tour"
        a.send_text(json.dumps({"type": "around", "exhibit": "amphora"}))
        wait_for(a, lambda m: m["type"] == "ack" and m["command"] == "around")
        moving = wait_for(a, lambda m: m["type"] == "status" and m["nav"]["tour"] == "around amphora")
        assert moving["nav"]["exhibit"] == "amphora"
    assert robot.commands == [("around", "amphora")]


def test_only_the_holder_gets_a_picture_and_not_too_often(
    robot: FakeRobot, db: Database, tmp_path: Path
) -> None:
    import cv2

    config = WebConfig(speech_dir=tmp_path, photo_interval=1.0)
    with TestClient(create_app({"lefkos": robot}, db, None, config)) as client:
        holder, watcher = new_session(client), new_session(client)
        with connect(client, holder) as a:
            assert client.post("/api/robots/lefkos/photo").status_code == 403  # no session
            client.cookies.set(COOKIE, watcher)
            assert client.post("/api/robots/lefkos/photo").status_code == 403
            a.send_text(json.dumps({"type": "book"}))
            wait_for(a, role_is("holder"))
            client.cookies.set(COOKIE, holder)
            cross = client.post("/api/robots/lefkos/photo", headers={"origin": "http://evil.example"})
            assert cross.status_code == 403
            photo = client.post("/api/robots/lefkos/photo")
            assert photo.status_code == 200
            assert photo.headers["content-type"] == "image/jpeg"
            image = cv2.imdecode(np.frombuffer(photo.content, np.uint8), cv2.IMREAD_GRAYSCALE)
            assert image is not None
            assert image.shape == (48, 64)
            again = client.post("/api/robots/lefkos/photo")
            assert again.status_code == 429
            assert int(again.headers["retry-after"]) >= 1
            time.sleep(1.05)
            assert client.post("/api/robots/lefkos/photo").status_code == 200
            assert client.post("/api/robots/ghost/photo").status_code == 404
        client.cookies.clear()
    assert [c for c in robot.commands if c[0] == "photo"] == [("photo", None), ("photo", None)]


def test_holder_and_watcher_get_the_path_of_a_new_goal(client: TestClient) -> None:
    """The planned path is published by the hub (one JSON text shared by all the viewers)."""
    with connect(client, new_session(client)) as holder, connect(client, new_session(client)) as watcher:
        holder.send_text(json.dumps({"type": "book"}))
        wait_for(holder, role_is("holder"))
        holder.send_text(json.dumps({"type": "goto", "x": 8.0, "y": 2.0}))
        for ws in (holder, watcher):
            path = wait_for(ws, lambda m: m["type"] == "path" and bool(m["points"]))
            assert path["points"][-1] == [8.0, 2.0]
        hub = client.app.state.hubs["lefkos"]  # type: ignore[attr-defined]
        assert hub.path_message is not None
        assert json.loads(hub.path_message)["points"][-1] == [8.0, 2.0]


# --- hardening -------------------------------------------------------------------------------
def login(client: TestClient) -> None:
    response = client.post("/api/login", json={"username": "curator", "password": "correct horse"})
    assert response.status_code == 200


@pytest.mark.parametrize(
    ("method", "path", "staff"),
    [
        ("post", "/api/login", False),
        ("post", "/api/admin/exhibits", False),
        ("post", "/api/admin/exhibits", True),
        ("post", "/api/robots/lefkos/staff-stop", False),
        ("get", "/api/site", False),
    ],
)
def test_a_large_body_is_refused_before_it_is_read_or_authenticated(
    client: TestClient, method: str, path: str, staff: bool
) -> None:
    if staff:
        login(client)
    big = b'{"username": "' + b"x" * 200_000 + b'"}'
    response = client.request(method, path, content=big, headers={"content-type": "application/json"})
    assert response.status_code == 413  # not 401, not 422: refused by its size alone
    assert len(response.content) < 200


def test_a_large_body_without_a_length_is_cut_off(client: TestClient) -> None:
    def chunks() -> Iterator[bytes]:
        for _ in range(100):
            yield b"x" * 10_000

    response = client.post("/api/login", content=chunks(), headers={"content-type": "application/json"})
    assert response.status_code == 413
    assert len(response.content) < 200


def test_errors_never_echo_the_request(client: TestClient) -> None:
    marker = "<script>echo-marker</script>"
    response = client.post("/api/login", json={"username": marker, "password": 5, marker: 1})
    assert response.status_code == 422
    assert "echo-marker" not in response.text
    assert response.json()["detail"]  # still says where and why
    login(client)
    bad_link = {"slug": "lyre", "name": "Lyre", "x": 1, "y": 2, "links": [{"url": "javascript:" + marker}]}
    response = client.post("/api/admin/exhibits", json=bad_link)
    assert response.status_code == 422
    assert "echo-marker" not in response.text
    for path in ("/api/exhibits/echo-marker", "/api/admin/stream/echo-marker"):
        response = client.get(path)
        assert response.status_code == 404
        assert "echo-marker" not in response.text
    with connect(client, new_session(client)) as ws:
        ws.send_text(json.dumps({"type": marker}))
        assert "echo-marker" not in json.dumps(wait_for(ws, lambda m: m["type"] == "error"))
        ws.send_text(json.dumps({"type": "book", marker: 1}))
        assert "echo-marker" not in json.dumps(wait_for(ws, lambda m: m["type"] == "error"))


@pytest.mark.parametrize(
    "url", ["javascript:alert(1)", " JavaScript:alert(1)", "data:text/html,x", "//evil.example/"]
)
def test_javascript_links_are_refused_by_the_api(client: TestClient, url: str) -> None:
    login(client)
    exhibit = {"slug": "lyre", "name": "Lyre", "x": 1, "y": 2, "pictures": [{"url": url}]}
    assert client.post("/api/admin/exhibits", json=exhibit).status_code == 422


def test_new_sessions_are_rate_limited_per_address(client: TestClient) -> None:
    codes = []
    for _ in range(40):
        client.cookies.clear()
        codes.append(client.get("/api/session").status_code)
    assert codes[:20] == [200] * 20
    assert codes.count(429) >= 15
    client.cookies.clear()
    assert client.get("/").status_code == 429  # a page view without a cookie mints one too


def test_one_address_holds_few_queue_places(client: TestClient) -> None:
    """Fresh sessions from one address cannot fill the queue ahead of real visitors."""
    sockets = [connect(client, new_session(client)) for _ in range(5)]
    try:
        answers = []
        for ws in sockets:
            ws.__enter__()
            ws.send_text(json.dumps({"type": "book"}))
            answers.append(wait_for(ws, lambda m: m["type"] in ("ack", "error")))
        assert [a["type"] for a in answers] == ["ack", "ack", "ack", "error", "error"]
        assert "places in the queue" in answers[3]["message"]
        sockets[0].send_text(json.dumps({"type": "book"}))  # booking again keeps the one place
        assert wait_for(sockets[0], lambda m: m["type"] in ("ack", "error"))["type"] == "ack"
    finally:
        for ws in sockets:
            ws.__exit__(None, None, None)


@pytest.mark.parametrize(
    "headers",
    [
        {"origin": "http://127.0.0.1:8899"},  # another port of the same host: same-site, not same-origin
        {"origin": "http://evil.example"},
        {"sec-fetch-site": "same-site"},
        {"sec-fetch-site": "cross-site", "origin": "http://testserver"},
        {"origin": "https://testserver"},
    ],
)
def test_staff_actions_from_another_origin_are_refused(
    client: TestClient, robot: FakeRobot, headers: dict[str, str]
) -> None:
    login(client)
    hub = client.app.state.hubs["lefkos"]  # type: ignore[attr-defined]
    assert client.post("/api/robots/lefkos/staff-stop", headers=headers).status_code == 403
    assert not hub.arbiter.staff_stopped
    assert robot.commands == []
    assert client.post("/api/robots/lefkos/staff-stop").status_code == 200
    assert client.post("/api/robots/lefkos/staff-release", headers=headers).status_code == 403
    assert hub.arbiter.staff_stopped
    assert client.delete("/api/admin/exhibits/loom", headers=headers).status_code == 403
    same = {"origin": "http://testserver", "sec-fetch-site": "same-origin"}
    assert client.post("/api/robots/lefkos/staff-release", headers=same).status_code == 200
    assert not hub.arbiter.staff_stopped


def test_sessions_expire_on_the_server(robot: FakeRobot, db: Database, tmp_path: Path) -> None:
    app = create_app({"lefkos": robot}, db, None, WebConfig(speech_dir=tmp_path, session_idle=1.0))
    with TestClient(app) as client:
        login(client)
        assert client.get("/api/admin/stats").status_code == 200
        time.sleep(1.3)
        assert client.get("/api/admin/stats").status_code == 401  # the cookie is still sent
        token = client.cookies.get(COOKIE)
        assert token is not None
        assert db.session_for(token) is None  # ended in the database too, not just forgotten


def test_an_idle_session_in_the_database_is_not_revived(db: Database) -> None:
    token, _ = db.new_session("web")
    assert db.session_for(token, max_idle=60.0) is not None
    with db.session() as s:
        from tourbot.web.db import VisitorSession

        for row in s.query(VisitorSession):
            row.last_seen -= 120.0
    assert db.session_for(token, max_idle=60.0) is None
    assert db.session_for(token) is None


def test_the_http_api_survives_schemathesis(robot: FakeRobot, db: Database, tmp_path: Path) -> None:
    """Every route of the OpenAPI document fuzzed, logged in as staff: never a server error, and
    every response of the content type and shape the document declares."""
    import schemathesis
    from hypothesis import HealthCheck, given, settings
    from schemathesis.checks import not_a_server_error
    from schemathesis.specs.openapi.checks import content_type_conformance, response_schema_conformance

    config = WebConfig(speech_dir=tmp_path, sessions_per_minute=1e6, login_attempts_per_minute=1_000_000)
    app = create_app({"lefkos": robot}, db, None, config)
    checks = [not_a_server_error, content_type_conformance, response_schema_conformance]
    with LiveServer(app) as url:
        import httpx

        logged_in = httpx.post(f"{url}/api/login", json={"username": "curator", "password": "correct horse"})
        cookie = {COOKIE: str(logged_in.cookies[COOKIE])}
        schema = schemathesis.openapi.from_dict(httpx.get(f"{url}/api/openapi.json").json())
        operations = [result.ok() for result in schema.get_all_operations()]  # type: ignore[union-attr]
        assert len(operations) >= 15
        for operation in operations:

            @settings(max_examples=12, deadline=None, suppress_health_check=list(HealthCheck), database=None)
            @given(case=operation.as_strategy())
            def check(case: Any) -> None:
                case.call_and_validate(base_url=url, cookies=cookie, checks=checks)

            check()


@given(st.lists(st.lists(st.booleans(), min_size=6, max_size=6), min_size=1, max_size=8))
def test_wall_boxes_cover_each_occupied_cell_once(rows: list[list[bool]]) -> None:
    occupied = np.array(rows, dtype=bool)
    cover = np.zeros(occupied.shape, dtype=int)
    for c0, r0, c1, r1 in wall_boxes(occupied):
        assert c1 > c0
        assert r1 > r0
        cover[r0:r1, c0:c1] += 1
    assert np.array_equal(cover, occupied.astype(int))


def test_walls_of_the_fhw_map_are_few_long_boxes() -> None:
    """A one-cell wall running up the map is one box, not a picket fence of cell-row runs; the
    scanned FHW map at 10 cm gives fewer than half as many boxes as it has runs at 5 cm."""
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site

    grid = load_site(site_path("fhw")).grid
    occupied = grid.occupied()
    boxes = wall_boxes(pooled(occupied, round(0.1 / grid.resolution)))  # as the server sends them
    runs = sum(
        int(np.count_nonzero(np.diff(np.concatenate([[0], r.astype(np.int8), [0]])))) // 2 for r in occupied
    )
    assert len(boxes) < 0.5 * runs
    column = np.zeros((40, 5), dtype=bool)
    column[:, 2] = True
    assert wall_boxes(column) == [[2, 0, 3, 40]]


def test_pooling_keeps_every_occupied_cell() -> None:
    occupied = np.zeros((5, 7), dtype=bool)
    occupied[4, 6] = occupied[0, 0] = True
    coarse = pooled(occupied, 2)
    assert coarse.shape == (3, 4)
    assert coarse[2, 3]
    assert coarse[0, 0]
    assert coarse.sum() == 2
