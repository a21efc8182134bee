"""Exclusive control slots: one web visitor at a time steers a robot (Burgard et al., section 6.1).

"They can control the robot exclusively for a fixed amount of time which generally is set to 10
minutes per user." The others watch and wait in a queue. A slot ends early when its holder leaves
or stops answering. The on-board touch screen (visitors standing beside the robot) and a staff
stop take precedence over the web holder: while either is active, no web command moves the robot.

Pure logic: every method takes the time ``now`` (seconds) and nothing here reads a clock, talks
to a robot or a database. One :class:`SlotArbiter` per robot, so several robots have their own
queues.
"""

from __future__ import annotations

from collections.abc import Hashable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Generic, TypeVar

__all__ = ["Role", "SlotArbiter", "SlotConfig", "SlotEvent", "SlotView"]

Client = TypeVar("Client", bound=Hashable)


@dataclass(frozen=True)
class SlotConfig:
    """Slot length: the paper's 10 minutes (section 6.1). Silence timeout: a holder whose page
        stopped answering (closed laptop, lost network) frees the robot after this long. On-board hold:
        how long a touch on the robot's own screen keeps web commands off. Places per group: the queue
    places (the slot included) that clients of one group (the server's: one network address) may hold
    at once, so that one machine cannot fill the queue with fresh sessions. Each client has one place
    at most (booking again changes nothing), and a holder whose page reloads keeps the slot: only
    ``answer_timeout`` of silence ends it (the grace time of a lost connection)."""

    slot_length: float = 600.0
    answer_timeout: float = 20.0
    onboard_hold: float = 60.0
    places_per_group: int = 3


class Role(StrEnum):
    HOLDER = "holder"
    QUEUED = "queued"
    WATCHER = "watcher"


@dataclass(frozen=True)
class SlotEvent:
    """A change of holder: ``started`` for the new holder, or ``ended`` with the reason."""

    kind: str
    client: Hashable
    reason: str


@dataclass(frozen=True)
class SlotView:
    """What one client is shown: its role, its place in the queue (1 = next), the time left."""

    role: Role
    position: int
    queue_length: int
    time_left: float
    onboard: bool
    staff_stop: bool

    def as_dict(self) -> dict[str, object]:
        return {
            "role": self.role.value,
            "position": self.position,
            "queue_length": self.queue_length,
            "time_left": round(self.time_left, 1),
            "onboard": self.onboard,
            "staff_stop": self.staff_stop,
        }


@dataclass
class SlotArbiter(Generic[Client]):
    """The queue and the current holder of one robot."""

    config: SlotConfig = field(default_factory=SlotConfig)
    holder: Client | None = None
    holder_since: float = 0.0
    queue: list[Client] = field(default_factory=list)
    staff_stopped: bool = False
    _onboard_until: float = float("-inf")
    _last_seen: dict[Client, float] = field(default_factory=dict)
    _groups: dict[Client, Hashable] = field(default_factory=dict)
    _events: list[SlotEvent] = field(default_factory=list)

    def book(self, client: Client, now: float, group: Hashable | None = None) -> bool:
        """``client`` asks for control: it joins the queue (again asking changes nothing). False,
        and nothing changes, when its ``group`` already holds ``places_per_group`` places."""
        self.update(now)
        if client == self.holder or client in self.queue:
            self._last_seen[client] = now
            return True
        if group is not None:
            members = [c for c in [self.holder, *self.queue] if c is not None]
            if sum(self._groups.get(c) == group for c in members) >= self.config.places_per_group:
                return False
            self._groups[client] = group
        self._last_seen[client] = now
        self.queue.append(client)
        self.update(now)
        return True

    def leave(self, client: Client, now: float) -> None:
        """``client`` gives up its slot or its place in the queue (or its page closed)."""
        if client == self.holder:
            self._end("left", now)
        elif client in self.queue:
            self.queue.remove(client)
        self._last_seen.pop(client, None)
        self._groups.pop(client, None)
        self.update(now)

    def seen(self, client: Client, now: float) -> None:
        """``client`` answered (any message or heartbeat)."""
        if client == self.holder or client in self.queue:
            self._last_seen[client] = now

    def onboard_touch(self, now: float) -> None:
        """Someone uses the robot's own screen: the web holder waits for ``onboard_hold``."""
        self._onboard_until = now + self.config.onboard_hold

    def onboard_active(self, now: float) -> bool:
        return now < self._onboard_until

    def staff_stop(self) -> None:
        self.staff_stopped = True

    def staff_release(self) -> None:
        self.staff_stopped = False

    def may_command(self, client: Client, now: float) -> bool:
        """Only the holder moves the robot, and not while the on-board screen or staff rule."""
        self.update(now)
        return (
            self.holder is not None
            and client == self.holder
            and not self.staff_stopped
            and not self.onboard_active(now)
        )

    def time_left(self, now: float) -> float:
        if self.holder is None:
            return 0.0
        return min(self.config.slot_length, max(0.0, self.config.slot_length - (now - self.holder_since)))

    def take_events(self) -> list[SlotEvent]:
        """The changes of holder since the last call (for bookings and notices), oldest first."""
        events, self._events = self._events, []
        return events

    def update(self, now: float) -> None:
        """Expire the slot or a silent client, hand over to the next in the queue."""
        timeout = self.config.answer_timeout
        for client in list(self.queue):
            if now - self._last_seen.get(client, now) > timeout:
                self.queue.remove(client)
                self._last_seen.pop(client, None)
                self._groups.pop(client, None)
        if self.holder is not None:
            if now - self._last_seen.get(self.holder, now) > timeout:
                self._end("silent", now)
            elif self.time_left(now) <= 0.0:
                self._end("expired", now)
        if self.holder is None and self.queue:
            self.holder = self.queue.pop(0)
            self.holder_since = now
            self._last_seen[self.holder] = now
            self._events.append(SlotEvent("started", self.holder, "next in queue"))

    def _end(self, reason: str, now: float) -> None:
        assert self.holder is not None
        self._events.append(SlotEvent("ended", self.holder, reason))
        self._last_seen.pop(self.holder, None)
        self._groups.pop(self.holder, None)
        self.holder = None
        self.holder_since = now

    def view(self, client: Client, now: float) -> SlotView:
        if client == self.holder:
            role, position = Role.HOLDER, 0
        elif client in self.queue:
            role, position = Role.QUEUED, self.queue.index(client) + 1
        else:
            role, position = Role.WATCHER, 0
        # A queued client waits for the holder's remaining time plus a full slot per client ahead.
        wait = self.time_left(now) + (position - 1) * self.config.slot_length if position else 0.0
        return SlotView(
            role=role,
            position=position,
            queue_length=len(self.queue),
            time_left=self.time_left(now) if role is Role.HOLDER else max(0.0, wait),
            onboard=self.onboard_active(now),
            staff_stop=self.staff_stopped,
        )
