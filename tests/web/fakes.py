"""A stand-in robot for the web tests only: drives straight to its goal among walking people."""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, replace

from tourbot.web.link import NavStatus, ObjectView, PersonView, RobotView


class FakeRobot:
    """Kinematic robot (``speed`` m/s) on wall-clock time; 7 people walking circles around it."""

    def __init__(self, speed: float = 1.5, people: int = 7) -> None:
        self.period = 0.05
        self.speed = speed
        self.n_people = people
        self.x, self.y, self.theta = 2.0, 2.0, 0.0
        self.v = 0.0
        self.goal: tuple[float, float] | None = None
        self.exhibit: str | None = None
        self.state = "idle"
        self.tour: list[tuple[str, float, float, float]] = []
        self.tour_name: str | None = None
        self.done = 0
        self.commands: list[tuple[str, object]] = []
        self.obstacles: tuple[tuple[float, float], ...] = ()  # what a forward camera would have found
        self.objects: tuple[ObjectView, ...] = ()  # doors and furniture "estimated" (set by a test)
        self._last = time.monotonic()
        self._lock = threading.Lock()

    def step(self) -> None:
        now = time.monotonic()
        dt, self._last = now - self._last, now
        with self._lock:
            if self.goal is None:
                self.v = 0.0
                return
            dx, dy = self.goal[0] - self.x, self.goal[1] - self.y
            dist = math.hypot(dx, dy)
            if dist < 0.05:
                self.v = 0.0
                self.state = "arrived"
                self.goal = None
                if self.tour:
                    self.done += 1
                    self._next_stop()
                return
            self.theta = math.atan2(dy, dx)
            move = min(dist, self.speed * dt)
            self.x += move * math.cos(self.theta)
            self.y += move * math.sin(self.theta)
            self.v = self.speed
            self.state = "moving"

    def _next_stop(self) -> None:
        if self.done < len(self.tour):
            slug, x, y, _ = self.tour[self.done]
            self.goal, self.exhibit = (x, y), slug

    def view(self) -> RobotView:
        t = time.time()
        people = tuple(
            PersonView(i, 5 + 2 * math.cos(0.3 * t + i), 5 + 2 * math.sin(0.3 * t + i),
                       -0.6 * math.sin(0.3 * t + i), 0.6 * math.cos(0.3 * t + i))
            for i in range(self.n_people)
        )  # fmt: skip
        with self._lock:
            path = () if self.goal is None else ((self.x, self.y), self.goal)
            nav = NavStatus(
                state=self.state, exhibit=self.exhibit, goal=self.goal, path=path, tour=self.tour_name,
                tour_progress=(self.done, len(self.tour)),
            )  # fmt: skip
            return RobotView(
                t,
                self.x,
                self.y,
                self.theta,
                self.v,
                0.0,
                people=people,
                nav=nav,
                obstacles=self.obstacles,
                objects=self.objects,
            )

    def send_goal(self, x: float, y: float, theta: float | None = None, exhibit: str | None = None) -> None:
        with self._lock:
            self.commands.append(("goal", (x, y, theta, exhibit)))
            self.goal, self.exhibit, self.tour, self.tour_name = (x, y), exhibit, [], None

    def start_tour(self, name: str, exhibits: list[tuple[str, float, float, float]]) -> None:
        with self._lock:
            self.commands.append(("tour", name))
            self.tour, self.tour_name, self.done = list(exhibits), name, 0
            self._next_stop()

    def around(self, exhibit: str, x: float, y: float, theta: float) -> None:
        """Four viewpoints 1 m around the point 1 m ahead of the viewing pose, run as a tour."""
        cx, cy = x + math.cos(theta), y + math.sin(theta)
        stops = [
            (exhibit, cx - math.cos(theta + k * math.pi / 2), cy - math.sin(theta + k * math.pi / 2), 0.0)
            for k in range(4)
        ]
        with self._lock:
            self.commands.append(("around", exhibit))
            self.tour, self.tour_name, self.done = stops, f"around {exhibit}", 0
            self._next_stop()

    def photo(self) -> bytes:
        """A small grey JPEG, marked with the robot's position (a real robot renders its camera)."""
        import cv2
        import numpy as np

        image = np.full((48, 64), 128, dtype=np.uint8)
        with self._lock:
            self.commands.append(("photo", None))
            image[:, : max(1, min(63, int(self.x * 5)))] = 200
        ok, jpeg = cv2.imencode(".jpg", image)
        assert ok
        return bytes(jpeg.tobytes())

    def stop(self) -> None:
        with self._lock:
            self.commands.append(("stop", None))
            self.goal, self.tour, self.state = None, [], "stopped"


@dataclass(frozen=True)
class FakeFactory:
    """A picklable :class:`FakeRobot` maker for a robot process; ``at`` restarts it at a pose.
    ``restart_time`` is how long a restarted robot takes to build (a real one loads its map and
    kernels for seconds; a forked fake is ready at once, before a page could see it restarting)."""

    start: tuple[float, float, float] | None = None
    restart_time: float = 0.0

    def at(self, pose: tuple[float, float, float]) -> FakeFactory:
        return replace(self, start=pose)

    def __call__(self) -> FakeRobot:
        robot = FakeRobot()
        if self.start is not None:
            time.sleep(self.restart_time)
            robot.x, robot.y, robot.theta = self.start
        return robot
