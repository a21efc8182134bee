"""One robot on the server: its link, its control slots, its latest state, its announcements.

The hub keeps the robot's loop running (``link.step`` in a worker thread, paced to real time),
samples the robot's view at the stream rate, arbitrates control (:mod:`tourbot.web.slots`) and
records bookings and visits in the database. Each state is encoded and framed once for all the
viewers (:class:`~tourbot.web.stream.StreamBroadcast`), and the hub itself writes that frame to
every viewer (:class:`StreamViewer`) in one pass: no task per viewer wakes for the stream. A viewer
that cannot take a frame at once (its socket's buffer full) is skipped and gets a keyframe of the
latest state when it can: clients never queue behind each other, and nothing piles up. The JSON
texts (status, path, speech) go through each connection's own task, woken only when one changed.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import math
import re
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

from tourbot.web.db import Database, DatabaseError, MessageData
from tourbot.web.face import FaceConfig, face_for
from tourbot.web.link import RobotLink, RobotView
from tourbot.web.slots import SlotArbiter, SlotConfig, SlotEvent
from tourbot.web.stream import MAX_BODIES, Body, ObjectsPayload, Scene, StreamBroadcast, StreamConfig

__all__ = [
    "Announcement",
    "RobotClock",
    "RobotHub",
    "StreamViewer",
    "nav_status",
    "path_moved",
    "path_points",
    "robots_summary",
    "scene_of",
]

log = logging.getLogger(__name__)
T = TypeVar("T")


def scene_of(view: RobotView, t: float, max_people: int = MAX_BODIES - 1, rate: float = 1.0) -> Scene:
    """The streamed scene of a view at wall-clock ``t``; track ids map into the stream's 1..65535.

    The stream runs on the wall clock (the viewers' clock); the view's velocities are per second
    of the robot's clock, which a simulated robot on a loaded machine runs slower than the wall
    (``rate``, the robot's seconds per wall second, :class:`RobotClock`). They are streamed per
    wall second (times ``rate``), so that a viewer's dead reckoning moves a body as far as it
    moves: otherwise every avatar overshoots by the lag and is resent more often, the more loaded
    the machine.

    A message carries at most ``MAX_BODIES`` bodies: in a denser crowd the people nearest to the
    robot are streamed.
    """
    v = view.v * rate
    vx, vy = v * math.cos(view.theta), v * math.sin(view.theta)
    robot = Body(0, view.x, view.y, vx, vy, view.theta, view.omega * rate)
    people = {}
    nearest = view.people
    if len(nearest) > max_people:
        nearest = tuple(sorted(nearest, key=lambda p: math.hypot(p.x - view.x, p.y - view.y))[:max_people])
    for p in nearest:
        i = p.id % 65535 + 1
        people[i] = Body(i, p.x, p.y, p.vx * rate, p.vy * rate)
    return Scene(t, robot, tuple(people.values()))


@dataclass
class RobotClock:
    """How fast the robot's clock runs against the wall's: the robot's seconds per wall second
    over the last ``window`` wall seconds (1 for a real robot; a simulated one on a loaded
    machine falls behind). A robot clock that goes back (a restarted robot process) starts the
    window afresh; until ``window / 4`` of wall time is seen the rate is taken as 1."""

    window: float = 2.0
    _samples: deque[tuple[float, float]] = field(default_factory=deque)

    def rate(self, wall: float, robot: float) -> float:
        samples = self._samples
        if samples and robot < samples[-1][1]:
            samples.clear()
        samples.append((wall, robot))
        while len(samples) > 2 and wall - samples[1][0] >= self.window:
            samples.popleft()
        span = wall - samples[0][0]
        if span < self.window / 4:
            return 1.0
        return (robot - samples[0][1]) / span


_RUNNING_COUNT = re.compile(r" for \d+ s\b")


def nav_status(view: RobotView | None) -> dict[str, Any]:
    """The navigation part of the pages' status message. A navigator's running count ("blocked
    for 12 s") is left out: the status is resent only when something a visitor cares about
    changed, not once a second to every viewer."""
    if view is None:
        return {"state": "idle"}
    nav = view.nav
    return {
        "state": nav.state,
        "exhibit": nav.exhibit,
        "tour": nav.tour,
        "progress": list(nav.tour_progress),
        "message": _RUNNING_COUNT.sub("", nav.message),
        "goal": None if nav.goal is None else [round(nav.goal[0], 2), round(nav.goal[1], 2)],
    }


def path_points(view: RobotView) -> list[tuple[float, float]]:
    """The planned path, thinned to at most 24 points at 10 cm (the page trims what is travelled)."""
    path = view.nav.path
    if not path:
        return []
    step = max(1, math.ceil(len(path) / 24))
    points = [*path[::step], path[-1]]
    return [(round(x, 1), round(y, 1)) for x, y in points]


def path_moved(
    new: list[tuple[float, float]], old: list[tuple[float, float]], tolerance: float = 1.0
) -> bool:
    """Whether a replanned path left the published one by more than ``tolerance`` (m)."""
    if not old:
        return bool(new)
    return any(min(math.hypot(x - u, y - v) for u, v in old) > tolerance for x, y in new)


def robots_summary(museum: list[RobotHub]) -> list[dict[str, Any]]:
    """Each robot's control queue as a visitor choosing a robot sees it (no one's identity)."""
    return [
        {
            "name": hub.name,
            "driven": hub.arbiter.holder is not None,
            "waiting": len(hub.arbiter.queue),
            "staff_stop": hub.arbiter.staff_stopped,
        }
        for hub in museum
    ]


@dataclass(eq=False)
class StreamViewer:
    """One viewer's end of the stream: ``write(message, frame)`` hands it a message (and that
    message's WebSocket frame) and says whether it took it at once; ``held`` is the stream state it
    holds (0: none yet)."""

    write: Callable[[bytes, bytes], bool]
    held: int = 0


@dataclass(frozen=True)
class Announcement:
    """Something the robot says: the text, and the audio file's name when speech is available."""

    seq: int
    text: str
    audio: str | None


@dataclass
class RobotHub:
    name: str
    link: RobotLink
    db: Database
    robot_id: int
    slot_config: SlotConfig = field(default_factory=SlotConfig)
    face_config: FaceConfig = field(default_factory=FaceConfig)
    rate_hz: float = 5.0
    speak: Callable[[str], str | None] | None = None
    drive: bool = True
    stream_config: StreamConfig = field(default_factory=StreamConfig)
    path_check_period: float = 5.0  # a replanned path is republished when it moved (checked this often)
    # moving <-> blocked (and the navigator's text with them) published once steady this long (s):
    # in a crowd the robot is slowed and freed every second, and every viewer would get each flip
    steady_time: float = 1.5
    obstacle_cell: float = 0.1  # m: the vision map's resolution
    obstacle_period: float = 1.0  # s: vision obstacles republished at most this often
    # s: a page's status at most this often (a change of its own role at once; see app._send_loop)
    status_period: float = 2.0

    def __post_init__(self) -> None:
        self.lock = threading.Lock()
        self.arbiter: SlotArbiter[int] = SlotArbiter(self.slot_config)
        self.view: RobotView | None = None
        self.scene: Scene | None = None
        self.stream = StreamBroadcast(self.stream_config)  # each state encoded once for all viewers
        self.clock = RobotClock()  # the robot's clock against the wall's: the stream's velocities
        self.nav_status: dict[str, Any] = nav_status(None)
        self.status_version = 0  # changes when the navigation status or the slots changed
        self._status_key: object = None
        self.path_message: str | None = None  # the path as the pages get it (JSON), shared
        # the forward camera's obstacles (JSON, on change), drawn in their own colour on the map
        self.obstacles_message: str | None = None
        self._obstacle_cells: list[tuple[int, int]] = []
        self._obstacles_at = -math.inf
        self.objects = ObjectsPayload()  # doors and furniture (JSON in .message), made on change
        # the museum's robots and their queues, for the page's choice of robot (JSON, on change)
        self.robots_message: str | None = None
        self._robots: list[dict[str, Any]] | None = None
        # debug overlay: a simulator's true people (JSON, once a second) while a debug page watches
        self.truth_message: str | None = None
        self.debug_viewers = 0
        self._truth_at = 0.0
        self._path: list[tuple[float, float]] = []
        self._path_goal: object = None
        self._path_checked = 0.0
        self.version = 0
        self.announcements: list[Announcement] = []
        self.chat: list[MessageData] = []  # the text channel's latest messages, for delivery
        self.photo_at = float("-inf")  # when the last high-resolution picture was asked for
        self.send_delays: deque[float] = deque(maxlen=100_000)
        self.viewers: set[StreamViewer] = set()  # the stream's viewers, written to by the hub
        self.texts_version = 0  # changes when a text a page shows may have changed (see notify)
        self._texts_key: tuple[object, ...] | None = None
        self.connections: dict[int, int] = {}
        self.museum: list[RobotHub] = [self]  # every robot of the server (a visitor books one at a time)
        self._bookings: dict[int, int] = {}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._task: asyncio.Task[None] | None = None
        self._changed: asyncio.Event | None = None  # set at a change, then replaced by a fresh one
        self._texts_changed: asyncio.Event | None = None  # the same, for the texts
        self._last_state: tuple[str, str | None] = ("idle", None)
        self._presented: tuple[str | None, str] | None = None
        self._pending_since: float | None = None

    # --- lifecycle --------------------------------------------------------------------------
    async def start(self) -> None:
        self._changed = asyncio.Event()
        self._texts_changed = asyncio.Event()
        self._slot_lock = asyncio.Lock()
        self._pending: set[asyncio.Future[None]] = set()
        if self.drive:
            self._thread = threading.Thread(target=self._run_robot, name=f"robot-{self.name}", daemon=True)
            self._thread.start()
        await self.refresh()
        self._task = asyncio.create_task(self._ticker())

    async def close(self) -> None:
        self._stop.set()
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        if self._thread is not None:
            await asyncio.to_thread(self._thread.join, 5.0)
        close = getattr(self.link, "close", None)  # a robot in its own process (ProcessLink)
        if callable(close):
            await asyncio.to_thread(close)
        now = time.time()
        for session, booking in list(self._bookings.items()):
            self._end_booking(session, booking, now, "server stopped")

    def _run_robot(self) -> None:
        """The robot's own loop, paced to real time; an error stops the robot, not the server."""
        period = float(getattr(self.link, "period", 0.1))
        next_time = time.monotonic()
        while not self._stop.is_set():
            try:
                with self.lock:
                    self.link.step()
            except Exception:
                log.exception("robot %s: step failed; the robot loop stops", self.name)
                return
            next_time += period
            delay = next_time - time.monotonic()
            if delay < -1.0:  # far behind (slow machine): do not try to catch up in a burst
                next_time = time.monotonic()
            self._stop.wait(max(0.0, delay))

    async def _ticker(self) -> None:
        """:meth:`refresh` at ``rate_hz``, paced to the clock (a refresh that writes to many
        viewers on a loaded machine does not slow the rate), never in a burst to catch up."""
        period = 1.0 / self.rate_hz
        next_time = time.monotonic()
        while not self._stop.is_set():
            next_time += period
            delay = next_time - time.monotonic()
            if delay < -period:  # far behind: start afresh
                next_time, delay = time.monotonic(), 0.0
            await asyncio.sleep(max(0.0, delay))
            try:
                await self.refresh()
            except Exception:
                log.exception("robot %s: refresh failed", self.name)

    # --- state ------------------------------------------------------------------------------
    async def refresh(self) -> None:
        """Sample the robot, update the slots, announce arrivals, wake the connections."""
        view = self.link.view()  # thread-safe by contract: never wait on the robot's step here
        now = time.time()
        self.view = view
        self.scene = scene_of(view, now, rate=self.clock.rate(now, view.t))
        self.stream.push(self.scene)
        for viewer in tuple(self.viewers):
            self._send_stream(viewer)
        self.nav_status = self._steady(nav_status(view), now)
        self._publish_path(view, now)
        self._publish_obstacles(view, now)
        self.objects.update(view.objects)  # doors and furniture as estimated: a message on change
        if self.debug_viewers > 0 and now - self._truth_at >= 1.0:
            self._truth_at = now
            points = [[round(p.x, 1), round(p.y, 1)] for p in view.truth]
            self.truth_message = json.dumps({"type": "truth", "people": points}, separators=(",", ":"))
        await self._sync_slots(now)
        self._publish_robots()
        state = (view.nav.state, view.nav.exhibit)
        if state != self._last_state and state[0] == "arrived" and state[1] is not None:
            # an exhibit is presented once per tour: moving around it stops at it several times
            presented = (view.nav.tour, state[1])
            if view.nav.tour is None or presented != self._presented:
                await self._arrived(state[1])
            self._presented = presented
        self._last_state = state
        await self.notify()

    def _steady(self, status: dict[str, Any], now: float) -> dict[str, Any]:
        """The status to publish: a change between ``moving`` and ``blocked`` on the same task
        waits until it has held for ``steady_time``; anything else is published at once."""
        published = self.nav_status
        flapping = {"moving", "blocked"}
        same_task = all(status[k] == published.get(k) for k in ("exhibit", "tour", "progress", "goal"))
        if status == published or not (
            same_task and status["state"] in flapping and published.get("state") in flapping
        ):
            self._pending_since = None
            return status
        if self._pending_since is None:
            self._pending_since = now
        return status if now - self._pending_since >= self.steady_time else published

    def _publish_path(self, view: RobotView, now: float) -> None:
        """A path message with a new goal, then only when a replan moved the path."""
        goal = self.nav_status["goal"]
        if goal == self._path_goal and (goal is None or now - self._path_checked < self.path_check_period):
            return
        self._path_checked = now
        points = path_points(view)
        if goal != self._path_goal or path_moved(points, self._path):
            self._path_goal, self._path = goal, points
            self.path_message = json.dumps({"type": "path", "points": points}, separators=(",", ":"))

    def _publish_robots(self) -> None:
        """The museum's robots with their queues (:func:`robots_summary`): a message when a robot
        was taken, freed, stopped by staff or its queue changed; the pages never poll for it."""
        robots = robots_summary(self.museum)
        if robots != self._robots:
            self._robots = robots
            self.robots_message = json.dumps({"type": "robots", "robots": robots}, separators=(",", ":"))

    def _publish_obstacles(self, view: RobotView, now: float) -> None:
        """The vision obstacles as cells of ``obstacle_cell`` metres: a message when the set of
        cells changed, at most every ``obstacle_period`` seconds (the map grows slowly)."""
        if now - self._obstacles_at < self.obstacle_period:
            return
        size = self.obstacle_cell
        cells = sorted({(round(x / size), round(y / size)) for x, y in view.obstacles})
        if cells == self._obstacle_cells:
            return
        self._obstacles_at, self._obstacle_cells = now, cells
        points = [[round(i * size, 2), round(j * size, 2)] for i, j in cells]
        message = {"type": "obstacles", "cell": size, "points": points}
        self.obstacles_message = json.dumps(message, separators=(",", ":"))

    # --- the stream's viewers -----------------------------------------------------------------
    def watch(self, viewer: StreamViewer) -> None:
        """A new viewer of the stream: it gets a keyframe now (once there is a state), then every
        state from the hub's :meth:`refresh`."""
        self.viewers.add(viewer)
        self._send_stream(viewer)

    def unwatch(self, viewer: StreamViewer) -> None:
        self.viewers.discard(viewer)

    def _send_stream(self, viewer: StreamViewer) -> None:
        """What ``viewer`` needs to hold the latest state, if it can take it now."""
        scene = self.scene
        if scene is None:
            return
        framed = self.stream.frame_for(viewer.held)
        if framed is None:  # it holds the latest state already, or nothing changed
            viewer.held = self.stream.version
        elif viewer.write(*framed):
            viewer.held = self.stream.version
            self.send_delays.append(time.time() - scene.t)
        # else: a slow viewer keeps what it held and gets a keyframe of a later state

    async def notify(self) -> None:
        self.version += 1
        a = self.arbiter
        key = (a.holder, tuple(a.queue), a.staff_stopped, self.nav_status)
        if key != self._status_key:
            self._status_key, self.status_version = key, self.status_version + 1
        texts = (
            self.status_version,
            a.onboard_active(time.time()),
            self.path_message,
            self.obstacles_message,
            self.objects.message,
            self.robots_message,
            self.truth_message,
            self.announcements[-1] if self.announcements else None,
            self.chat[-1] if self.chat else None,
        )
        old = self._texts_key
        if old is None or any(x is not y for x, y in zip(texts, old, strict=True)):
            self._texts_key, self.texts_version = texts, self.texts_version + 1
            if self._texts_changed is not None:
                changed, self._texts_changed = self._texts_changed, asyncio.Event()
                changed.set()
        if self._changed is not None:
            changed, self._changed = self._changed, asyncio.Event()
            changed.set()  # wakes every waiting connection at once (no lock to pass along)

    async def wait_change(self, seen: int, timeout: float | None = None) -> int:
        """Wait until the state is newer than ``seen`` (or ``timeout`` s); the current version."""
        assert self._changed is not None
        if self.version == seen:
            if timeout is None:
                await self._changed.wait()
            else:
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self._changed.wait(), timeout)
        return self.version

    async def wait_texts(self, seen: int, timeout: float | None = None) -> int:
        """Wait until a text the pages show may have changed since ``texts_version`` ``seen`` (or
        ``timeout`` s): the status (slots, navigation, the on-board screen's presence), the path,
        the obstacles, the objects, the robots' list, the debug overlay, an announcement or a chat
        line; the current texts version."""
        assert self._texts_changed is not None
        if self.texts_version == seen:
            if timeout is None:
                await self._texts_changed.wait()
            else:
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self._texts_changed.wait(), timeout)
        return self.texts_version

    async def _arrived(self, exhibit: str) -> None:
        try:
            data = await asyncio.to_thread(self.db.exhibit, exhibit)
            text = data.summary or f"Here is {data.name}."
        except DatabaseError:
            text = "We have arrived."
        await self.announce(text)

    async def announce(self, text: str) -> Announcement:
        audio = None
        if self.speak is not None:
            try:
                audio = await asyncio.to_thread(self.speak, text)
            except Exception as exc:  # speech is a nicety: the text still shows
                log.warning("robot %s: speech failed: %s", self.name, exc)
        item = Announcement(len(self.announcements) + 1, text, audio)
        self.announcements.append(item)
        del self.announcements[:-20]
        await self.notify()
        return item

    async def post_chat(self, session: int, sender: str, text: str) -> MessageData:
        """A message of the conversation with visitor ``session``: stored, then delivered to that
        visitor's pages and the on-board screens (the staff page reads the database)."""
        item = await asyncio.to_thread(self.db.add_message, self.robot_id, session, sender, text, time.time())
        self.chat.append(item)
        del self.chat[:-50]
        await self.notify()
        return item

    def face(self) -> dict[str, object]:
        view = self.view
        if view is None:
            return {"mood": "happy", "gaze": 0.0}
        face = face_for((view.x, view.y, view.theta), view.nav.path, view.nav.blocked_time, self.face_config)
        return {"mood": face.mood, "gaze": round(face.gaze / 0.1) * 0.1}

    # --- slots and bookings -----------------------------------------------------------------
    async def connect(self, session: int) -> None:
        self.connections[session] = self.connections.get(session, 0) + 1

    async def disconnect(self, session: int) -> None:
        """A page closed. Its session keeps its slot or queue place for the arbiter's answer
        timeout (the grace time): a reload, a second tab or a short network loss keeps control;
        only a ``leave`` gives it up at once."""
        left = self.connections.get(session, 0) - 1
        if left > 0:
            self.connections[session] = left
            return
        self.connections.pop(session, None)
        now = time.time()
        self.arbiter.seen(session, now)  # the grace time runs from the last page's closing
        await self._sync_slots(now)
        await self.notify()

    async def slot_changed(self) -> None:
        now = time.time()
        await self._sync_slots(now)
        await self.notify()

    async def _sync_slots(self, now: float) -> None:
        """Apply time to the slots and record the changes of holder, one caller at a time.

        Shielded: a caller cancelled midway (a closing connection) must not lose the events it took.
        """

        async def sync() -> None:
            async with self._slot_lock:
                self.arbiter.update(now)
                await self._handle(self.arbiter.take_events(), now)

        task = asyncio.ensure_future(sync())
        self._pending.add(task)
        task.add_done_callback(self._pending.discard)
        await asyncio.shield(task)

    async def _handle(self, events: list[SlotEvent], now: float) -> None:
        for event in events:
            session = int(str(event.client))
            if event.kind == "started":
                self._bookings[session] = await asyncio.to_thread(
                    self.db.booking_started, self.robot_id, session, now
                )
            elif event.kind == "ended" and session in self._bookings:
                booking = self._bookings.pop(session)
                await asyncio.to_thread(self.db.booking_ended, booking, now, event.reason)

    def _end_booking(self, session: int, booking: int, now: float, reason: str) -> None:
        self._bookings.pop(session, None)
        self.db.booking_ended(booking, now, reason)

    # --- commands (already authorised by the caller) ------------------------------------------
    async def command(self, action: Callable[[RobotLink], T]) -> T:
        """Run ``action`` on the link between two robot steps (in a worker thread: the event loop
        never waits for a step); its result."""

        def locked() -> T:
            with self.lock:
                return action(self.link)

        return await asyncio.to_thread(locked)
