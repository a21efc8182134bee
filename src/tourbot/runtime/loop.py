"""The runtime: one event loop wiring a source to the localizer, the estimators, the navigator and sinks.

Read :meth:`Runtime.step` first: poll the source, feed odometry, scans and camera images to the
localizer and the estimators (images to those that take them; scans alternating as in Table 1 of
Schulz and Burgard 2001 for those that ask), build the :class:`~tourbot.snapshot.StateSnapshot`, let
the navigator choose a velocity from that snapshot (never from ground truth), and hand the snapshot
to every sink.

A web server drives it from its own loop or thread: :meth:`snapshot` returns the last immutable
snapshot, and :meth:`send_goal`, :meth:`start_tour` and :meth:`stop` take effect at the next step (a
lock serialises them with :meth:`step`).
"""

from __future__ import annotations

import threading
import time as _time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from tourbot.errors import TourbotError
from tourbot.interfaces import (
    DrivableSource,
    Estimator,
    ImageEstimator,
    ImageLocalizer,
    Localizer,
    Navigator,
    PoseBelief,
    RecordSink,
    ScanShare,
    Sink,
    Source,
)
from tourbot.records import Image, Odometry, Scan
from tourbot.snapshot import NavigationStatus, StateSnapshot

__all__ = ["Runtime", "RuntimeConfig", "RuntimeControlError"]


class RuntimeControlError(TourbotError):
    """A request the runtime cannot serve (e.g. a goal when no navigator runs)."""


@dataclass(frozen=True)
class RuntimeConfig:
    """How the loop runs.

    ``speedup``: pace the loop to this many times real time in :meth:`Runtime.run` (``None``: as
    fast as possible). ``alternate_scans``: honour estimators' ``ScanShare.ALTERNATE`` (Schulz and
    Burgard, Table 1); when False every estimator gets every scan.
    """

    speedup: float | None = None
    alternate_scans: bool = True


