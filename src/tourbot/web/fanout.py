"""The robots' state fanned out through a broker (Redis pub/sub) to several web servers.

One server runs (or is linked to) the robots and takes their control: the slots, the queue and
the commands stay there. Any number of *follower* servers show the same robots to their own
viewers: each follows the robots' views through the broker and streams them with its own hub, so
the viewers of one robot are spread over processes and machines. A follower refuses to book a
slot and points to the controlling server instead (:attr:`tourbot.web.app.WebConfig.control_url`).

On the controlling server each link is wrapped in a :class:`PublishingLink`: every view the hub
samples (5 times a second) is handed to a publisher thread, which sends the latest one, so the
hub's event loop never waits on the network. A follower's :class:`FollowerLink` keeps the latest
view it received; once none has come for ``stale_after`` seconds, the view is shown at rest and
marked ``failed`` ("no news from the robot's server"), and recovers by itself when views resume.

A view travels as compact JSON on the channel ``tourbot:<site>:<robot>`` (:func:`channel`), with
the time it was published (``sent``); :func:`publish_delays` measures the hop.
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
import time
from dataclasses import asdict, replace
from typing import TYPE_CHECKING, Any

from tourbot.errors import TourbotError
from tourbot.web.link import NavStatus, ObjectView, PersonView, RobotLink, RobotView

if TYPE_CHECKING:
    import redis

__all__ = [
    "BrokerError",
    "FollowerLink",
    "PublishingLink",
    "channel",
    "connect",
    "decode_view",
    "encode_view",
    "publish_delays",
]

log = logging.getLogger(__name__)


class BrokerError(TourbotError):
    """The broker cannot be reached, or a message on it is not a robot's view."""


def channel(site: str, robot: str) -> str:
    """The broker channel of one robot of one site."""
    return f"tourbot:{site}:{robot}"


def connect(url: str) -> redis.Redis:
    """A client of the broker at ``url`` (``redis://host:port/db``), checked by a ping."""
    import redis

    try:
        client = redis.Redis.from_url(url, socket_connect_timeout=5.0, socket_timeout=10.0)
        client.ping()
    except ValueError as exc:
        raise BrokerError(f"{url}: not a broker URL ({exc})") from None
    except redis.RedisError as exc:
        raise BrokerError(f"cannot reach the broker at {url}: {exc}") from None
    return client


def encode_view(view: RobotView, sent: float | None = None) -> bytes:
    """A view as compact JSON (positions rounded to the millimetre); ``sent``: when it was
    published (unix s), for the followers' delay."""
    data: dict[str, Any] = asdict(view)
    if sent is not None:
        data["sent"] = sent
    for key in ("x", "y", "theta", "v", "omega"):
        data[key] = round(data[key], 4)
    for key in ("people", "truth"):
        data[key] = [[p["id"], *(round(p[k], 3) for k in ("x", "y", "vx", "vy"))] for p in data[key]]
    data["obstacles"] = [[round(x, 2), round(y, 2)] for x, y in data["obstacles"]]
    return json.dumps(data, separators=(",", ":")).encode()


def _people(rows: Any) -> tuple[PersonView, ...]:
    return tuple(PersonView(int(r[0]), float(r[1]), float(r[2]), float(r[3]), float(r[4])) for r in rows)


def decode_view(message: bytes) -> RobotView:
    """The view of :func:`encode_view`; :class:`BrokerError` for anything else."""
    try:
        data = json.loads(message)
        nav = data["nav"]
        status = NavStatus(
            state=str(nav["state"]),
            exhibit=None if nav["exhibit"] is None else str(nav["exhibit"]),
            goal=None if nav["goal"] is None else (float(nav["goal"][0]), float(nav["goal"][1])),
            path=tuple((float(a), float(b)) for a, b in nav["path"]),
            blocked_time=float(nav["blocked_time"]),
            tour=None if nav["tour"] is None else str(nav["tour"]),
            tour_progress=(int(nav["tour_progress"][0]), int(nav["tour_progress"][1])),
            message=str(nav["message"]),
        )
        c = data["covariance"]
        return RobotView(
            t=float(data["t"]),
            x=float(data["x"]),
            y=float(data["y"]),
            theta=float(data["theta"]),
            v=float(data["v"]),
            omega=float(data["omega"]),
            covariance=(float(c[0]), float(c[1]), float(c[2])),
            people=_people(data["people"]),
            nav=status,
            truth=_people(data["truth"]),
            obstacles=tuple((float(x), float(y)) for x, y in data.get("obstacles", ())),
            objects=tuple(
                ObjectView(
                    str(o["name"]), str(o["kind"]), tuple((float(x), float(y)) for x, y in o["outline"])
                )
                for o in data.get("objects", ())
            ),
        )
    except (ValueError, KeyError, TypeError, IndexError) as exc:
        raise BrokerError(f"not a robot view on the broker ({type(exc).__name__}: {exc})") from None


def publish_delays(url: str, channel: str, seconds: float) -> list[float]:
    """Listen on ``channel`` for ``seconds``: each view's arrival minus its publication (s)."""
    client = connect(url)
    pubsub = client.pubsub(ignore_subscribe_messages=True)
    pubsub.subscribe(channel)
    delays: list[float] = []
    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end:
            message = pubsub.get_message(timeout=0.5)
            if message is not None and message.get("type") == "message":
                with contextlib.suppress(ValueError, KeyError, TypeError):
                    delays.append(time.time() - float(json.loads(message["data"])["sent"]))
    finally:
        pubsub.close()
        client.close()
    return delays


