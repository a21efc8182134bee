"""The CARMEN reader and writer: the four real logs, synthetic quirks, bad input, round trips."""

from __future__ import annotations

import gzip
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from tourbot.io import LogFormatError, iter_carmen, load_log, read_carmen, write_carmen
from tourbot.io.carmen import DEFAULT_MAX_RANGE, guess_angle_increment
from tourbot.records import LaserGeometry, Odometry, RobotLog, Scan

# scans, beams, duration (s), reference path length (m): ../shared/data/README.md
REAL_LOGS = {
    "fhw": (488, 180, 2007, 406),
    "intel": (910, 180, 2651, 500),
    "aces": (440, 180, 1318, 323),
    "freiburg-079": (4791, 360, 1061, 422),
}


def _flaser(ranges: list[float], pose: tuple[float, float, float], ts: float) -> str:
    r = " ".join(str(v) for v in ranges)
    p = " ".join(str(v) for v in pose)
    return f"FLASER {len(ranges)} {r} {p} {p} {ts} host {ts}"


def _odom(pose: tuple[float, float, float], ts: float) -> str:
    return f"ODOM {pose[0]} {pose[1]} {pose[2]} 0 0 0 {ts} host {ts}"


def _write(tmp_path: Path, lines: list[str], name: str = "x.log") -> Path:
    path = tmp_path / name
    text = "\n".join(lines) + "\n"
    if name.endswith(".gz"):
        with gzip.open(path, "wt") as f:
            f.write(text)
    else:
        path.write_text(text)
    return path


def _same_logs(a: RobotLog, b: RobotLog) -> None:
    assert len(a.scans) == len(b.scans)
    assert a.odometry == b.odometry
    for s, t in zip(a.scans, b.scans, strict=True):
        assert s.timestamp == t.timestamp
        assert s.geometry == t.geometry
        assert s.odom == t.odom
        # the line carries the laser's pose (CARMEN's): the robot's comes back to rounding
        if s.reference is None or t.reference is None:
            assert s.reference == t.reference
        else:
            assert t.reference == pytest.approx(s.reference, rel=1e-12, abs=1e-12)
        assert s.sensor == t.sensor
        np.testing.assert_array_equal(s.ranges, t.ranges)


@pytest.mark.parametrize("name", sorted(REAL_LOGS))
def test_reads_the_real_logs(real_log: Callable[[str], RobotLog], name: str) -> None:
    scans, beams, duration, length = REAL_LOGS[name]
    log = real_log(name)
    assert len(log) == scans
    assert {s.geometry.num_beams for s in log.scans} == {beams}
    assert log.has_reference
    assert not np.isnan(log.odom_poses).any()
    assert log.times[-1] - log.times[0] == pytest.approx(duration, abs=1)
    steps = np.diff(log.reference_poses[:, :2], axis=0)
    assert np.hypot(steps[:, 0], steps[:, 1]).sum() == pytest.approx(length, rel=0.02)
    # the raw odometry is the timestamped ODOM stream, not the corrected copies after each scan
    assert all(o.timestamp > 0 for o in log.odometry)
    assert len(log.odometry) > len(log)
    # beams span 180 degrees from the right (-90 degrees)
    g = log.scans[0].geometry
    assert g.angle_min == pytest.approx(-math.pi / 2)
    assert g.fov == pytest.approx(math.pi, abs=math.radians(1.01))


def test_fhw_rebuilt_odometry_increments_are_the_wheels(real_log: Callable[[str], RobotLog]) -> None:
    """Per-scan rotation of the rebuilt odometry against the reference: wheel error, no corrections."""
    from tourbot.geometry import relative, wrap_angle

    log = real_log("fhw")
    o, r = log.odom_poses, log.reference_poses
    do, dr = relative(o[:-1], o[1:]), relative(r[:-1], r[1:])
    err = np.degrees(np.abs(wrap_angle(do[:, 2] - dr[:, 2])).mean())
    assert 0.8 < err < 1.8


