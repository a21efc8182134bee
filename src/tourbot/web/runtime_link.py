"""The robot's runtime (:mod:`tourbot.runtime`) seen through the web's :class:`RobotLink`.

The simulator runtime and a real robot's runtime both give a plain
:class:`~tourbot.snapshot.StateSnapshot`; this adapter turns it into the web's
:class:`RobotView` and passes goals, tours and stops on. It shows the *estimated* pose (what the
robot acts on) and the people tracker's confirmed tracks (what it perceives); without a tracker no
people are shown. A simulator's true people travel apart, as debug truth, for the pages' labelled
debug overlay only.

"Move around this exhibit" runs like a tour authored on the web: a sequence of goals, the
viewpoints around the exhibit (:func:`tourbot.navigation.around.viewpoints_around`) on the
robot's own map, a short dwell at each. A high-resolution picture of the robot's camera comes from
the ``camera`` given (for a simulated robot, its simulated forward camera; see
:mod:`tourbot.web.serve`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from tourbot.errors import TourbotError
from tourbot.navigation.around import AroundConfig, viewpoints_around
from tourbot.navigation.navigator import SiteNavigator
from tourbot.runtime.loop import Runtime
from tourbot.snapshot import NavMode, StateSnapshot
from tourbot.web.link import NavStatus, ObjectView, PersonView, RobotView

__all__ = ["RuntimeLink"]

_STATE = {
    NavMode.IDLE: "idle",
    NavMode.NAVIGATING: "moving",
    NavMode.BLOCKED: "blocked",
    NavMode.DWELLING: "arrived",
    NavMode.FINISHED: "arrived",
    NavMode.FAILED: "failed",
}


@dataclass
class RuntimeLink:
    """A :class:`~tourbot.runtime.loop.Runtime` as a web :class:`~tourbot.web.link.RobotLink`.

    ``period`` is the source's time step; the server calls :meth:`step` at that pace (real time).
    Tours the robot's site file knows run on the robot's own tour executor. A tour authored only
    in the web database is run here as a sequence of goals, ``dwell`` seconds at each exhibit.
    """

    runtime: Runtime
    period: float = 0.1
    site_tours: frozenset[str] = frozenset()
    dwell: float = 10.0
    around_config: AroundConfig = field(default_factory=AroundConfig)
    camera: Callable[[], bytes] | None = None  # a high-resolution JPEG of the robot's camera, now
    _exhibit: str | None = None
    _stop_dwell: float = 10.0
    _web_tour: str | None = None
    _stops: list[tuple[str, float, float, float]] = field(default_factory=list)
    _done: int = 0
    _dwell_until: float | None = None
    _finished_seen: bool = False

    def step(self) -> None:
        snapshot = self.runtime.step()
        if snapshot is not None and self._web_tour is not None:
            self._advance_web_tour(snapshot)

    def view(self) -> RobotView:
        return view_of(self.runtime.snapshot(), self._exhibit, self._web_status())

    def send_goal(self, x: float, y: float, theta: float | None = None, exhibit: str | None = None) -> None:
        self._web_tour, self._stops = None, []
        self._exhibit = exhibit
        self.runtime.send_goal(x, y, 0.0 if theta is None else theta)

    def start_tour(self, name: str, exhibits: list[tuple[str, float, float, float]]) -> None:
        if name in self.site_tours:
            self._web_tour, self._stops, self._exhibit = None, [], None
            self.runtime.start_tour(name)
            return
        if not exhibits:
            raise TourbotError(f"tour {name!r} has no exhibits")
        self._web_tour, self._stops, self._done = name, list(exhibits), 0
        self._stop_dwell = self.dwell
        self._go_to_stop()

    def around(self, exhibit: str, x: float, y: float, theta: float) -> None:
        """Move around the exhibit viewed from ``(x, y, theta)``: its viewpoints, on the robot's map."""
        navigator = self.runtime.navigator
        if not isinstance(navigator, SiteNavigator):
            raise TourbotError("this robot cannot plan a way around an exhibit")
        views = viewpoints_around((x, y, theta), navigator.costmap, self.around_config)
        if not views:
            raise TourbotError("no place around this exhibit is free on the robot's map")
        self._web_tour, self._done = f"around {exhibit}", 0
        self._stops = [(exhibit, vx, vy, vtheta) for vx, vy, vtheta in views]
        self._stop_dwell = self.around_config.dwell
        self._go_to_stop()

    def photo(self) -> bytes:
        if self.camera is None:
            raise TourbotError("this robot has no camera")
        return self.camera()

    def stop(self) -> None:
        self._web_tour, self._stops, self._exhibit = None, [], None
        self.runtime.stop()

    # --- tours authored on the web --------------------------------------------------------------
    def _go_to_stop(self) -> None:
        slug, x, y, theta = self._stops[self._done]
        self._exhibit, self._dwell_until, self._finished_seen = slug, None, False
        self.runtime.send_goal(x, y, theta)

    def _advance_web_tour(self, snapshot: StateSnapshot) -> None:
        mode = snapshot.navigation.mode
        if mode == NavMode.FAILED:
            self._web_tour, self._stops = None, []
            return
        if mode != NavMode.FINISHED or self._finished_seen:
            return
        now = time.monotonic()
        if self._dwell_until is None:
            self._dwell_until = now + self._stop_dwell
        if now >= self._dwell_until:
            self._finished_seen = True
            self._done += 1
            if self._done < len(self._stops):
                self._go_to_stop()
            else:
                self._web_tour = None

    def _web_status(self) -> tuple[str, int, int] | None:
        if self._web_tour is None:
            return None
        return (self._web_tour, self._done, len(self._stops))


