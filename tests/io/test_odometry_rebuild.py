"""Re-anchored odometry streams (corrected CARMEN logs): found by their pattern, rebuilt from increments.

In a corrected log an ``ODOM`` line after each scan repeats the scan's corrected pose and the
stream continues from it (``../shared/data/README.md``). Read as recorded its error never grows;
rebuilt from the increments it drifts as real odometry does (README: Intel ~24 m, FHW ~26 m).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tourbot.geometry import compose, relative
from tourbot.io import load_log, read_carmen, write_carmen
from tourbot.io.carmen import survey_odometry
from tourbot.plotting import align_rigid
from tourbot.records import RobotLog


def _ate(log: RobotLog) -> float:
    """Aligned trajectory error (RMS, metres) of the odometry at the scans against the reference."""
    a = align_rigid(log.odom_poses, log.reference_poses)
    e = np.hypot(*(a[:, :2] - log.reference_poses[:, :2]).T)
    return float(np.sqrt(np.mean(e**2)))


@pytest.mark.parametrize(("name", "expected"), [("intel", 24.0), ("fhw", 26.0)])
def test_rebuilt_odometry_drifts_as_in_the_readme(shared_data: Path, name: str, expected: float) -> None:
    path = shared_data / "carmen" / f"{name}-corrected.log.gz"
    rebuilt = read_carmen(path)
    kept = read_carmen(path, odometry="as-recorded")
    assert rebuilt.odometry_kind == "rebuilt"
    assert kept.odometry_kind == "re-anchored"
    assert _ate(rebuilt) == pytest.approx(expected, rel=0.1)
    assert _ate(kept) < 0.1  # the stream fed the answer
    assert sum("rebuilt from its increments" in w for w in rebuilt.warnings) == 1
    assert sum("kept as recorded" in w for w in kept.warnings) == 1
    # the same readings (copies left out of both), only the poses differ
    assert len(rebuilt.odometry) == len(kept.odometry)
    assert [o.timestamp for o in rebuilt.odometry] == [o.timestamp for o in kept.odometry]


def test_every_real_log_is_found_reanchored(shared_data: Path) -> None:
    for name in ("aces", "freiburg-079"):
        survey = survey_odometry(shared_data / "carmen" / f"{name}-corrected.log.gz")
        assert survey.reanchored
        assert survey.anchored_scans == survey.scans
        assert survey.misfit[0] < 0.9 * survey.misfit[1]


def _fmt(pose: np.ndarray) -> str:
    return " ".join(f"{float(v):.6g}" for v in pose)


def _synthetic(tmp_path: Path, *, reanchor: bool, copy_after: bool = True, stamp: str = "0") -> Path:
    """A robot driving a curve with odometry that drifts; corrected poses on the scans.

    ``reanchor``: the stream continues from each scan's corrected pose (a corrected log) or runs
    in its own frame (a raw log that still writes the copies).
    """
    rng = np.random.default_rng(3)
    true = np.zeros(3)
    raw = np.zeros(3)
    lines = []
    t = 0.0
    for _ in range(60):
        for _step in range(3):
            step = np.array([0.1, 0.0, 0.03])
            true = compose(true, step)
            raw = compose(raw, step * np.array([1.05, 1.0, 1.1]) + rng.normal(0, 0.002, 3))
            t += 0.1
            lines.append(f"ODOM {_fmt(raw)} 0 0 0 {t!r} host {t!r}")
        ranges = " ".join(["2.0"] * 10)
        p = _fmt(true)
        copy = f"ODOM {p} 0 0 0 {stamp} host {stamp}"
        if not copy_after:
            lines.append(copy)
        lines.append(f"FLASER 10 {ranges} {p} {p} {t!r} host {t!r}")
        if copy_after:
            lines.append(copy)
        if reanchor:
            raw = np.array([float(f"{v:.6g}") for v in true])
    path = tmp_path / "synthetic.log"
    path.write_text("\n".join(lines) + "\n")
    return path


def _wheel_increments(log: RobotLog) -> np.ndarray:
    o = np.array([r.pose for r in log.odometry])
    return relative(o[:-1], o[1:])


def test_rebuild_keeps_the_wheel_increments_and_drops_the_corrections(tmp_path: Path) -> None:
    path = _synthetic(tmp_path, reanchor=True)
    rebuilt = read_carmen(path)
    kept = read_carmen(path, odometry="as-recorded")
    assert rebuilt.odometry_kind == "rebuilt"
    inc = _wheel_increments(rebuilt)
    # every increment is a wheel step (about 0.105 m), none is a jump onto a corrected pose
    assert np.all(np.abs(inc[:, 0] - 0.105) < 0.01)
    assert np.all(np.abs(inc[:, 2] - 0.033) < 0.01)
    # the rebuilt path drifts from the reference, the kept one does not
    drift = np.hypot(*(rebuilt.odom_poses[-1, :2] - rebuilt.reference_poses[-1, :2]))
    assert drift > 1.0
    assert np.hypot(*(kept.odom_poses[-1, :2] - kept.reference_poses[-1, :2])) < 0.05


def test_copies_before_the_scan_are_found_too(tmp_path: Path) -> None:
    after = read_carmen(_synthetic(tmp_path, reanchor=True))
    (tmp_path / "a").mkdir()
    before = read_carmen(_synthetic(tmp_path / "a", reanchor=True, copy_after=False))
    assert before.odometry_kind == "rebuilt"
    assert len(before.odometry) == len(after.odometry) == 180


def test_a_stream_in_its_own_frame_is_not_rebuilt(tmp_path: Path) -> None:
    """Copies of the scan poses but readings that do not continue from them: drop the copies only."""
    log = read_carmen(_synthetic(tmp_path, reanchor=False))
    assert log.odometry_kind == "raw"
    assert len(log.odometry) == 180
    assert any("do not continue" in w or "does not continue" in w for w in log.warnings)
    inc = _wheel_increments(log)
    assert np.all(np.abs(inc[:, 0] - 0.105) < 0.01)


def test_copies_with_garbage_timestamps_are_recognised_by_their_pose(tmp_path: Path) -> None:
    log = read_carmen(_synthetic(tmp_path, reanchor=True, stamp="3.7e-86"))
    assert log.odometry_kind == "rebuilt"
    assert len(log.odometry) == 180  # all real readings kept, no copy among them
    assert np.all(np.abs(_wheel_increments(log)[:, 0] - 0.105) < 0.01)


def test_written_rebuilt_log_reads_back_rebuilt_and_unchanged(tmp_path: Path) -> None:
    rebuilt = read_carmen(_synthetic(tmp_path, reanchor=True))
    out = tmp_path / "again.log.gz"
    write_carmen(rebuilt, out)
    again = load_log(out)
    assert again.odometry_kind == "rebuilt"
    np.testing.assert_allclose(again.odom_poses, rebuilt.odom_poses)
    assert [o.pose for o in again.odometry] == [o.pose for o in rebuilt.odometry]


def test_rebuilt_heading_stays_wrapped(tmp_path: Path) -> None:
    log = read_carmen(_synthetic(tmp_path, reanchor=True))
    th = np.array([o.pose[2] for o in log.odometry])
    assert np.all((th > -math.pi) & (th <= math.pi))