def test_max_range_inferred_or_from_param(real_log: Callable[[str], RobotLog]) -> None:
    fhw = real_log("fhw")
    assert fhw.scans[0].geometry.max_range == pytest.approx(51.05)  # piled-up "no return" value
    fr = real_log("freiburg-079")
    assert fr.scans[0].geometry.max_range == pytest.approx(80.99)  # PARAM robot_front_laser_max
    assert fr.scans[0].geometry.offset == (-0.04, 0.0, 0.0)  # PARAM robot_frontlaser_offset


def test_odometry_interpolated_at_scan_time_and_reference_from_line(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        [
            "# comment",
            _odom((0.0, 0.0, 3.0), 1.0),
            _flaser([1.0, 2.0, 3.0], (5.0, 6.0, 0.5), 2.0),
            _odom((5.0, 6.0, 0.5), 0.0),  # corrected copy: not odometry
            "NEFF 12",
            _odom((2.0, 4.0, -3.0), 3.0),
        ],
    )
    log = read_carmen(path)
    assert [o.timestamp for o in log.odometry] == [1.0, 3.0]
    (scan,) = log.scans
    assert scan.reference == (5.0, 6.0, 0.5)
    assert scan.odom is not None
    x, y, th = scan.odom
    assert (x, y) == pytest.approx((1.0, 2.0))
    # halfway from 3.0 to -3.0 the short way round (through pi), not through zero
    assert abs(th) == pytest.approx(math.pi, abs=1e-9)
    assert scan.geometry.angle_increment == pytest.approx(guess_angle_increment(3))
    (warning,) = log.warnings
    assert "copies are left out, the stream kept (too few readings to tell)" in warning


def test_streaming_holds_a_scan_until_the_next_odometry(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        [_odom((0.0, 0.0, 0.0), 1.0), _flaser([1.0], (0, 0, 0), 1.5), _odom((1.0, 0.0, 0.0), 2.0)],
    )
    records = list(iter_carmen(path))
    assert [type(r).__name__ for r in records] == ["Odometry", "Scan", "Odometry"]
    scan = records[1]
    assert isinstance(scan, Scan)
    assert scan.odom == pytest.approx((0.5, 0.0, 0.0))


def test_zero_timestamps_fall_back_to_record_order_with_one_warning(tmp_path: Path) -> None:
    lines = []
    for i in range(4):
        lines.append(f"ODOM {i}.0 0 0 0 0 0 0 host 0")
        lines.append(f"FLASER 2 1 1 {i}.5 0 0 {i}.5 0 0 0 host 0")
    log = read_carmen(_write(tmp_path, lines))
    assert len(log.warnings) == 1
    assert "record order" in log.warnings[0]
    # without a timestamped odometry stream the odometry written on the laser line is used
    assert [s.odom for s in log.scans] == [(i + 0.5, 0.0, 0.0) for i in range(4)]
    assert [s.reference for s in log.scans] == [None] * 4


def test_backwards_timestamps_fall_back_to_record_order(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        [
            _odom((0.0, 0.0, 0.0), 5.0),
            _odom((1.0, 0.0, 0.0), 4.0),  # backwards
            _flaser([1.0], (9, 9, 0), 4.5),
            _odom((2.0, 0.0, 0.0), 6.0),
            _flaser([1.0], (9, 9, 0), 3.0),  # backwards
        ],
    )
    log = read_carmen(path)
    assert len(log.warnings) == 1
    assert "go backwards" in log.warnings[0]
    assert [s.odom for s in log.scans] == [(1.0, 0.0, 0.0), (2.0, 0.0, 0.0)]