def view_of(
    snapshot: StateSnapshot, exhibit: str | None = None, web_tour: tuple[str, int, int] | None = None
) -> RobotView:
    """The web's view of a runtime snapshot: the estimated pose and the confirmed tracks; the
    simulator's true people (if any) only as debug truth."""
    nav = snapshot.navigation
    pose = snapshot.pose
    message = nav.message
    truth = () if snapshot.truth is None else snapshot.truth.people
    if pose is None:
        x = y = theta = 0.0
        cov = (0.0, 0.0, 0.0)
        message = (message + "; " if message else "") + "localizing"
    else:
        x, y, theta = pose.x, pose.y, pose.theta
        cov = (pose.covariance[0][0], pose.covariance[1][1], pose.covariance[2][2])
    tour, progress = nav.tour, (len(nav.visited), nav.exhibits_total)
    if web_tour is not None:
        tour, progress = web_tour[0], (web_tour[1], web_tour[2])
    status = NavStatus(
        state=_STATE.get(nav.mode, str(nav.mode)),
        exhibit=nav.current_exhibit or exhibit,
        goal=None if nav.goal is None else (nav.goal[0], nav.goal[1]),
        path=tuple(nav.path),
        blocked_time=nav.blocked_time,
        tour=tour,
        tour_progress=progress,
        message=message,
    )
    return RobotView(
        t=snapshot.time,
        x=x,
        y=y,
        theta=theta,
        v=nav.speed,
        omega=nav.turn_rate,
        covariance=cov,
        people=tuple(PersonView(p.id, p.x, p.y, p.vx, p.vy) for p in snapshot.people if p.confirmed),
        nav=status,
        truth=tuple(PersonView(p.id, p.x, p.y, p.vx, p.vy) for p in truth),
        obstacles=tuple(
            (float(x), float(y)) for x, y in snapshot.estimators.get("vision", {}).get("obstacles", ())
        ),
        objects=objects_of(snapshot),
    )


def objects_of(snapshot: StateSnapshot) -> tuple[ObjectView, ...]:
    """The doors and furniture of the object estimator's snapshot entry in the states the world
    model holds (those never well observed have none and are left out)."""
    entry = (snapshot.estimators or {}).get("objects")
    items = entry.get("objects", ()) if isinstance(entry, dict) else ()
    return tuple(
        ObjectView(
            str(o["name"]),
            str(o.get("kind", "furniture")),
            tuple((float(x), float(y)) for x, y in o["outline"]),
        )
        for o in items
        if o.get("outline")
    )
