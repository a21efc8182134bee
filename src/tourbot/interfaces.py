"""The plug-in points of the runtime: sources, the localizer, estimators, sinks and the navigator.

Each is a Protocol, so a new estimator (the people tracker, the door and furniture estimator, the
mapper, the ceiling camera) or a new sink (recorder, metrics, web stream) is a new class that
satisfies one of them, handed to :class:`tourbot.runtime.loop.Runtime`; nothing else changes.

Data flow per loop step (``../shared/SYSTEM.md``)::

    source.poll() -> records -> localizer (odometry, scans, images)          -> PoseBelief
                              -> estimators (odometry, scans, images + belief) -> EstimatorOutput
                   snapshot <- all of the above + navigator.status() (+ source truth)
                   sinks     <- snapshot
                   navigator <- snapshot + latest scan -> (v, w) -> source.command()
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from tourbot.records import Image, Odometry, Record, Scan
from tourbot.snapshot import (
    DoorState,
    FurnitureState,
    GroundTruth,
    NavigationStatus,
    PersonState,
    PoseEstimate,
    SampleSummary,
    StateSnapshot,
)

__all__ = [
    "DrivableSource",
    "Estimator",
    "EstimatorOutput",
    "ImageEstimator",
    "ImageLocalizer",
    "Localizer",
    "Navigator",
    "PoseBelief",
    "RecordSink",
    "ScanShare",
    "Sink",
    "Source",
]


@runtime_checkable
class Source(Protocol):
    """Anything that produces records: a log replay, a bag, the simulator, a live robot."""

    name: str

    @property
    def time(self) -> float:
        """The source's clock (s): the time of the last records polled."""
        ...

    def poll(self) -> Sequence[Record] | None:
        """The records of the next step, in time order; ``None`` once the source is exhausted."""
        ...


@runtime_checkable
class DrivableSource(Source, Protocol):
    """A source that also takes velocity commands: the simulator, or a real robot.

    ``dt`` is its step length (s) and ``truth()`` the ground truth where it has one (a simulator;
    ``None`` on a real robot). The runtime passes truth to the snapshot for metrics only.
    """

    dt: float

    def command(self, speed: float, turn_rate: float) -> None:
        """Set the commanded translational (m/s) and rotational (rad/s) velocities."""
        ...

    def truth(self) -> GroundTruth | None: ...


@dataclass(frozen=True)
class PoseBelief:
    """The localizer's belief after a scan: a summary estimate plus the weighted samples.

    Estimators that integrate over the robot's pose (Schulz and Burgard, Eq. 10) use
    ``samples`` ``(N, 3)`` and ``weights`` ``(N,)`` (summing to one); a Gaussian-only localizer
    gives one sample with weight 1.
    """

    estimate: PoseEstimate
    samples: NDArray[np.float64]
    weights: NDArray[np.float64]
    summary: SampleSummary | None = None


@runtime_checkable
class Localizer(Protocol):
    """Turns odometry and scans into a pose belief (MCL with the novelty filter, grid Markov...)."""

    def on_odometry(self, odom: Odometry) -> None: ...

    def on_scan(self, scan: Scan) -> PoseBelief | None:
        """Integrate ``scan`` (its ``odom`` field carries the odometry pose at its time)."""
        ...


@runtime_checkable
class ImageLocalizer(Localizer, Protocol):
    """A localizer that also weighs its belief by camera images (the ceiling camera inside MCL)."""

    def on_image(self, image: Image) -> PoseBelief | None:
        """Integrate ``image`` (its ``odom`` field carries the odometry pose at its time)."""
        ...


class ScanShare(StrEnum):
    """Which scans an estimator receives.

    ``ALL``: every scan. ``ALTERNATE``: the odd scans only, the even ones going to the localizer
    alone, as in Table 1 of Schulz and Burgard (2001), because the robot's pose and the objects'
    states are assumed independent and so must not be updated with the same reading.
    """

    ALL = "all"
    ALTERNATE = "alternate"


@dataclass(frozen=True)
class EstimatorOutput:
    """What an estimator contributes to the snapshot; fields left ``None`` contribute nothing."""

    people: tuple[PersonState, ...] | None = None
    doors: tuple[DoorState, ...] | None = None
    furniture: tuple[FurnitureState, ...] | None = None
    extra: dict[str, Any] = field(default_factory=dict)


@runtime_checkable
class Estimator(Protocol):
    """A belief about the world beside the robot's pose: people, doors and furniture, a map."""

    name: str
    scan_share: ScanShare

    def on_odometry(self, odom: Odometry) -> None: ...

    def on_scan(self, scan: Scan, belief: PoseBelief) -> None: ...

    def state(self) -> EstimatorOutput: ...


@runtime_checkable
class ImageEstimator(Estimator, Protocol):
    """An estimator that also takes camera images: the ceiling camera's tracker, the forward
    camera's obstacle detector. Images reach it with the localizer's latest belief."""

    def on_image(self, image: Image, belief: PoseBelief | None) -> None: ...


@runtime_checkable
class Sink(Protocol):
    """Consumes snapshots: a recorder, metrics, a live view, the web stream."""

    def on_snapshot(self, snapshot: StateSnapshot) -> None: ...

    def close(self) -> None: ...


@runtime_checkable
class RecordSink(Sink, Protocol):
    """A sink that also takes the records of each step, before the estimators (a recorder of the
    sensor stream: an MCAP file, a live Foxglove view)."""

    def on_records(self, records: Sequence[Record]) -> None: ...


@runtime_checkable
class Navigator(Protocol):
    """Goals and tours in, velocity commands out; acts on the snapshot (the estimate), never truth."""

    def send_goal(self, goal: tuple[float, float, float]) -> None: ...

    def start_tour(self, tour: str) -> None: ...

    def stop(self) -> None: ...

    def control(self, snapshot: StateSnapshot, scan: Scan | None, dt: float) -> tuple[float, float]:
        """The velocity command ``(speed, turn_rate)`` for the next ``dt`` seconds."""
        ...

    def status(self) -> NavigationStatus: ...
