"""The runtime loop, with small stand-in components defined here (tests only)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest

from tourbot.interfaces import (
    DrivableSource,
    Estimator,
    EstimatorOutput,
    ImageEstimator,
    ImageLocalizer,
    Localizer,
    PoseBelief,
    ScanShare,
    Sink,
)
from tourbot.records import Image, LaserGeometry, Odometry, Record, RobotLog, Scan
from tourbot.runtime import Runtime, RuntimeConfig, RuntimeControlError
from tourbot.runtime.sources import LogSource
from tourbot.snapshot import GroundTruth, NavigationStatus, NavMode, PersonState, PoseEstimate, StateSnapshot

GEOM = LaserGeometry(num_beams=3, angle_min=-1.0, angle_increment=1.0, max_range=10.0)


def _log(n: int) -> RobotLog:
    scans = [
        Scan(timestamp=float(i), ranges=np.ones(3), geometry=GEOM, odom=(float(i), 0.0, 0.0))
        for i in range(n)
    ]
    odom = [Odometry(timestamp=i - 0.5, pose=(i - 0.5, 0.0, 0.0)) for i in range(n)]
    return RobotLog(source="test", scans=scans, odometry=odom)


class OdomLocalizer:
    """Believes odometry: enough to see what the loop feeds it."""

    def __init__(self) -> None:
        self.scans: list[float] = []
        self.odometry = 0

    def on_odometry(self, odom: Odometry) -> None:  # noqa: ARG002
        self.odometry += 1

    def on_scan(self, scan: Scan) -> PoseBelief | None:
        self.scans.append(scan.timestamp)
        assert scan.odom is not None
        x, y, th = scan.odom
        return PoseBelief(PoseEstimate(x, y, th), np.array([[x, y, th]]), np.ones(1))


class CountingEstimator:
    def __init__(self, name: str, share: ScanShare) -> None:
        self.name = name
        self.scan_share = share
        self.scans: list[float] = []

    def on_odometry(self, odom: Odometry) -> None:
        pass

    def on_scan(self, scan: Scan, belief: PoseBelief) -> None:  # noqa: ARG002
        self.scans.append(scan.timestamp)

    def state(self) -> EstimatorOutput:
        return EstimatorOutput(people=(PersonState(len(self.scans), 0.0, 0.0),), extra={"n": len(self.scans)})


class ListSink:
    def __init__(self) -> None:
        self.snapshots: list[StateSnapshot] = []
        self.closed = False

    def on_snapshot(self, snapshot: StateSnapshot) -> None:
        self.snapshots.append(snapshot)

    def close(self) -> None:
        self.closed = True


def test_stand_ins_satisfy_the_protocols() -> None:
    assert isinstance(OdomLocalizer(), Localizer)
    assert isinstance(CountingEstimator("a", ScanShare.ALL), Estimator)
    assert isinstance(ListSink(), Sink)
    assert isinstance(LogSource(_log(1)), DrivableSource) is False


def test_log_replay_feeds_every_record_and_every_sink() -> None:
    loc = OdomLocalizer()
    est = CountingEstimator("people", ScanShare.ALL)
    sink = ListSink()
    rt = Runtime(LogSource(_log(5)), loc, estimators=[est], sinks=[sink])
    final = rt.run()
    assert loc.scans == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert loc.odometry == 5
    assert est.scans == loc.scans
    assert len(sink.snapshots) == 5
    assert sink.closed
    assert rt.finished
    assert final.pose is not None
    assert final.pose.x == 4.0
    assert final.people[0].id == 5
    assert final.estimators["people"] == {"n": 5}


def test_alternating_estimators_get_odd_scans_and_localizer_even_ones() -> None:
    # Schulz and Burgard, Table 1.
    loc = OdomLocalizer()
    objects = CountingEstimator("objects", ScanShare.ALTERNATE)
    people = CountingEstimator("people", ScanShare.ALL)
    Runtime(LogSource(_log(6)), loc, estimators=[objects, people]).run()
    assert loc.scans == [0.0, 2.0, 4.0]
    assert objects.scans == [1.0, 3.0, 5.0]
    assert people.scans == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    loc2 = OdomLocalizer()
    Runtime(
        LogSource(_log(4)),
        loc2,
        estimators=[CountingEstimator("objects", ScanShare.ALTERNATE)],
        config=RuntimeConfig(alternate_scans=False),
    ).run()
    assert loc2.scans == [0.0, 1.0, 2.0, 3.0]


def test_run_stops_at_max_time_and_until() -> None:
    rt = Runtime(LogSource(_log(20)), OdomLocalizer())
    assert rt.run(max_time=3.0).time == 3.0
    rt2 = Runtime(LogSource(_log(20)), OdomLocalizer())
    assert rt2.run(until=lambda s: s.step >= 7).step == 7


def test_goal_without_navigator_is_a_clear_error() -> None:
    rt = Runtime(LogSource(_log(2)), OdomLocalizer())
    with pytest.raises(RuntimeControlError, match="no navigator"):
        rt.send_goal(1.0, 2.0)
    with pytest.raises(RuntimeControlError):
        rt.start_tour("main")
    rt.stop()  # harmless


class FakeRobot:
    """A drivable source that integrates the commanded speed along x."""

    name = "fake-robot"
    dt = 0.5

    def __init__(self) -> None:
        self._t = 0.0
        self.x = 0.0
        self.speed = 0.0

    @property
    def time(self) -> float:
        return self._t

    def poll(self) -> Sequence[Record] | None:
        self._t += self.dt
        self.x += self.speed * self.dt
        return [Scan(self._t, np.ones(3), GEOM, odom=(self.x, 0.0, 0.0))]

    def command(self, speed: float, turn_rate: float) -> None:  # noqa: ARG002
        self.speed = speed

    def truth(self) -> GroundTruth | None:
        return GroundTruth(pose=(self.x, 0.0, 0.0))


class GoX:
    """Drives along x to the goal, then stops."""

    def __init__(self) -> None:
        self.goal: tuple[float, float, float] | None = None

    def send_goal(self, goal: tuple[float, float, float]) -> None:
        self.goal = goal

    def start_tour(self, tour: str) -> None:
        raise RuntimeControlError(f"no tour {tour}")

    def stop(self) -> None:
        self.goal = None

    def control(self, snapshot: StateSnapshot, scan: Scan | None, dt: float) -> tuple[float, float]:  # noqa: ARG002
        if self.goal is None or snapshot.pose is None or snapshot.pose.x >= self.goal[0]:
            return 0.0, 0.0
        return 1.0, 0.0

    def status(self) -> NavigationStatus:
        return NavigationStatus(
            mode=NavMode.IDLE if self.goal is None else NavMode.NAVIGATING, goal=self.goal
        )


def test_navigator_drives_a_drivable_source_on_the_estimate() -> None:
    robot = FakeRobot()
    rt = Runtime(robot, OdomLocalizer(), navigator=GoX())
    assert isinstance(robot, DrivableSource)
    rt.send_goal(2.0, 0.0)
    for _ in range(10):
        rt.step()
    snap = rt.snapshot()
    assert snap.truth is not None
    assert snap.truth.pose[0] == pytest.approx(2.0)
    assert snap.navigation.goal == (2.0, 0.0, 0.0)
    with pytest.raises(RuntimeControlError, match="no tour"):
        rt.start_tour("nope")
    rt.stop()
    assert robot.speed == 0.0


def test_replay_of_a_real_log_through_mcl(fhw_log_path: Path) -> None:
    from tourbot.localization.mcl import MCLConfig, MonteCarloLocalization
    from tourbot.maps.reference import build_reference_map
    from tourbot.runtime.localizers import MCLLocalizer, UpdatePolicy

    source = LogSource.from_path(fhw_log_path)
    log = source._log
    grid = build_reference_map(log, resolution=0.1)
    mcl = MonteCarloLocalization(grid, MCLConfig().with_samples(300, fixed=True), seed=0)
    first = log.scans[0].reference
    assert first is not None
    mcl.reset_tracking(first)
    policy = UpdatePolicy(beam_step=2, min_travel=0.0, min_turn=0.0, max_interval=0.0)
    rt = Runtime(source, MCLLocalizer(mcl, policy))
    snap = rt.run(until=lambda s: s.step >= 20)
    ref = log.scans[19].reference
    assert snap.pose is not None
    assert ref is not None
    assert np.hypot(snap.pose.x - ref[0], snap.pose.y - ref[1]) < 0.3


class ImageLocalizerStandIn(OdomLocalizer):
    """Also weighs by images: counts them and moves its belief to x = 100 + the image's time."""

    def __init__(self) -> None:
        super().__init__()
        self.images: list[str] = []

    def on_image(self, image: Image) -> PoseBelief | None:
        self.images.append(image.camera)
        x = 100.0 + image.timestamp
        return PoseBelief(PoseEstimate(x, 0.0, 0.0), np.array([[x, 0.0, 0.0]]), np.ones(1))