def test_new_laser_records_carry_their_geometry(tmp_path: Path) -> None:
    ranges = " ".join(["2.0"] * 181)
    lines = [
        _odom((0.0, 0.0, 0.0), 1.0),
        f"RAWLASER1 0 -1.5708 3.14159 0.0174533 32.767 0.01 0 181 {ranges} 0 1.5 host 1.5",
        f"ROBOTLASER1 0 -1.5708 3.14159 0.0174533 32.767 0.01 0 181 {ranges} 0 "
        "1.1 2 0.3 1 2 0.3 0 0 0.5 0.3 0 1.6 host 1.6",
        _odom((1.0, 0.0, 0.0), 2.0),
    ]
    path = _write(tmp_path, lines)
    raw = read_carmen(path)
    assert raw.scans[0].sensor == "RAWLASER1"
    assert "ROBOTLASER1" in raw.warnings[0]
    g = raw.scans[0].geometry
    assert (g.num_beams, g.angle_min, g.max_range) == (181, -1.5708, 32.767)
    assert raw.scans[0].odom == pytest.approx((0.5, 0.0, 0.0))
    robot = read_carmen(path, laser="ROBOTLASER1")
    scan = robot.scans[0]
    assert scan.reference == (1.0, 2.0, 0.3)
    assert scan.geometry.offset == pytest.approx((0.1 * math.cos(0.3), -0.1 * math.sin(0.3), 0.0))
    with pytest.raises(LogFormatError, match="no RLASER scans"):
        read_carmen(path, laser="RLASER")


def test_plain_and_gzip_give_the_same_log(tmp_path: Path) -> None:
    lines = [_odom((0.0, 0.0, 0.0), 1.0), _flaser([1.0, 2.0], (0, 0, 0), 1.5), _odom((1, 0, 0), 2.0)]
    _same_logs(read_carmen(_write(tmp_path, lines)), read_carmen(_write(tmp_path, lines, "x.log.gz")))


def test_default_max_range_without_param_or_pileup(tmp_path: Path) -> None:
    log = read_carmen(_write(tmp_path, [_flaser([1.0, 2.0], (0, 0, 0), 1.0)]))
    assert log.scans[0].geometry.max_range == DEFAULT_MAX_RANGE


# ---- bad input -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("line", "field", "message"),
    [
        ("FLASER 3 1.0 nan 2.0 0 0 0 0 0 0 1.0 h 1.0", "range[1]", "not a number"),
        ("FLASER 3 1.0 1.0 -2.0 0 0 0 0 0 0 1.0 h 1.0", "range[2]", "negative"),
        ("FLASER 3 1.0 abc 2.0 0 0 0 0 0 0 1.0 h 1.0", "range[1]", "not a number"),
        ("FLASER 3 1.0 2.0 0 0 0", None, "too short"),
        ("FLASER x 1.0", "num_readings", "whole number"),
        ("ODOM 1 2 oops 0 0 0 1.0 h 1.0", "theta", "not a number"),
        ("ODOM 1 2", None, "too short"),
        ("3.5 4.5 6", None, "unrecognised record"),
    ],
)
def test_malformed_record_names_file_line_and_field(
    tmp_path: Path, line: str, field: str | None, message: str
) -> None:
    good = _flaser([1.0, 2.0, 3.0], (0, 0, 0), 0.5)
    path = _write(tmp_path, ["# header", good, line, good.replace("0.5", "2.0")])
    with pytest.raises(LogFormatError, match=message) as info:
        read_carmen(path)
    err = info.value
    assert err.path == str(path)
    assert err.line == 3
    assert err.field == field
    assert f"{path}:3" in str(err)
    lenient = read_carmen(path, lenient=True)
    assert len(lenient) == 2
    assert any("skipped 1 malformed record" in w and "line 3" in w for w in lenient.warnings)


def test_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "empty.log"
    path.write_text("")
    with pytest.raises(LogFormatError, match="empty file"):
        read_carmen(path)
    only_comments = _write(tmp_path, ["# nothing", "PARAM a b"], "c.log")
    with pytest.raises(LogFormatError, match="no laser scans"):
        read_carmen(only_comments)


def test_binary_garbage(tmp_path: Path) -> None:
    path = tmp_path / "garbage.log"
    path.write_bytes(bytes(range(256)) * 8)
    with pytest.raises(LogFormatError, match="binary data") as info:
        read_carmen(path)
    assert info.value.line == 1
    with pytest.raises(LogFormatError, match=r"no laser scans.*malformed records skipped"):
        read_carmen(path, lenient=True)


