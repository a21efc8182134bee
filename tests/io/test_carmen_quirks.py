"""Quirks of robot logs from other labs, reproduced on variants of the shared logs written here.

Each variant is the FHW (or Intel) corrected log with one change a real log of the same
collection has; each must be read right or refused in one line, never read silently wrong.
"""

from __future__ import annotations

import gzip
import math
from pathlib import Path

import numpy as np
import pytest

from tourbot.io import LogFormatError, read_carmen
from tourbot.records import RobotLog


def _lines(path: Path) -> list[str]:
    with gzip.open(path, "rt") as f:
        return f.read().splitlines()


def _variant(tmp_path: Path, lines: list[str], name: str = "variant.log.gz") -> Path:
    out = tmp_path / name
    with gzip.open(out, "wt", compresslevel=1) as f:
        f.write("\n".join(lines) + "\n")
    return out


def _is_copy(lines: list[str], k: int) -> bool:
    """The ODOM line right after a laser line, zero-stamped: the corrected copy in these logs."""
    return lines[k].startswith("ODOM") and k > 0 and lines[k - 1].startswith("FLASER")


@pytest.fixture(scope="module")
def fhw_lines(shared_data: Path) -> list[str]:
    return _lines(shared_data / "carmen" / "fhw-corrected.log.gz")


@pytest.fixture(scope="module")
def fhw(shared_data: Path) -> RobotLog:
    return read_carmen(shared_data / "carmen" / "fhw-corrected.log.gz")


def test_a_field_of_view_in_radians_is_read_as_radians(
    tmp_path: Path, fhw_lines: list[str], fhw: RobotLog
) -> None:
    log = read_carmen(_variant(tmp_path, ["PARAM laser_front_laser_fov 3.14159 nohost 0", *fhw_lines]))
    g = log.scans[0].geometry
    assert g.angle_min == pytest.approx(-math.pi / 2, abs=1e-4)
    assert g.angles[-1] == pytest.approx(fhw.scans[0].geometry.angles[-1], abs=math.radians(1.01))
    assert any("laser_front_laser_fov 3.14159 read as radians" in n for n in log.notes)
    assert any("consecutive scans at the reference poses agree" in n for n in log.notes)


def test_a_field_of_view_in_degrees_stays_degrees(tmp_path: Path, fhw_lines: list[str]) -> None:
    log = read_carmen(_variant(tmp_path, ["PARAM laser_front_laser_fov 180 nohost 0", *fhw_lines]))
    assert log.scans[0].geometry.angle_min == pytest.approx(-math.pi / 2)
    assert any("fov 180 read as degrees" in n for n in log.notes)


def test_a_wrong_field_of_view_is_overruled_by_the_data(tmp_path: Path, fhw_lines: list[str]) -> None:
    """A PARAM that would squeeze the beams into 100 degrees: the scans disagree, CARMEN's layout fits."""
    log = read_carmen(_variant(tmp_path, ["PARAM laser_front_laser_fov 100 nohost 0", *fhw_lines]))
    assert log.scans[0].geometry.angle_min == pytest.approx(-math.pi / 2)
    assert log.scans[0].geometry.fov == pytest.approx(math.radians(179))
    assert any("do not fit the data" in w for w in log.warnings)


def _mirror(line: str) -> str:
    tokens = line.split()
    n = int(tokens[1])
    tokens[2 : 2 + n] = tokens[2 : 2 + n][::-1]
    return " ".join(tokens)


def test_beams_swept_left_to_right_are_found_mirrored(
    tmp_path: Path, fhw_lines: list[str], fhw: RobotLog
) -> None:
    lines = [_mirror(line) if line.startswith("FLASER") else line for line in fhw_lines]
    log = read_carmen(_variant(tmp_path, lines))
    assert log.scans[0].geometry == fhw.scans[0].geometry
    for k in (0, 100, 487):
        np.testing.assert_array_equal(log.scans[k].ranges, fhw.scans[k].ranges)
    assert any("mirrored" in w and "ranges reversed" in w for w in log.warnings)


def test_scans_no_layout_explains_are_refused_in_one_line(tmp_path: Path, fhw_lines: list[str]) -> None:
    rng = np.random.default_rng(0)

    def shuffle(line: str) -> str:
        tokens = line.split()
        n = int(tokens[1])
        tokens[2 : 2 + n] = list(rng.permutation(tokens[2 : 2 + n]))
        return " ".join(tokens)

    lines = [shuffle(line) if line.startswith("FLASER") else line for line in fhw_lines]
    with pytest.raises(LogFormatError, match="no beam layout makes consecutive scans agree") as err:
        read_carmen(_variant(tmp_path, lines))
    assert "\n" not in str(err.value)


def test_a_10_m_range_cap_is_seen_through(tmp_path: Path, fhw_lines: list[str], fhw: RobotLog) -> None:
    log = read_carmen(_variant(tmp_path, ["PARAM robot_front_laser_max 10 nohost 0", *fhw_lines]))
    assert log.scans[0].geometry.max_range == pytest.approx(fhw.scans[0].geometry.max_range)
    assert any("read as a software cap" in w for w in log.warnings)


