"""Sinks: what consumes the snapshots (recorder, metrics). The terminal view is in ``cli/demo.py``;
the web stream is the web server's own sink."""

from __future__ import annotations

import gzip
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tourbot.io.output import output_file
from tourbot.snapshot import NavMode, StateSnapshot

__all__ = ["MetricsSink", "Recorder", "TourMetrics"]


class Recorder:
    """Keeps every ``every``-th snapshot and writes them as gzipped JSON lines on :meth:`close`."""

    def __init__(self, path: str | Path | None = None, every: int = 1) -> None:
        self.path = None if path is None else Path(path)
        self.every = max(1, every)
        self.snapshots: list[StateSnapshot] = []
        self._n = 0

    def on_snapshot(self, snapshot: StateSnapshot) -> None:
        if self._n % self.every == 0:
            self.snapshots.append(snapshot)
        self._n += 1

    def close(self) -> None:
        if self.path is None:
            return
        with output_file(self.path) as tmp, gzip.open(tmp, "wt", compresslevel=5) as f:
            for s in self.snapshots:
                f.write(s.to_json() + "\n")

    @staticmethod
    def read(path: str | Path) -> list[StateSnapshot]:
        with gzip.open(path, "rt") as f:
            return [StateSnapshot.from_dict(json.loads(line)) for line in f if line.strip()]


@dataclass
class TourMetrics:
    """What a run achieved: localization error, time blocked, collisions, tour outcome."""

    duration: float = 0.0
    distance: float = 0.0
    errors: list[float] = field(default_factory=list)
    collisions: int = 0
    total_blocked_time: float = 0.0
    visited: tuple[str, ...] = ()
    exhibits_total: int = 0
    finished: bool = False
    message: str = ""

    @property
    def success(self) -> bool:
        """The whole tour visited, without a collision with a person or an invisible obstacle."""
        return self.finished and len(self.visited) == self.exhibits_total and self.collisions == 0

    def error_quantile(self, q: float) -> float:
        return float(np.quantile(self.errors, q)) if self.errors else math.nan

    def fraction_within(self, limit: float) -> float:
        return float(np.mean(np.asarray(self.errors) <= limit)) if self.errors else math.nan

    def as_dict(self) -> dict[str, Any]:
        return {
            "duration_s": self.duration,
            "distance_m": self.distance,
            "mean_error_m": float(np.mean(self.errors)) if self.errors else math.nan,
            "p99_error_m": self.error_quantile(0.99),
            "within_15cm": self.fraction_within(0.15),
            "collisions": self.collisions,
            "blocked_s": self.total_blocked_time,
            "visited": len(self.visited),
            "exhibits": self.exhibits_total,
            "finished": self.finished,
            "success": self.success,
            "message": self.message,
        }


class MetricsSink:
    """Accumulates :class:`TourMetrics` from snapshots that carry ground truth."""

    def __init__(self) -> None:
        self.metrics = TourMetrics()
        self._start: float | None = None
        self._last_xy: tuple[float, float] | None = None

    def on_snapshot(self, snapshot: StateSnapshot) -> None:
        m = self.metrics
        if self._start is None:
            self._start = snapshot.time
        m.duration = snapshot.time - self._start
        err = snapshot.position_error
        if err is not None and snapshot.samples is not None:
            m.errors.append(err)
        if snapshot.truth is not None:
            xy = (snapshot.truth.pose[0], snapshot.truth.pose[1])
            if self._last_xy is not None:
                m.distance += math.hypot(xy[0] - self._last_xy[0], xy[1] - self._last_xy[1])
            self._last_xy = xy
            m.collisions = snapshot.truth.collisions
        nav = snapshot.navigation
        m.total_blocked_time = nav.total_blocked_time
        m.visited = nav.visited
        m.exhibits_total = max(m.exhibits_total, nav.exhibits_total)
        m.finished = nav.mode == NavMode.FINISHED
        m.message = nav.message

    def close(self) -> None:
        pass
