"""The crowd overlay on a log: beams cut to the visitors' legs, consistently, with the truth kept."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tourbot.cli.main import main
from tourbot.errors import InputError
from tourbot.io import read_carmen, write_carmen
from tourbot.io.mapserver import write_map
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.raycast import DDACaster
from tourbot.records import LaserGeometry, Odometry, RobotLog, Scan
from tourbot.sim.crowd import CrowdConfig
from tourbot.sim.overlay import (
    OverlayConfig,
    OverlayError,
    overlay_crowd,
    read_truth,
    truth_path,
    write_truth,
)


def _room() -> OccupancyGrid:
    prob = np.zeros((100, 200), dtype=np.float32)  # 20 x 10 m at 10 cm
    prob[:2, :] = prob[-2:, :] = prob[:, :2] = prob[:, -2:] = 1.0
    return OccupancyGrid(prob, 0.1, (0.0, 0.0, 0.0))


def _log(grid: OccupancyGrid, n: int = 40) -> RobotLog:
    """A robot driving along the room at 0.4 m/s, scans every 0.5 s cast from the map."""
    geometry = LaserGeometry(181, -math.pi / 2, math.pi / 180, 30.0)
    caster = DDACaster(grid, geometry.max_range)
    poses = np.array([(3.0 + 0.2 * i, 5.0, 0.0) for i in range(n)])
    ranges = caster.cast(poses, geometry.angles).astype(np.float64)
    scans = [
        Scan(0.5 * i, ranges[i], geometry, odom=tuple(poses[i]), reference=tuple(poses[i])) for i in range(n)
    ]
    odometry = [Odometry(0.5 * i - 0.1, tuple(poses[i])) for i in range(n)]
    return RobotLog("synthetic", scans, odometry)


def _busy() -> OverlayConfig:
    return OverlayConfig(
        crowd=CrowdConfig(num_people=40, robot_interest=0.9, notice_distance=30.0), warmup=20.0
    )


def test_beams_are_cut_to_the_legs_only() -> None:
    grid = _room()
    log = _log(grid)
    result = overlay_crowd(log, grid, _busy(), seed=1)
    before, after = log.ranges, result.log.ranges
    hit = result.truth.corrupted
    assert hit.shape == before.shape
    assert 0.05 < hit.mean() < 0.9
    np.testing.assert_array_equal(after[~hit], before[~hit])
    # Cut beams end at a leg, in front of the wall (up to the 1 cm noise).
    assert np.all(after[hit] < before[hit] + 0.05)
    assert np.median(before[hit] - after[hit]) > 0.5
    # Poses and odometry untouched without kidnaps.
    np.testing.assert_array_equal(result.log.odom_poses, log.odom_poses)
    assert result.truth.kidnaps == []


def test_same_seed_same_crowd_other_seed_other_crowd() -> None:
    grid = _room()
    log = _log(grid, 12)
    a = overlay_crowd(log, grid, _busy(), seed=3).log.ranges
    b = overlay_crowd(log, grid, _busy(), seed=3).log.ranges
    c = overlay_crowd(log, grid, _busy(), seed=4).log.ranges
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_people_persist_from_scan_to_scan() -> None:
    """Consecutive scans 0.5 s apart see mostly the same corrupted directions (people walk slowly)."""
    grid = _room()
    log = _log(grid)
    hit = overlay_crowd(log, grid, _busy(), seed=2).truth.corrupted
    same = (hit[1:] & hit[:-1]).sum() / max(1, hit[1:].sum())
    assert same > 0.5


def test_kidnaps_change_only_the_odometry() -> None:
    grid = _room()
    log = _log(grid)
    cfg = OverlayConfig(crowd=CrowdConfig(num_people=0), warmup=0.0, kidnap=None)
    plain = overlay_crowd(log, grid, cfg, seed=0)
    from tourbot.sim.kidnap import KidnapConfig

    kid_cfg = OverlayConfig(
        crowd=CrowdConfig(num_people=0), warmup=0.0, kidnap=KidnapConfig(probability_per_metre=1.0)
    )
    kidnapped = overlay_crowd(log, grid, kid_cfg, seed=0)
    assert kidnapped.truth.kidnaps
    np.testing.assert_array_equal(kidnapped.log.ranges, plain.log.ranges)
    np.testing.assert_array_equal(kidnapped.log.reference_poses, plain.log.reference_poses)
    assert not np.allclose(kidnapped.log.odom_poses, plain.log.odom_poses)


def test_truth_round_trip(tmp_path: Path) -> None:
    grid = _room()
    result = overlay_crowd(_log(grid, 10), grid, _busy(), seed=5, preset="busy")
    path = truth_path(tmp_path / "crowded.log.gz")
    assert path.name == "crowded.truth.json"
    write_truth(result.truth, path)
    back = read_truth(path)
    np.testing.assert_array_equal(back.corrupted, result.truth.corrupted)
    np.testing.assert_allclose(back.times, result.truth.times)
    assert back.preset == "busy"
    assert back.seed == 5
    (tmp_path / "bad.json").write_text("{}")
    with pytest.raises(InputError, match=r"bad\.json"):
        read_truth(tmp_path / "bad.json")


def test_longest_stretch_above() -> None:
    grid = _room()
    truth = overlay_crowd(
        _log(grid, 6), grid, OverlayConfig(crowd=CrowdConfig(num_people=0), warmup=0.0)
    ).truth
    truth.corrupted[:] = False
    truth.corrupted[1:4, :120] = True  # scans 1-3 (0.5 to 1.5 s) two-thirds corrupted
    assert truth.longest_above(0.5) == pytest.approx(1.0)
    assert truth.longest_above(0.9) == 0.0


def test_a_log_without_reference_is_refused() -> None:
    grid = _room()
    log = _log(grid, 5)
    bare = RobotLog("bare", [Scan(s.timestamp, s.ranges, s.geometry, odom=s.odom) for s in log.scans])
    with pytest.raises(OverlayError, match="reference"):
        overlay_crowd(bare, grid)


def test_scans_stamped_out_of_order_are_walked_through_with_a_warning() -> None:
    grid = _room()
    log = _log(grid, 12)
    stamps = [s.timestamp for s in log.scans]
    stamps[6] = stamps[5] - 0.3  # as in the Intel log: a scan stamped before the one it follows
    shuffled = RobotLog(
        "shuffled",
        [
            Scan(t, s.ranges, s.geometry, odom=s.odom, reference=s.reference)
            for t, s in zip(stamps, log.scans, strict=True)
        ],
    )
    result = overlay_crowd(shuffled, grid, _busy(), seed=1)
    assert len(result.log.scans) == 12
    assert [s.timestamp for s in result.log.scans] == stamps  # the log keeps its own stamps
    assert np.all(np.diff(result.truth.times) >= 0)  # the crowd's clock never goes back
    assert any("go backwards 1 times" in w for w in result.log.warnings)


def test_crowd_command(tmp_path: Path) -> None:
    grid = _room()
    write_carmen(_log(grid, 10), tmp_path / "in.log.gz")
    write_map(grid, tmp_path / "room.yaml")
    out = tmp_path / "out.log.gz"
    main(
        [
            "crowd",
            str(tmp_path / "in.log.gz"),
            "--map",
            str(tmp_path / "room.yaml"),
            "--preset",
            "peak",
            "--seed",
            "2",
            "-o",
            str(out),
        ]
    )
    crowded = read_carmen(out)
    assert len(crowded) == 10
    truth = read_truth(tmp_path / "out.truth.json")
    assert truth.preset == "peak"
    assert truth.corrupted.shape == (10, 181)
