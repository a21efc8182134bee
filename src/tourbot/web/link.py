"""What the web server needs from a robot: the :class:`RobotLink` protocol.

The server never reaches into the robot's estimators: it reads a plain :class:`RobotView` (pose
estimate, people tracks, navigation status) and sends goals, tours, "move around this exhibit" and
stops, and asks for a high-resolution picture of the robot's camera. The simulator
runtime and the real robot plug in through :mod:`tourbot.web.runtime_link`;
:mod:`tourbot.web.process_link` runs such a link in a process of its own.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

__all__ = ["NavStatus", "ObjectView", "PersonView", "RobotLink", "RobotView"]


@dataclass(frozen=True)
class PersonView:
    """A tracked person: track id, position (m) and velocity (m/s) in the map frame."""

    id: int
    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0


@dataclass(frozen=True)
class ObjectView:
    """A door or piece of furniture in its *estimated* state: its outline (world, m) in the state
    the robot's world model holds (the latest well-observed estimate, what MCL and the navigator
    use: :class:`tourbot.objects.world.ObjectWorld`)."""

    name: str
    kind: str
    outline: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class NavStatus:
    """Navigation as the pages show it.

    ``state`` is one of ``idle``, ``moving``, ``blocked``, ``arrived``, ``stopped``; ``exhibit``
    the exhibit being approached or shown; ``blocked_time`` how long the way has been blocked (s),
    which drives the on-board face; ``tour`` and ``tour_progress`` (stops done, stops in all).
    """

    state: str = "idle"
    exhibit: str | None = None
    goal: tuple[float, float] | None = None
    path: tuple[tuple[float, float], ...] = ()
    blocked_time: float = 0.0
    tour: str | None = None
    tour_progress: tuple[int, int] = (0, 0)
    message: str = ""


@dataclass(frozen=True)
class RobotView:
    """One instant of a robot as the web sees it: its estimated pose and velocity, the people it
    tracks (``people``), and for a simulated robot the true people (``truth``, debug only)."""

    t: float
    x: float
    y: float
    theta: float
    v: float = 0.0
    omega: float = 0.0
    covariance: tuple[float, float, float] = (0.0, 0.0, 0.0)
    people: tuple[PersonView, ...] = ()
    nav: NavStatus = field(default_factory=NavStatus)
    truth: tuple[PersonView, ...] = ()  # a simulator's true people: debug overlay only, never acted on
    # obstacles the forward camera found where the laser sees none (tourbot.vision), world points (m)
    obstacles: tuple[tuple[float, float], ...] = ()
    objects: tuple[ObjectView, ...] = ()  # doors and furniture as estimated (tourbot.objects)


@runtime_checkable
class RobotLink(Protocol):
    """A robot (simulated or real) the server can watch and command.

    ``step`` advances the robot's own loop by one cycle; the server calls it from a worker thread
    at ``period`` seconds when the link is not driven elsewhere. Commands are never called during
    a ``step``. ``view`` may be called at any time from another thread and must not block on a step
    (return the latest finished state).
    """

    period: float

    def step(self) -> None: ...

    def view(self) -> RobotView: ...

    def send_goal(
        self, x: float, y: float, theta: float | None = None, exhibit: str | None = None
    ) -> None: ...

    def start_tour(self, name: str, exhibits: list[tuple[str, float, float, float]]) -> None: ...

    def around(self, exhibit: str, x: float, y: float, theta: float) -> None:
        """Move around the exhibit seen from the viewing pose ``(x, y, theta)``: view it from
        several directions (Burgard et al., section 6.1)."""
        ...

    def photo(self) -> bytes:
        """A high-resolution JPEG from the robot's camera, taken now (a TourbotError when the
        robot has no camera)."""
        ...

    def stop(self) -> None: ...
