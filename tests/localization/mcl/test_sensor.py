"""The laser's sensor model: the too-long test, the longest returns, the crowd beam model."""

from __future__ import annotations

import math

import numpy as np

from tourbot.geometry import compose
from tourbot.localization.mcl import MonteCarloLocalization
from tourbot.localization.mcl.sensor import longest_returns
from tourbot.maps.grid import OccupancyGrid

from ..conftest import simulate, waypoints_path
from .conftest import tuned
from .scenes import crowd_around


def test_longest_keeps_the_longest_valid_returns() -> None:
    ranges = np.array([5.0, 1.0, 9.0, 2.0, 50.0, 3.0])
    valid = np.array([True, True, True, True, False, True])
    np.testing.assert_array_equal(
        longest_returns(ranges, valid, 0.4), [True, False, True, False, False, False]
    )
    np.testing.assert_array_equal(longest_returns(ranges, valid, 1.0), valid)
    assert longest_returns(ranges, valid, 0.01).sum() == 1


def test_too_long_readings_judge_a_pose(room: OccupancyGrid) -> None:
    truth = waypoints_path(10)
    crowded = simulate(room, truth, seed=23, circles=crowd_around(truth, np.random.default_rng(23), 6))
    sensor = MonteCarloLocalization(room, tuned(300, 100), seed=24).sensor
    scan = crowded.scans[3]
    r = np.asarray(scan.ranges)
    valid = r < scan.geometry.max_range
    rec = tuned(300, 100).recovery

    def too_long(pose: np.ndarray, ranges: np.ndarray = r) -> float:
        return sensor.too_long_fraction(
            pose[None, :], ranges, scan.geometry, valid, rec.lost_margin, rec.lost_min_beams
        )

    # People shorten beams, never lengthen them: the true pose sees no wall through.
    assert too_long(truth[3]) < 0.1
    # Turned around and moved by a metre, most of the readings pass through walls.
    wrong = compose(truth[3], np.array([0.5, -0.4, 2.7]))
    assert too_long(wrong) > rec.lost_fraction
    # The smallest fraction over the poses counts (any plausible pose of the track explains it).
    both = np.stack([wrong, truth[3]])
    assert sensor.too_long_fraction(both, r, scan.geometry, valid, rec.lost_margin, 20) == too_long(truth[3])
    # A crowd right around a robot in the open (every reading 20 cm, the nearest wall more than
    # a metre away) leaves nothing to judge.
    assert math.isnan(too_long(np.array([2.0, 3.5, 0.0]), np.full_like(r, 0.2)))


def test_the_crowd_model_prefers_the_true_pose(room: OccupancyGrid) -> None:
    truth = waypoints_path(10)
    crowded = simulate(room, truth, seed=25, circles=crowd_around(truth, np.random.default_rng(25), 14))
    sensor = MonteCarloLocalization(room, seed=0).sensor
    scan = crowded.scans[2]
    r = np.asarray(scan.ranges)
    valid = r < scan.geometry.max_range
    poses = np.stack(
        [truth[2], compose(truth[2], np.array([0.5, 0.0, 0.0])), compose(truth[2], np.array([0.0, 0.0, 0.5]))]
    )
    ll = sensor.crowd_log_likelihood(poses, r, scan.geometry, valid)
    assert ll[0] > ll[1]
    assert ll[0] > ll[2]
    assert sensor.crowd_log_likelihood(poses, r, scan.geometry, np.zeros_like(valid)).tolist() == [0.0] * 3


def test_free_space_and_uniform_poses(room: OccupancyGrid) -> None:
    sensor = MonteCarloLocalization(room, seed=0).sensor
    poses = sensor.uniform_free_poses(500, np.random.default_rng(1))
    assert sensor.in_free_space(poses).all()
    assert not sensor.in_free_space(
        np.array([[-50.0, 0.0, 0.0], [-0.95, -1.95, 0.0]])
    ).any()  # off, in a wall
