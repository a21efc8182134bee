"""The expected-range table: its screening kernel against the numpy reference, finding a pose, files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from tourbot.geometry import compose, wrap_angle
from tourbot.localization.errors import LocalizationError
from tourbot.localization.mcl import MCLConfig, MonteCarloLocalization, SearchConfig
from tourbot.localization.range_table import ExpectedRangeTable, best_headings, best_headings_reference
from tourbot.maps.raycast import DistanceCaster
from tourbot.records import LaserGeometry

from .conftest import room_with_boxes


@st.composite
def _tables(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n_pos = draw(st.integers(1, 6))
    n_dir = draw(st.integers(1, 12))
    n_beams = draw(st.integers(1, 5))
    n_q = draw(st.integers(1, 9))
    table = draw(arrays(np.uint16, (n_pos, n_dir), elements=st.integers(0, n_q - 1)))
    offsets = draw(arrays(np.int64, n_beams, elements=st.integers(-30, 30)))
    loglik = draw(arrays(np.float64, (n_beams, n_q), elements=st.floats(-20.0, 2.0, width=32)))
    return table, offsets, loglik


@settings(max_examples=200, deadline=None)
@given(_tables())
def test_best_headings_kernel_matches_reference(case: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    table, offsets, loglik = case
    score, heading = best_headings(table, offsets, loglik)
    ref_score, _ = best_headings_reference(table, offsets, loglik)
    np.testing.assert_allclose(score, ref_score, rtol=1e-5, atol=1e-3)
    # the kernel's heading scores (by the reference's sums) as well as the reference's best
    n_dir = table.shape[1]
    for p in range(table.shape[0]):
        cols = (heading[p] + offsets % n_dir) % n_dir
        s = float(loglik[np.arange(offsets.size), table[p, cols]].sum())
        assert s >= ref_score[p] - 1e-3


def test_screen_finds_the_pose_that_took_the_scan() -> None:
    grid = room_with_boxes()
    geometry = LaserGeometry(
        num_beams=90, angle_min=-math.pi, angle_increment=math.radians(4.0), max_range=20.0
    )
    caster = DistanceCaster(grid, geometry.max_range)
    table = ExpectedRangeTable.on_lattice(grid, caster, spacing=0.25, directions=90)
    model = MCLConfig().recovery.model
    for truth in ([2.1, 3.3, 0.7], [8.6, 0.4, -2.0], [4.4, 1.0, 2.9]):
        laser = np.asarray(truth)[None, :]
        ranges = caster.cast(laser, geometry.angles)[0].astype(np.float64)
        ranges[10:25] = np.minimum(ranges[10:25], 0.8)  # a visitor in front of some beams
        poses, scores = table.screen(ranges, geometry.angles, model, 5)
        assert poses.shape == (5, 3)
        assert np.all(np.diff(scores) <= 0)
        assert math.hypot(poses[0, 0] - truth[0], poses[0, 1] - truth[1]) < 0.25
        assert abs(float(wrap_angle(poses[0, 2] - truth[2]))) < math.radians(4.0)


def test_table_poses_are_robot_poses_for_an_offset_laser() -> None:
    grid = room_with_boxes()
    offset = (0.2, 0.0, math.pi / 2)
    geometry = LaserGeometry(
        num_beams=90, angle_min=-math.pi, angle_increment=math.radians(4.0), max_range=20.0, offset=offset
    )
    search = SearchConfig(table_survivors=3, table_beams=45)
    sensor = MonteCarloLocalization(grid, seed=0).sensor
    truth = np.array([6.3, 0.9, -0.6])
    laser = compose(truth[None, :], np.asarray(offset))
    ranges = DistanceCaster(grid, geometry.max_range).cast(laser, geometry.angles)[0].astype(np.float64)
    poses = sensor.table_poses(ranges, geometry, np.ones(90, dtype=bool), search)
    assert poses.shape == (3, 3)
    assert math.hypot(poses[0, 0] - truth[0], poses[0, 1] - truth[1]) < 0.3
    assert abs(float(wrap_angle(poses[0, 2] - truth[2]))) < math.radians(4.0)
    assert sensor.table_poses(ranges, geometry, np.zeros(90, dtype=bool), search).shape == (0, 3)


def test_a_saved_table_reads_back_and_a_foreign_file_is_refused(tmp_path: Path) -> None:
    grid = room_with_boxes()
    table = ExpectedRangeTable.on_lattice(grid, DistanceCaster(grid, 10.0), spacing=1.0, directions=8)
    assert table.bins.shape[1] == 8
    assert table.n_bins == 201
    table.save(tmp_path / "t.npz")
    back = ExpectedRangeTable.load(tmp_path / "t.npz")
    np.testing.assert_array_equal(back.bins, table.bins)
    assert (back.angle_step, back.range_bin, back.max_range) == (table.angle_step, 0.05, 10.0)
    with pytest.raises(LocalizationError, match="does not know its positions"):
        back.screen(np.ones(3), np.zeros(3), MCLConfig().recovery.model, 2)
    (tmp_path / "bad.npz").write_bytes(b"not a table")
    with pytest.raises(LocalizationError, match="not an expected-range table"):
        ExpectedRangeTable.load(tmp_path / "bad.npz")