class ImageCountingEstimator(CountingEstimator):
    def __init__(self) -> None:
        super().__init__("camera", ScanShare.ALL)
        self.images: list[tuple[str, float | None]] = []

    def on_image(self, image: Image, belief: PoseBelief | None) -> None:
        self.images.append((image.camera, None if belief is None else belief.estimate.x))


class RecordSource:
    """Replays a fixed list of record batches."""

    name = "records"

    def __init__(self, batches: list[list[Record]]) -> None:
        self._batches = batches
        self.time = 0.0

    def poll(self) -> Sequence[Record] | None:
        if not self._batches:
            return None
        batch = self._batches.pop(0)
        self.time = batch[-1].timestamp
        return batch


def test_images_reach_the_localizer_and_the_estimators_that_take_them() -> None:
    pixels = np.zeros((4, 6), dtype=np.uint8)
    log = _log(3)
    batches: list[list[Record]] = [
        [log.odometry[0], Image(0.2, pixels, camera="ceiling"), log.scans[0]],
        [log.odometry[1], log.scans[1], Image(1.2, pixels, camera="forward")],
        [log.odometry[2], log.scans[2]],
    ]
    loc = ImageLocalizerStandIn()
    cam = ImageCountingEstimator()
    plain = CountingEstimator("people", ScanShare.ALL)
    assert isinstance(loc, ImageLocalizer)
    assert isinstance(cam, ImageEstimator)
    assert not isinstance(OdomLocalizer(), ImageLocalizer)
    assert not isinstance(plain, ImageEstimator)
    rt = Runtime(RecordSource(batches), loc, estimators=[cam, plain])
    snaps = [rt.step() for _ in range(3)]
    assert loc.images == ["ceiling", "forward"]
    # each estimator sees the belief the localizer made of that image
    assert cam.images == [("ceiling", 100.2), ("forward", 101.2)]
    assert plain.scans == [0.0, 1.0, 2.0]
    # the belief an image gives is the snapshot's until the next scan
    assert snaps[1] is not None
    assert snaps[1].pose is not None
    assert snaps[1].pose.x == 101.2
    assert rt.step() is None
