"""The state snapshot: everything the robot believes at one instant, as plain data.

This is what sinks read (the recorder, metrics, the terminal view, the web server's stream) and
what the navigator acts on. It holds only numbers, strings, tuples and nested frozen dataclasses,
so ``to_dict`` gives JSON-ready data and ``StateSnapshot.from_dict`` reads it back.

Stability: fields are only ever added (with defaults), never renamed or removed, so a web page
written against one version keeps working.

Ground truth (``truth``) is filled only by a simulator source and is for metrics and display: the
navigator and the estimators never read it (``../shared/SYSTEM.md``: the robot acts on its
estimate).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from enum import Enum, StrEnum
from typing import Any

__all__ = [
    "DoorState",
    "FurnitureState",
    "GroundTruth",
    "NavMode",
    "NavigationStatus",
    "PersonState",
    "PoseEstimate",
    "SampleSummary",
    "StateSnapshot",
]

Pose3 = tuple[float, float, float]
Point2 = tuple[float, float]
Matrix3 = tuple[Pose3, Pose3, Pose3]

_ZERO_COV: Matrix3 = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


class NavMode(StrEnum):
    """What the navigator is doing."""

    IDLE = "idle"  # no goal
    NAVIGATING = "navigating"  # driving to a goal
    BLOCKED = "blocked"  # a goal, but people block the way: waiting or replanning
    DWELLING = "dwelling"  # stopped at an exhibit's viewing pose, explaining it
    FINISHED = "finished"  # the tour or goal is done
    FAILED = "failed"  # no path, or gave up after being blocked too long


@dataclass(frozen=True, slots=True)
class PoseEstimate:
    """The robot's estimated pose ``(x, y, theta)`` (m, rad) with its 3x3 covariance."""

    x: float
    y: float
    theta: float
    covariance: Matrix3 = _ZERO_COV

    @property
    def pose(self) -> Pose3:
        return (self.x, self.y, self.theta)

    @property
    def position_std(self) -> float:
        """sqrt(var x + var y): a one-number position uncertainty in metres."""
        return float(max(self.covariance[0][0] + self.covariance[1][1], 0.0) ** 0.5)


@dataclass(frozen=True, slots=True)
class SampleSummary:
    """A small, drawable summary of the localizer's samples.

    ``poses`` is a subsample (at most a few hundred, drawn by weight) for display; ``count`` is the
    size of the whole set and ``n_effective`` its effective sample size (1 / sum w^2).
    """

    count: int
    n_effective: float
    poses: tuple[Pose3, ...] = ()


@dataclass(frozen=True, slots=True)
class PersonState:
    """A person near the robot: a tracker's track (``id`` stable over time) or a true person."""

    id: int
    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0
    confirmed: bool = True


@dataclass(frozen=True, slots=True)
class DoorState:
    """A door: ``angle`` of its leaf from closed (rad) and the fraction of its opening angle."""

    name: str
    angle: float
    open_fraction: float


@dataclass(frozen=True, slots=True)
class FurnitureState:
    """A movable piece of furniture and its pose."""

    name: str
    x: float
    y: float
    theta: float


@dataclass(frozen=True, slots=True)
class NavigationStatus:
    """Where the navigator is going, how far the tour is, and how long it has been blocked.

    ``blocked_time`` is the current stretch of being blocked (s, 0 when moving freely; the on-board
    face shows it); ``total_blocked_time`` adds all stretches. ``path`` is the planned path as
    world points, thinned for display.
    """

    mode: NavMode = NavMode.IDLE
    goal: Pose3 | None = None
    tour: str | None = None
    current_exhibit: str | None = None
    exhibit_index: int = 0
    exhibits_total: int = 0
    visited: tuple[str, ...] = ()
    path: tuple[Point2, ...] = ()
    blocked_time: float = 0.0
    total_blocked_time: float = 0.0
    speed: float = 0.0
    turn_rate: float = 0.0
    message: str = ""

    @property
    def progress(self) -> float:
        """Fraction of the tour's exhibits visited, in [0, 1]."""
        return len(self.visited) / self.exhibits_total if self.exhibits_total else 0.0