def test_a_range_param_in_centimetres_is_seen_through(
    tmp_path: Path, fhw_lines: list[str], fhw: RobotLog
) -> None:
    log = read_carmen(_variant(tmp_path, ["PARAM robot_front_laser_max 5105 nohost 0", *fhw_lines]))
    assert log.scans[0].geometry.max_range == pytest.approx(fhw.scans[0].geometry.max_range)
    assert any("beyond every reading" in w for w in log.warnings)


def test_a_range_param_the_data_respects_is_kept(tmp_path: Path, fhw_lines: list[str]) -> None:
    log = read_carmen(_variant(tmp_path, ["PARAM robot_front_laser_max 60 nohost 0", *fhw_lines]))
    assert log.scans[0].geometry.max_range == 60.0
    assert not any("software cap" in w for w in log.warnings)


def test_zero_stamped_odometry_beside_garbage_stamped_copies(
    tmp_path: Path, fhw_lines: list[str], fhw: RobotLog
) -> None:
    """The real ODOM lines carry zero timestamps, the per-scan copies garbage ones: all kept, copies out."""
    garbage = ["3.46", "3.7e-86", "1e+300", "-7.2", "12345.678"]
    lines = []
    for k, line in enumerate(fhw_lines):
        if not line.startswith("ODOM"):
            lines.append(line)
            continue
        t = line.split()
        stamp = garbage[k % len(garbage)] if _is_copy(fhw_lines, k) else "0"
        t[7], t[9] = stamp, stamp
        lines.append(" ".join(t))
    log = read_carmen(_variant(tmp_path, lines))
    assert len(log.odometry) == len(fhw.odometry)  # every real reading kept
    assert log.odometry_kind == "rebuilt"
    np.testing.assert_allclose([o.pose for o in log.odometry], [o.pose for o in fhw.odometry], atol=1e-9)
    # matched in record order: the reading before each scan is the one at the scan's time
    err = np.hypot(*(log.odom_poses[:, :2] - fhw.odom_poses[:, :2]).T)
    assert np.max(err) < 0.05
    assert any("record order" in w for w in log.warnings)


def test_wrapped_timestamps_are_unwrapped(tmp_path: Path, fhw_lines: list[str], fhw: RobotLog) -> None:
    """Stamps near 2^32 s that wrap to small values halfway: unwrapped, the duration right."""
    base = 2.0**32 - 1000.0

    def restamp(line: str) -> str:
        t = line.split()
        if t[0] == "ODOM":
            i = 7
        elif t[0] == "FLASER":
            i = 2 + int(t[1]) + 6
        else:
            return line
        if float(t[i]) == 0.0:
            return line
        stamp = (base + float(t[i])) % 2.0**32
        t[i] = t[i + 2] = f"{stamp:.6f}"
        return " ".join(t)

    log = read_carmen(_variant(tmp_path, [restamp(line) for line in fhw_lines]))
    span, _why = log.duration()
    assert span == pytest.approx(fhw.duration()[0], abs=0.01)
    assert any("wrap around" in w for w in log.warnings)
    err = np.hypot(*(log.odom_poses[:, :2] - fhw.odom_poses[:, :2]).T)
    assert np.max(err) < 1e-6


def test_all_zero_scan_timestamps_give_no_duration(tmp_path: Path, fhw_lines: list[str]) -> None:
    def unstamp(line: str) -> str:
        t = line.split()
        if t[0] != "FLASER":
            return line
        i = 2 + int(t[1]) + 6
        t[i] = t[i + 2] = "0"
        return " ".join(t)

    log = read_carmen(_variant(tmp_path, [unstamp(line) for line in fhw_lines]))
    span, why = log.duration()
    assert span is None
    assert "all zero" in why


def test_one_garbage_scan_stamp_gives_no_duration(tmp_path: Path, fhw_lines: list[str]) -> None:
    lines = list(fhw_lines)
    last = max(k for k, line in enumerate(lines) if line.startswith("FLASER"))
    t = lines[last].split()
    i = 2 + int(t[1]) + 6
    t[i] = t[i + 2] = "99999.0"
    lines[last] = " ".join(t)
    span, why = read_carmen(_variant(tmp_path, lines)).duration()
    assert span is None
    assert "holds most of the log" in why


def test_sparse_odometry_is_read_and_counted(tmp_path: Path, fhw_lines: list[str]) -> None:
    """4 real odometry readings for hundreds of scans: read (the checks before the work refuse it)."""
    keep = 4
    odom = [k for k, line in enumerate(fhw_lines) if line.startswith("ODOM") and not _is_copy(fhw_lines, k)]
    drop = set(odom) - set(odom[:: max(1, len(odom) // keep)][:keep])
    log = read_carmen(_variant(tmp_path, [line for k, line in enumerate(fhw_lines) if k not in drop]))
    assert len(log.odometry) == keep
    assert len(log.scans) == 488
