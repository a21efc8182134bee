"""The Nav2 AMCL peer through its Python binding, on synthetic rooms: it tracks and, from the
adapter's stand-in for a uniform start, localizes globally."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tourbot.bench.peers.amcl_adapter import AMCLLocalizer, AMCLParams, amcl_available
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.raycast import DDACaster
from tourbot.records import LaserGeometry, Scan

pytestmark = pytest.mark.skipif(not amcl_available(), reason="the amcl peer is not installed")

GEOMETRY = LaserGeometry(181, -math.pi / 2, math.pi / 180, 30.0)


def _room(stub: bool) -> OccupancyGrid:
    prob = np.zeros((100, 160), dtype=np.float32)  # 16 x 10 m at 10 cm
    prob[:2, :] = prob[-2:, :] = prob[:, :2] = prob[:, -2:] = 1.0
    if stub:
        prob[60:98, 40:44] = 1.0  # breaks the room's symmetry
    return OccupancyGrid(prob, 0.1)


def _drive(grid: OccupancyGrid, n: int, start: str) -> tuple[np.ndarray, np.ndarray]:
    poses = np.array([(3.0 + 0.1 * i, 3.0 + 0.05 * i, 0.3) for i in range(n)])
    ranges = DDACaster(grid, GEOMETRY.max_range).cast(poses, GEOMETRY.angles).astype(np.float64)
    amcl = AMCLLocalizer(grid, AMCLParams(max_particles=3000))
    if start == "global":
        amcl.reset_global()
    else:
        amcl.reset_tracking(poses[0])
    est = np.array([amcl.update(poses[i], Scan(0.5 * i, ranges[i], GEOMETRY)).pose for i in range(n)])
    return poses, est


def test_amcl_tracks_in_a_room() -> None:
    poses, est = _drive(_room(stub=True), 20, "tracking")
    assert np.hypot(*(est[:, :2] - poses[:, :2]).T).max() < 0.15


def test_amcl_global_start_in_an_asymmetric_room() -> None:
    """The binding has no uniform start; the adapter's broad Gaussian over the free space still
    lets AMCL find itself in a room whose wall stub makes the pose unique. AMCL cannot be seeded
    (the binding draws from std::random_device), and one run in a few stays split between
    hypotheses, so it gets three tries."""
    finals = []
    for _ in range(3):
        poses, est = _drive(_room(stub=True), 60, "global")
        err = np.hypot(*(est[:, :2] - poses[:, :2]).T)
        assert err[0] > 0.45  # it did start lost
        finals.append(float(np.median(err[-10:])))
        if finals[-1] < 0.45:  # localized in the paper's sense
            return
    pytest.fail(f"AMCL never localized globally in 3 tries: final errors {finals}")


def test_amcl_runs_cannot_be_repeated_even_with_drand48_seeded() -> None:
    """Why the benchmark's seeds fix only the crowd and the kidnaps for AMCL: the binding has no
    seed, and seeding the C library's ``drand48`` (which Nav2's particle filter also uses) right
    before the same run does not repeat it, because the binding also draws from
    ``std::random_device``. Should a later binding become repeatable, this fails: seed it then."""
    import ctypes

    libc = ctypes.CDLL(None)
    if not hasattr(libc, "srand48"):
        pytest.skip("no srand48 in this C library")
    grid = _room(stub=True)
    poses = np.array([(3.0 + 0.1 * i, 3.0 + 0.05 * i, 0.3) for i in range(10)])
    ranges = DDACaster(grid, GEOMETRY.max_range).cast(poses, GEOMETRY.angles).astype(np.float64)

    def run() -> np.ndarray:
        amcl = AMCLLocalizer(grid, AMCLParams(max_particles=1000))
        libc.srand48(ctypes.c_long(7))
        amcl.reset_tracking(poses[0])
        return np.array([amcl.update(poses[i], Scan(0.5 * i, ranges[i], GEOMETRY)).pose for i in range(10)])

    first, second = run(), run()
    assert np.isfinite(first).all()
    assert not np.array_equal(first, second)