class PublishingLink:
    """A robot link whose every sampled view is also published on the broker (by a thread of its
    own, latest view only); steps and commands go to the wrapped link."""

    def __init__(self, link: RobotLink, client: redis.Redis, channel: str) -> None:
        self.link = link
        self.period = link.period
        self.channel = channel
        self.published = 0
        self._client = client
        self._latest: RobotView | None = None
        self._wake = threading.Condition()
        self._closed = False
        self._thread = threading.Thread(target=self._publish, name=f"publish-{channel}", daemon=True)
        self._thread.start()

    def _publish(self) -> None:
        import redis

        while True:
            with self._wake:
                while self._latest is None and not self._closed:
                    self._wake.wait()
                view, self._latest = self._latest, None
                if self._closed or view is None:
                    return
            try:
                self._client.publish(self.channel, encode_view(view, time.time()))
                self.published += 1
            except redis.RedisError as exc:  # the broker went away: the followers say so; retry
                log.warning("cannot publish on %s: %s", self.channel, exc)
                time.sleep(1.0)

    def step(self) -> None:
        self.link.step()

    def view(self) -> RobotView:
        view = self.link.view()
        with self._wake:
            self._latest = view
            self._wake.notify()
        return view

    def send_goal(self, x: float, y: float, theta: float | None = None, exhibit: str | None = None) -> None:
        self.link.send_goal(x, y, theta, exhibit)

    def start_tour(self, name: str, exhibits: list[tuple[str, float, float, float]]) -> None:
        self.link.start_tour(name, exhibits)

    def stop(self) -> None:
        self.link.stop()

    def around(self, exhibit: str, x: float, y: float, theta: float) -> None:
        self.link.around(exhibit, x, y, theta)

    def photo(self) -> bytes:
        return self.link.photo()

    def close(self) -> None:
        with self._wake:
            self._closed = True
            self._wake.notify()
        self._thread.join(5.0)
        close = getattr(self.link, "close", None)
        if callable(close):
            close()


class FollowerLink:
    """A robot shown, not controlled: its views as the controlling server publishes them.

    ``controlled_at`` is the address of the controlling server: the follower's server refuses
    every command of its viewers and points them there. Commands on the link itself raise
    :class:`BrokerError`. ``wait_ready`` waits for the first view.
    """

    period = 0.2

    def __init__(
        self, client: redis.Redis, channel: str, *, controlled_at: str, stale_after: float = 3.0
    ) -> None:
        self.channel = channel
        self.controlled_at = controlled_at
        self.stale_after = stale_after
        self.received = 0
        self._view: RobotView | None = None
        self._at = 0.0
        self._ready = threading.Event()
        self._closed = threading.Event()
        self._client = client  # kept: a client that is collected disconnects its pool, pubsub included
        self._pubsub = client.pubsub(ignore_subscribe_messages=True)
        self._pubsub.subscribe(channel)
        self._thread = threading.Thread(target=self._follow, name=f"follow-{channel}", daemon=True)
        self._thread.start()

    def _follow(self) -> None:
        import redis

        while not self._closed.is_set():
            try:
                message = self._pubsub.get_message(timeout=0.5)
            except redis.RedisError as exc:
                log.warning("lost the broker on %s: %s", self.channel, exc)
                self._closed.wait(1.0)
                continue
            if message is None or message.get("type") != "message":
                continue
            try:
                view = decode_view(message["data"])
            except BrokerError as exc:
                log.warning("%s: %s", self.channel, exc)
                continue
            self._view, self._at = view, time.monotonic()
            self.received += 1
            self._ready.set()

    def wait_ready(self, timeout: float = 30.0) -> None:
        if not self._ready.wait(timeout):
            raise BrokerError(f"no view of the robot on {self.channel} within {timeout:.0f} s")

    def step(self) -> None:
        """Nothing: the robot runs behind the controlling server."""

    def view(self) -> RobotView:
        self.wait_ready()
        view = self._view
        assert view is not None
        if time.monotonic() - self._at > self.stale_after:
            nav = replace(view.nav, state="failed", message="no news from the robot's server")
            return replace(view, v=0.0, omega=0.0, nav=nav)
        return view

    def _refuse(self) -> None:
        raise BrokerError("this server only shows the robot: it is controlled on another server")

    def send_goal(self, x: float, y: float, theta: float | None = None, exhibit: str | None = None) -> None:  # noqa: ARG002
        self._refuse()

    def start_tour(self, name: str, exhibits: list[tuple[str, float, float, float]]) -> None:  # noqa: ARG002
        self._refuse()

    def stop(self) -> None:
        self._refuse()

    def around(self, exhibit: str, x: float, y: float, theta: float) -> None:  # noqa: ARG002
        self._refuse()

    def photo(self) -> bytes:
        self._refuse()
        return b""

    def close(self) -> None:
        self._closed.set()
        self._thread.join(5.0)
        with contextlib.suppress(Exception):
            self._pubsub.close()