def test_truncated_gzip(tmp_path: Path, fhw_log_path: Path) -> None:
    data = fhw_log_path.read_bytes()
    path = tmp_path / "cut.log.gz"
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(LogFormatError, match="truncated") as info:
        read_carmen(path)
    assert info.value.line is not None
    log = read_carmen(path, lenient=True)
    assert 100 < len(log) < 488
    assert any("truncated" in w for w in log.warnings)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(LogFormatError, match="no such file"):
        load_log(tmp_path / "nope.log")


# ---- writing --------------------------------------------------------------------------------------


@pytest.mark.parametrize(("name", "suffix"), [("fhw", ".log.gz"), ("intel", ".log")])
def test_round_trip_of_a_real_log_is_identical(
    real_log: Callable[[str], RobotLog], tmp_path: Path, name: str, suffix: str
) -> None:
    first = real_log(name)
    out = tmp_path / f"copy{suffix}"
    write_carmen(first, out)
    _same_logs(first, read_carmen(out))


finite = st.floats(-1e3, 1e3, allow_nan=False)


@settings(max_examples=25, deadline=None)
@given(
    n=st.integers(1, 20),
    steps=st.lists(
        st.tuples(finite, finite, st.floats(-3.14, 3.14), st.floats(0.01, 5.0)), min_size=1, max_size=8
    ),
    with_reference=st.booleans(),
    amin=st.floats(-3.0, 0.0),
    inc=st.floats(1e-3, 0.1),
    max_range=st.floats(1.0, 100.0),
)
def test_round_trip_property(
    n: int,
    steps: list[tuple[float, float, float, float]],
    with_reference: bool,
    amin: float,
    inc: float,
    max_range: float,
) -> None:
    import tempfile

    rng = np.random.default_rng(n)
    geometry = LaserGeometry(n, amin, inc, max_range, 0.0, (0.1, -0.2, 0.3))
    t = 0.0
    scans, odometry = [], []
    for x, y, th, dt in steps:
        t += dt
        odometry.append(Odometry(t - dt / 2, (y, x, th), 0.5, -0.1))
        ranges = rng.uniform(0, max_range, n)
        ref = (x, y, th) if with_reference else None
        scans.append(Scan(t, ranges, geometry, (x + 1, y, th), ref, "FLASER"))
    log = RobotLog("mem", scans, odometry)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "r.log"
        write_carmen(log, path)
        back = read_carmen(path)
    _same_logs(log, back)


def test_writer_refuses_mixed_reference(tmp_path: Path) -> None:
    g = LaserGeometry(1, 0.0, 0.1, 10.0)
    log = RobotLog(
        "mem",
        [Scan(1.0, np.ones(1), g, (0, 0, 0), (0, 0, 0)), Scan(2.0, np.ones(1), g, (0, 0, 0), None)],
    )
    with pytest.raises(LogFormatError, match="only some scans"):
        write_carmen(log, tmp_path / "m.log")


def test_the_line_pose_is_the_lasers_and_the_reference_the_robots(tmp_path: Path) -> None:
    # CARMEN writes the laser's pose on FLASER lines: the robot's is 0.1 m behind a laser
    # mounted 0.1 m ahead of it, here facing +y
    lines = [
        "PARAM robot_frontlaser_offset 0.1 nohost 0",
        _odom((0.0, 0.0, 0.0), 1.0),
        _flaser([1.0] * 181, (1.0, 2.0, math.pi / 2), 1.5),
        _odom((0.1, 0.0, 0.0), 2.0),
    ]
    log = read_carmen(_write(tmp_path, lines))
    (scan,) = log.scans
    assert scan.reference == pytest.approx((1.0, 1.9, math.pi / 2))
    assert any("the laser's on the FLASER lines" in n and "+0.1" in n for n in log.notes)
    # written back, the line holds the laser's pose again, and says so
    out = tmp_path / "w.log"
    write_carmen(log, out)
    text = out.read_text()
    assert "PARAM tourbot_scan_pose laser" in text
    (line,) = [ln for ln in text.splitlines() if ln.startswith("FLASER")]
    assert [float(v) for v in line.split()[2 + 181 : 2 + 181 + 3]] == pytest.approx([1.0, 2.0, math.pi / 2])
    assert read_carmen(out).scans[0].reference == pytest.approx((1.0, 1.9, math.pi / 2))


