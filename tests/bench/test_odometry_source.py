"""Every localization and mapping benchmark stands on odometry rebuilt from the increments.

The corrected logs' ODOM stream is re-anchored to the reference at every scan; a benchmark that
read it as recorded would be fed the answer. These tests fail if a benchmark's logs carry it.
"""

from __future__ import annotations

import inspect
from pathlib import Path

import numpy as np
import pytest

import tourbot.bench.grid
import tourbot.bench.kernels
import tourbot.bench.localization
import tourbot.bench.mapping
import tourbot.bench.mcl
from tourbot.records import RobotLog


def _drift(log: RobotLog) -> float:
    """How far the odometry ends from the reference once both start at the same pose (m).

    From the second scan: the first one's odometry precedes the first re-anchoring.
    """
    from tourbot.geometry import compose, relative

    o, r = log.odom_poses, log.reference_poses
    moved = compose(r[1], relative(o[1], o[-1]))
    return float(np.hypot(*(moved[:2] - r[-1, :2])))


@pytest.mark.usefixtures("shared_data")
def test_mapping_bench_reads_rebuilt_odometry() -> None:
    log = tourbot.bench.mapping._read("intel", 300)
    assert log.odometry_kind == "rebuilt"
    assert _drift(log) > 0.5  # the re-anchored stream ends within centimetres of the reference


def test_localization_bench_crowds_keep_rebuilt_odometry(shared_data: Path, tmp_path: Path) -> None:
    from tourbot.io import read_carmen
    from tourbot.maps.reference import build_reference_map

    base = read_carmen(shared_data / "carmen" / "intel-corrected.log.gz")
    short = RobotLog(base.source, base.scans[:300], base.odometry, odometry_kind=base.odometry_kind)
    grid = build_reference_map(short, 0.1)
    crowded, _truth = tourbot.bench.localization._crowded(short, grid, "intel", "sparse", 0, tmp_path)
    assert crowded.odometry_kind == "rebuilt"
    np.testing.assert_allclose(crowded.odom_poses, short.odom_poses)
    assert _drift(crowded) > 0.5
    # a cache written from the stream kept as recorded is never taken for the rebuilt one
    kept = read_carmen(shared_data / "carmen" / "intel-corrected.log.gz", odometry="as-recorded")
    kept_short = RobotLog(kept.source, kept.scans[:300], kept.odometry, odometry_kind=kept.odometry_kind)
    again, _ = tourbot.bench.localization._crowded(kept_short, grid, "intel", "sparse", 0, tmp_path)
    assert again.odometry_kind == "re-anchored"
    assert _drift(crowded) > 3 * _drift(again)


@pytest.mark.parametrize(
    "module",
    [
        tourbot.bench.grid,
        tourbot.bench.kernels,
        tourbot.bench.localization,
        tourbot.bench.mapping,
        tourbot.bench.mcl,
    ],
)
def test_no_benchmark_asks_for_the_stream_as_recorded(module: object) -> None:
    """The readers rebuild by default; a benchmark passing ``as-recorded`` would bypass it."""
    source = inspect.getsource(module)  # type: ignore[arg-type]
    assert "as-recorded" not in source
    assert "read_carmen(" in source or "load_log(" in source
