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
from .scenes import crowd_around, rarely_seen


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


def test_a_reading_through_rarely_seen_free_space_is_not_too_long(room: OccupancyGrid) -> None:
    # issue 22, FHW seed 4: where the map from the log had seen the free space only a few times
    # (unknown cells), a correct track found 31-41 % of its readings "through walls", three scans
    # in a row, and was dropped for a guess 16 m away. Only occupied cells are walls.
    truth = waypoints_path(10)
    crowded = simulate(room, truth, seed=23, circles=crowd_around(truth, np.random.default_rng(23), 6))
    seen = rarely_seen(room, 9.0, 5.6)
    sensor = MonteCarloLocalization(seen, tuned(300, 100), seed=24).sensor
    rec = tuned(300, 100).recovery
    scan = crowded.scans[0]  # at the oval's right end, facing the unknown corner
    r = np.asarray(scan.ranges)
    valid = r < scan.geometry.max_range

    def too_long(pose: np.ndarray) -> float:
        return sensor.too_long_fraction(
            pose[None, :], r, scan.geometry, valid, rec.lost_margin, rec.lost_min_beams
        )

    # The beam model's casts stop at the unknown cells: most readings reach beyond them ...
    cast = sensor.caster(float(scan.geometry.max_range)).cast(truth[:1], scan.geometry.angles[valid])[0]
    assert np.mean(r[valid] > cast + rec.lost_margin) > rec.lost_fraction
    # ... but through no wall: the true pose passes, a wrong one still fails.
    assert too_long(truth[0]) < 0.05
    assert too_long(compose(truth[0], np.array([0.5, -0.4, 2.7]))) > rec.lost_fraction


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