def test_a_written_rebuilt_odometry_is_noted_as_the_file_says(tmp_path: Path) -> None:
    g = LaserGeometry(3, -0.1, 0.1, 10.0)
    scans = [Scan(float(t), np.ones(3), g, (0.1 * t, 0.0, 0.0), None) for t in range(1, 4)]
    out = tmp_path / "r.log"
    write_carmen(RobotLog("mem", scans, [], odometry_kind="rebuilt"), out)
    back = read_carmen(out)
    assert back.odometry_kind == "rebuilt"
    assert "odometry: rebuilt (as PARAM tourbot_odometry_kind says)" in back.notes


def test_an_older_tourbot_file_carries_the_robots_pose(tmp_path: Path) -> None:
    # written before PARAM tourbot_scan_pose: the line's pose is the robot's, kept as it is
    lines = [
        "PARAM tourbot_scan_odometry line nohost 0",
        "PARAM tourbot_scan_reference line nohost 0",
        "PARAM tourbot_flaser_offset_x 0.1 nohost 0",
        "PARAM tourbot_flaser_offset_y 0.0 nohost 0",
        "PARAM tourbot_flaser_offset_theta 0.0 nohost 0",
        _flaser([1.0] * 181, (1.0, 2.0, math.pi / 2), 1.5),
    ]
    log = read_carmen(_write(tmp_path, lines))
    assert log.scans[0].reference == (1.0, 2.0, math.pi / 2)
    assert any("the robot's on the FLASER lines" in n for n in log.notes)
    with pytest.raises(LogFormatError, match="unknown scan pose 'base'"):
        read_carmen(_write(tmp_path, ["PARAM tourbot_scan_pose base nohost 0", *lines], "bad.log"))


def test_param_lines_set_the_old_laser_geometry(tmp_path: Path) -> None:
    lines = [
        "PARAM laser_front_laser_fov 100 nohost 0",
        "PARAM laser_front_laser_max_range 32.767 nohost 0",
        "PARAM robot_rearlaser_offset -0.2 nohost 0",
        "PARAM robot_rear_laser_max 8.0 nohost 0",
        "PARAM some_device /dev/ttyS0 nohost 0",
        _flaser([1.0] * 101, (0, 0, 0), 1.0),
        _flaser([1.0] * 181, (0, 0, 0), 2.0).replace("FLASER", "RLASER"),
    ]
    path = _write(tmp_path, lines)
    front = read_carmen(path).scans[0].geometry
    assert front.angle_min == pytest.approx(-math.radians(50))
    assert front.fov == pytest.approx(math.radians(100))
    assert front.max_range == 32.767
    rear = read_carmen(path, laser="RLASER").scans[0].geometry
    assert rear.offset == (-0.2, 0.0, math.pi)
    assert rear.max_range == 8.0
    assert rear.angle_increment == pytest.approx(math.radians(1))  # CARMEN's guess for 181 beams


def test_iter_carmen_collects_warnings(tmp_path: Path) -> None:
    path = _write(tmp_path, ["FLASER 1 1.0 0 0 0 0 0 0 0 h 0", "FLASER 1 -1 0 0 0 0 0 0 1 h 1"])
    warnings: list[str] = []
    records = list(iter_carmen(path, lenient=True, warnings=warnings))
    assert len(records) == 1
    assert len(warnings) == 2  # zero timestamps, one skipped record
    assert any("record order" in w for w in warnings)
    assert any("skipped 1" in w for w in warnings)