@dataclass(frozen=True, slots=True)
class GroundTruth:
    """The simulator's truth at the snapshot's time: for metrics and display only."""

    pose: Pose3
    people: tuple[PersonState, ...] = ()
    doors: tuple[DoorState, ...] = ()
    furniture: tuple[FurnitureState, ...] = ()
    collisions: int = 0


@dataclass(frozen=True, slots=True)
class StateSnapshot:
    """The robot's whole belief at ``time`` (s, the source's clock), after ``step`` loop steps.

    ``pose`` is None until the localizer has produced an estimate. ``people``, ``doors`` and
    ``furniture`` are what the estimators believe (empty when no such estimator runs).
    ``estimators`` carries any extra plain data an estimator publishes, keyed by its name.
    """

    time: float
    step: int
    source: str
    pose: PoseEstimate | None = None
    samples: SampleSummary | None = None
    people: tuple[PersonState, ...] = ()
    doors: tuple[DoorState, ...] = ()
    furniture: tuple[FurnitureState, ...] = ()
    navigation: NavigationStatus = field(default_factory=NavigationStatus)
    truth: GroundTruth | None = None
    site: str = ""
    realtime_factor: float = 0.0
    estimators: dict[str, dict[str, Any]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready nested dicts and lists (enums as their string values)."""
        return _plain(asdict(self))

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), separators=(",", ":"))

    @property
    def position_error(self) -> float | None:
        """Distance (m) between the estimate and the truth, when both are known."""
        if self.pose is None or self.truth is None:
            return None
        dx = self.pose.x - self.truth.pose[0]
        dy = self.pose.y - self.truth.pose[1]
        return float((dx * dx + dy * dy) ** 0.5)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> StateSnapshot:
        """The inverse of :meth:`to_dict`."""
        pose = data.get("pose")
        samples = data.get("samples")
        truth = data.get("truth")
        nav = dict(data.get("navigation") or {})
        if nav:
            nav["mode"] = NavMode(nav.get("mode", "idle"))
            nav["goal"] = _tuple(nav["goal"]) if nav.get("goal") is not None else None
            nav["visited"] = tuple(nav.get("visited", ()))
            nav["path"] = tuple(_tuple(p) for p in nav.get("path", ()))
        return cls(
            time=float(data["time"]),
            step=int(data["step"]),
            source=str(data["source"]),
            pose=None if pose is None else _pose_estimate(pose),
            samples=None
            if samples is None
            else SampleSummary(
                count=int(samples["count"]),
                n_effective=float(samples["n_effective"]),
                poses=tuple(_tuple(p) for p in samples.get("poses", ())),
            ),
            people=tuple(PersonState(**p) for p in data.get("people", ())),
            doors=tuple(DoorState(**d) for d in data.get("doors", ())),
            furniture=tuple(FurnitureState(**f) for f in data.get("furniture", ())),
            navigation=NavigationStatus(**nav),
            truth=None
            if truth is None
            else GroundTruth(
                pose=_tuple(truth["pose"]),
                people=tuple(PersonState(**p) for p in truth.get("people", ())),
                doors=tuple(DoorState(**d) for d in truth.get("doors", ())),
                furniture=tuple(FurnitureState(**f) for f in truth.get("furniture", ())),
                collisions=int(truth.get("collisions", 0)),
            ),
            site=str(data.get("site", "")),
            realtime_factor=float(data.get("realtime_factor", 0.0)),
            estimators=dict(data.get("estimators", {})),
        )


def _pose_estimate(d: dict[str, Any]) -> PoseEstimate:
    cov = d.get("covariance", _ZERO_COV)
    return PoseEstimate(
        x=float(d["x"]),
        y=float(d["y"]),
        theta=float(d["theta"]),
        covariance=(_tuple(cov[0]), _tuple(cov[1]), _tuple(cov[2])),
    )


def _tuple(seq: Any) -> Any:
    return tuple(float(v) for v in seq)


def _plain(value: Any) -> Any:
    if isinstance(value, Enum):
        return value.value
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if hasattr(value, "item") and callable(value.item):  # numpy scalars
        return value.item()
    return value