class Runtime:
    """The robot's main loop over one source; see the module docstring."""

    def __init__(
        self,
        source: Source,
        localizer: Localizer | None = None,
        *,
        navigator: Navigator | None = None,
        estimators: Iterable[Estimator] = (),
        sinks: Iterable[Sink] = (),
        site: str = "",
        config: RuntimeConfig | None = None,
    ) -> None:
        self.source = source
        self.localizer = localizer
        self.navigator = navigator
        self.estimators: list[Estimator] = list(estimators)
        self.sinks: list[Sink] = []
        self._record_sinks: list[RecordSink] = []
        self.site = site
        self.config = config or RuntimeConfig()
        self._lock = threading.RLock()
        self._belief: PoseBelief | None = None
        self._last_scan: Scan | None = None
        self._scan_index = 0
        self._steps = 0
        self._finished = False
        self._wall_start: float | None = None
        self._time_start: float | None = None
        self._snapshot = StateSnapshot(time=source.time, step=0, source=source.name, site=site)
        # Protocol isinstance checks are slow: decide once
        self._drivable: DrivableSource | None = source if isinstance(source, DrivableSource) else None
        for sink in sinks:
            self.add_sink(sink)

    # -- plugging in -----------------------------------------------------------------------------

    def add_estimator(self, estimator: Estimator) -> None:
        with self._lock:
            self.estimators.append(estimator)

    def add_sink(self, sink: Sink) -> None:
        with self._lock:
            self.sinks.append(sink)
            if isinstance(sink, RecordSink):
                self._record_sinks.append(sink)

    # -- control (callable from another thread) --------------------------------------------------

    def send_goal(self, x: float, y: float, theta: float = 0.0) -> None:
        """Drive to the world pose ``(x, y, theta)``."""
        with self._lock:
            self._require_navigator().send_goal((float(x), float(y), float(theta)))

    def start_tour(self, tour: str) -> None:
        """Start the site's tour named ``tour`` (an unknown name raises a TourbotError)."""
        with self._lock:
            self._require_navigator().start_tour(tour)

    def stop(self) -> None:
        """Stop: cancel the goal or tour and halt the robot."""
        with self._lock:
            if self.navigator is not None:
                self.navigator.stop()
            if self._drivable is not None:
                self._drivable.command(0.0, 0.0)

    def snapshot(self) -> StateSnapshot:
        """The latest snapshot (immutable; safe to read from any thread)."""
        return self._snapshot

    @property
    def finished(self) -> bool:
        """True once the source is exhausted."""
        return self._finished

    # -- the loop --------------------------------------------------------------------------------

    def step(self) -> StateSnapshot | None:
        """One step of the source; the new snapshot, or ``None`` once the source is exhausted."""
        with self._lock:
            if self._finished:
                return None
            if self._wall_start is None:
                self._wall_start = _time.perf_counter()
                self._time_start = self.source.time
            records = self.source.poll()
            if records is None:
                self._finished = True
                self._close_sinks()
                return None
            for record_sink in self._record_sinks:
                record_sink.on_records(records)
            for record in records:
                if isinstance(record, Odometry):
                    self._on_odometry(record)
                elif isinstance(record, Image):
                    self._on_image(record)
                else:
                    self._on_scan(record)
            self._steps += 1
            snapshot = self._build_snapshot()
            if self.navigator is not None and self._drivable is not None:
                speed, turn = self.navigator.control(snapshot, self._last_scan, self._drivable.dt)
                self._drivable.command(speed, turn)
            self._snapshot = snapshot
            for sink in self.sinks:
                sink.on_snapshot(snapshot)
            return snapshot

    def run(
        self,
        *,
        max_time: float | None = None,
        until: Callable[[StateSnapshot], bool] | None = None,
    ) -> StateSnapshot:
        """Step until the source ends, ``max_time`` seconds of source time pass, or ``until`` holds.

        Paced to ``config.speedup`` times real time when set. Sinks are closed at the end.
        """
        start = self.source.time
        wall0 = _time.perf_counter()
        try:
            while True:
                snap = self.step()
                if snap is None:
                    break
                if until is not None and until(snap):
                    break
                if max_time is not None and snap.time - start >= max_time:
                    break
                if self.config.speedup:
                    ahead = (snap.time - start) / self.config.speedup - (_time.perf_counter() - wall0)
                    if ahead > 0:
                        _time.sleep(ahead)
        finally:
            self.close()
        return self._snapshot

    def close(self) -> None:
        """Close every sink (idempotent)."""
        with self._lock:
            self._close_sinks()

    # -- internals -------------------------------------------------------------------------------

    def _require_navigator(self) -> Navigator:
        if self.navigator is None:
            raise RuntimeControlError("this runtime has no navigator: it replays a log or only observes")
        return self.navigator

    def _on_odometry(self, odom: Odometry) -> None:
        if self.localizer is not None:
            self.localizer.on_odometry(odom)
        for est in self.estimators:
            est.on_odometry(odom)

    def _on_scan(self, scan: Scan) -> None:
        k = self._scan_index
        self._scan_index += 1
        self._last_scan = scan
        alternating = self.config.alternate_scans and any(
            e.scan_share == ScanShare.ALTERNATE for e in self.estimators
        )
        # Table 1 of Schulz and Burgard: even scans update the pose, odd scans the objects.
        if self.localizer is not None and (not alternating or k % 2 == 0 or self._belief is None):
            belief = self.localizer.on_scan(scan)
            if belief is not None:
                self._belief = belief
        if self._belief is None:
            return
        for est in self.estimators:
            if est.scan_share == ScanShare.ALTERNATE and alternating and k % 2 == 0:
                continue
            est.on_scan(scan, self._belief)

    def _on_image(self, image: Image) -> None:
        if isinstance(self.localizer, ImageLocalizer):
            belief = self.localizer.on_image(image)
            if belief is not None:
                self._belief = belief
        for est in self.estimators:
            if isinstance(est, ImageEstimator):
                est.on_image(image, self._belief)

    def _build_snapshot(self) -> StateSnapshot:
        people: tuple = ()
        doors: tuple = ()
        furniture: tuple = ()
        extras: dict = {}
        for est in self.estimators:
            out = est.state()
            if out.people is not None:
                people = people + out.people
            if out.doors is not None:
                doors = doors + out.doors
            if out.furniture is not None:
                furniture = furniture + out.furniture
            if out.extra:
                extras[est.name] = dict(out.extra)
        truth = self._drivable.truth() if self._drivable is not None else None
        nav = self.navigator.status() if self.navigator is not None else NavigationStatus()
        wall = _time.perf_counter() - (self._wall_start or _time.perf_counter())
        elapsed = self.source.time - (self._time_start if self._time_start is not None else self.source.time)
        belief = self._belief
        return StateSnapshot(
            time=self.source.time,
            step=self._steps,
            source=self.source.name,
            pose=None if belief is None else belief.estimate,
            samples=None if belief is None else belief.summary,
            people=people,
            doors=doors,
            furniture=furniture,
            navigation=nav,
            truth=truth,
            site=self.site,
            realtime_factor=elapsed / wall if wall > 0 else 0.0,
            estimators=extras,
        )

    def _close_sinks(self) -> None:
        sinks, self.sinks, self._record_sinks = self.sinks, [], []
        for sink in sinks:
            sink.close()