def test_angles_are_wrapped(tmp_path: Path) -> None:
    log = read_carmen(_write(tmp_path, [_odom((0, 0, 4.0), 1.0), _flaser([1.0], (0, 0, -3.5), 1.0)]))
    assert log.odometry[0].pose[2] == pytest.approx(4.0 - 2 * math.pi)
    scan = log.scans[0]
    assert scan.reference is not None
    assert scan.reference[2] == pytest.approx(2 * math.pi - 3.5)


def test_a_scan_from_the_far_future_does_not_hold_the_stream(tmp_path: Path) -> None:
    lines = [_odom((0.0, 0.0, 0.0), 1.0), _flaser([1.0], (0, 0, 0), 1e9)]
    lines += [_odom((float(i), 0.0, 0.0), 1.0 + i) for i in range(1, 50)]
    lines += [_flaser([1.0], (0, 0, 0), 30.5), _odom((99.0, 0.0, 0.0), 60.0)]
    log = read_carmen(_write(tmp_path, lines))
    assert len(log.warnings) == 1
    assert "go backwards" in log.warnings[0]
    # record order: each scan takes the latest reading before it in the file
    assert [s.odom for s in log.scans] == [(0.0, 0.0, 0.0), (49.0, 0.0, 0.0)]


@pytest.mark.parametrize("fraction", [0.3, 0.51, 0.77, 0.9])
def test_truncation_anywhere_is_reported_as_truncation(tmp_path: Path, fraction: float) -> None:
    rng = np.random.default_rng(1)
    lines = []
    for i in range(300):
        lines.append(_odom((0.01 * i, 0.0, 0.0), 1.0 + i))
        lines.append(_flaser(rng.uniform(0.5, 9.0, 90).round(3).tolist(), (0.01 * i, 0.0, 0.0), 1.5 + i))
    whole = _write(tmp_path, lines, "whole.log.gz").read_bytes()
    cut = tmp_path / "cut.log.gz"
    cut.write_bytes(whole[: int(len(whole) * fraction)])
    with pytest.raises(LogFormatError, match="truncated"):
        read_carmen(cut)
    kept = read_carmen(cut, lenient=True)
    assert 0 < len(kept) < 300
    assert not any("malformed" in w for w in kept.warnings)


@settings(max_examples=30, deadline=None)
@given(
    odom_steps=st.lists(st.floats(0.01, 2.0), min_size=2, max_size=30),
    scan_steps=st.lists(st.floats(0.01, 2.0), min_size=1, max_size=20),
    seed=st.integers(0, 1000),
)
def test_streaming_matches_whole_stream_interpolation(
    odom_steps: list[float], scan_steps: list[float], seed: int
) -> None:
    """The streaming matcher gives what interpolating over the whole odometry stream gives."""
    import tempfile

    from tourbot.geometry import interpolate_poses

    rng = np.random.default_rng(seed)
    odom_t = np.cumsum(odom_steps)
    scan_t = np.cumsum(scan_steps) + rng.uniform(-1.0, 1.0)
    scan_t = scan_t[scan_t > 0]
    assume(len(scan_t) > 0)
    poses = np.column_stack([rng.uniform(-5, 5, (len(odom_t), 2)), rng.uniform(-3.1, 3.1, len(odom_t))])
    events = [(t, 0, i) for i, t in enumerate(odom_t)] + [(t, 1, i) for i, t in enumerate(scan_t)]
    lines = []
    for t, kind, i in sorted(events):
        if kind == 0:
            lines.append(_odom(tuple(poses[i]), float(t)))
        else:
            lines.append(_flaser([1.0], (9.0, 9.0, 0.0), float(t)))
    with tempfile.TemporaryDirectory() as tmp:
        log = read_carmen(_write(Path(tmp), lines))
    assert log.warnings == []
    expected = interpolate_poses(odom_t, poses, scan_t)
    got = log.odom_poses
    np.testing.assert_allclose(got[:, :2], expected[:, :2], atol=1e-9)
    np.testing.assert_allclose(np.cos(got[:, 2] - expected[:, 2]), 1.0, atol=1e-9)
