"""Crowd statistics on made-up trajectories whose answers are known."""

from __future__ import annotations

import numpy as np

from tourbot.io.pedestrians import Trajectories
from tourbot.maps.grid import OccupancyGrid
from tourbot.sim import crowd_stats as cs
from tourbot.sim.crowd import Crowd, CrowdConfig


def _walkers(frames: int = 30) -> Trajectories:
    """Persons 0 and 1 walk side by side at 1 m/s 0.8 m apart; 2 walks the other way far off;
    3 stands until frame 12, then walks."""
    rows: list[tuple[float, float, float, float]] = []
    for k in range(frames):
        x = 0.4 * k
        rows += [(k, 0, x, 0.0), (k, 1, x, 0.8), (k, 2, 20.0 - x, 10.0)]
        rows.append((k, 3, 5.0 + (0.0 if k < 12 else 0.5 * (k - 12)), -6.0))
    a = np.array(rows, dtype=np.float64)
    return Trajectories(a[:, 0].astype(np.int64), a[:, 1].astype(np.int64), a[:, 2:4])


def test_speeds_and_velocities() -> None:
    tr = _walkers()
    v = cs.speeds(tr)
    assert len(v) == 4 * 29
    np.testing.assert_allclose(np.sort(v)[-3 * 29 :][:10], 1.0, atol=1e-9)
    vel = cs.velocities(tr)
    assert not np.isnan(vel).any()  # the last frame takes the backward difference


def test_nearest_neighbours_and_groups() -> None:
    tr = _walkers()
    nn = cs.nearest_neighbour_distances(tr)
    assert len(nn) == 4 * 30
    assert np.sum(np.isclose(nn, 0.8)) == 2 * 30
    sizes = cs.group_sizes(tr)
    assert sorted(sizes.tolist()) == [1, 1, 2]


def test_standing_bouts() -> None:
    tr = _walkers()
    bouts = cs.standing_bouts(tr)
    np.testing.assert_allclose(bouts, [12 * 0.4])  # frames 0-12 at the same place
    assert cs.standing_share(tr) == 12 / (4 * 29)


def test_compare_is_zero_for_the_same_sample() -> None:
    a = np.random.default_rng(0).normal(size=200)
    assert cs.compare(a, a) == (0.0, 0.0)
    w, ks = cs.compare(a, a + 1.0)
    assert abs(w - 1.0) < 1e-9
    assert ks > 0.3


def test_sample_crowd_records_everyone_every_frame() -> None:
    prob = np.zeros((100, 160), dtype=np.float32)
    prob[:2, :] = prob[-2:, :] = prob[:, :2] = prob[:, -2:] = 1.0
    grid = OccupancyGrid(prob, 0.1, (0.0, 0.0, 0.0))
    rng = np.random.default_rng(0)
    crowd = Crowd(CrowdConfig(num_people=8, robot_interest=0.0), grid, rng, (8.0, 5.0, 0.0))
    tr = cs.sample_crowd(crowd, 4.0, rng, (8.0, 5.0, 0.0))
    assert len(tr) == 8 * 10
    assert tr.people == 8
    v = cs.speeds(tr)
    assert v.max() <= CrowdConfig().speed_max + 1e-9
