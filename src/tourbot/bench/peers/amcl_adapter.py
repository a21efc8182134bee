"""Nav2 AMCL (the PyPI package ``amcl``: Python bindings of Nav2's AMCL C++ core) behind tourbot's
localizer interface, for ``tourbot bench localization``.

Configuration: Nav2's defaults (``nav2_amcl`` parameters: ``alpha1..5`` 0.2, ``z_hit`` 0.5,
``z_short`` 0.05, ``z_max`` 0.05, ``z_rand`` 0.5, ``sigma_hit`` 0.2, ``lambda_short`` 0.1,
``max_beams`` 60, ``min_particles`` 500, ``max_particles`` 2000, ``pf_err`` 0.05, ``pf_z`` 0.99),
with this documented tuning so that the comparison is fair:

- ``max_particles`` is the benchmark's sample budget (5000, as for tourbot's MCL), ``min_particles``
  stays 500 (KLD-sampling adapts the count between them in both);
- ``recovery_alpha_slow`` 0.001 / ``recovery_alpha_fast`` 0.1 instead of Nav2's 0.0 / 0.0: with
  Nav2's defaults AMCL never injects random particles, so it could not recover from a kidnap at
  all; these are the values the ROS ``amcl`` documentation suggests;
- ``chi_outlier`` 0.0, as Nav2 builds its beam model.

What the binding (version 0.1.2) does differently from Nav2, found by reading its source and
checked on synthetic cases in ``tests/bench/test_amcl_adapter.py``:

1. it offers only the *beam* sensor model (Nav2's default is ``likelihood_field``), so AMCL here
   ray casts every beam of every particle;
2. its pose is the mean of *all* particles, not of the heaviest cluster as Nav2 publishes; with two
   hypotheses the reported pose lies between them (shown by the tests);
3. there is no global-localization call (Nav2's ``reinitialize_global_localization`` service):
   a uniform start is approximated by a Gaussian over the whole map (:meth:`AMCLLocalizer.reset_global`);
4. it filters every scan (no ``update_min_d`` / ``update_min_a`` gating; the museum logs' scans
   are ~0.8 m apart, so Nav2 would filter them all anyway);
5. its random numbers come from ``std::random_device`` and ``drand48`` unseeded, so runs cannot be
   repeated exactly: the benchmark's seeds only fix the crowd and the kidnaps for AMCL.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from tourbot.errors import TourbotError
from tourbot.localization.estimate import LocalizationEstimate
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import Scan

__all__ = ["AMCLLocalizer", "AMCLParams", "PeerError", "amcl_available"]


class PeerError(TourbotError):
    """A peer that is not installed or refuses its input."""


def amcl_available() -> bool:
    """Whether the ``amcl`` package imports."""
    try:
        import amcl  # noqa: F401
    except ImportError:
        return False
    return True


@dataclass(frozen=True)
class AMCLParams:
    """Nav2 AMCL's parameters (defaults from ``nav2_amcl``; tuning in the module docstring)."""

    min_particles: int = 500
    max_particles: int = 5000
    alpha_slow: float = 0.001
    alpha_fast: float = 0.1
    alpha1: float = 0.2
    alpha2: float = 0.2
    alpha3: float = 0.2
    alpha4: float = 0.2
    alpha5: float = 0.2
    z_hit: float = 0.5
    z_short: float = 0.05
    z_max: float = 0.05
    z_rand: float = 0.5
    sigma_hit: float = 0.2
    lambda_short: float = 0.1
    chi_outlier: float = 0.0
    max_beams: int = 60
    laser_likelihood_max_dist: float = 2.0
    robot_model: str = "differential"
    tracking_std: tuple[float, float, float] = (0.1, 0.1, math.radians(5.0))


def _import_amcl() -> Any:
    try:
        import amcl
    except ImportError as exc:
        raise PeerError("the Nav2 AMCL peer is not installed: pip install amcl (or tourbot[peers])") from exc
    return amcl


class AMCLLocalizer:
    """Nav2 AMCL with tourbot's localizer interface: ``reset_tracking``, ``reset_global``, ``update``."""

    def __init__(self, grid: OccupancyGrid, params: AMCLParams | None = None) -> None:
        self.params = p = params or AMCLParams()
        self._amcl = _import_amcl()
        a = self._amcl
        motion = a.MotionParameters(p.alpha1, p.alpha2, p.alpha3, p.alpha4, p.alpha5)
        laser = a.LaserParameters(
            p.z_hit, p.z_short, p.z_max, p.z_rand, p.sigma_hit, p.lambda_short, p.chi_outlier, p.max_beams
        )
        args: list[Any] = [p.min_particles, p.max_particles, p.alpha_slow, p.alpha_fast, motion]
        try:  # the binding's signature changed between releases (laser_likelihood_max_dist)
            self._pf = a.AMCL(*args, laser, p.robot_model)
        except TypeError:
            self._pf = a.AMCL(*args, p.laser_likelihood_max_dist, laser, p.robot_model)
        if abs(grid.origin[2]) > 1e-9:
            raise PeerError("AMCL needs a map whose origin is not rotated")
        self.grid = grid
        rows, cols = grid.shape
        m = a.OccupancyGrid(cols, rows, grid.resolution, grid.origin[0], grid.origin[1])
        cells = np.full(grid.prob.shape, -1, dtype=np.int8)
        cells[grid.free()] = 0
        cells[grid.occupied()] = 100
        m.data = cells.ravel().tolist()
        self._pf.set_map(m)
        self._laser_offset: tuple[float, float, float] | None = None

    def _vec(self, pose: ArrayLike) -> Any:
        x, y, th = (float(v) for v in np.asarray(pose, dtype=np.float64).reshape(3))
        return self._amcl.Vector3D(x, y, th)

    def _cov(self, sx: float, sy: float, sth: float) -> Any:
        return self._amcl.create_diagonal_covariance(sx * sx, sy * sy, sth * sth)

    def reset_tracking(self, pose: ArrayLike, cov: ArrayLike | None = None) -> None:
        """Particles from a Gaussian around ``pose`` (``tracking_std`` unless ``cov`` is given)."""
        if cov is None:
            sx, sy, sth = self.params.tracking_std
        else:
            c = np.asarray(cov, dtype=np.float64)
            sx, sy, sth = (math.sqrt(float(c[i, i])) for i in range(3))
        self._pf.set_initial_pose(self._vec(pose), self._cov(sx, sy, sth))

    def reset_global(self) -> None:
        """The binding has no uniform initialisation: a Gaussian centred on the map's free space,
        one standard deviation spanning half of it, with a uniform-like heading spread."""
        free = self.grid.free_cell_centres()
        centre = free.mean(axis=0)
        spread = free.std(axis=0)
        self._pf.set_initial_pose(
            self._vec((centre[0], centre[1], 0.0)), self._cov(float(spread[0]), float(spread[1]), math.pi)
        )

    def update(self, odom_pose: ArrayLike, scan: Scan) -> LocalizationEstimate:
        t0 = time.perf_counter()
        g = scan.geometry
        if self._laser_offset != g.offset:
            self._pf.set_laser_pose(self._vec(g.offset))
            self._laser_offset = g.offset
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        ranges = np.where(np.isfinite(ranges), np.minimum(ranges, g.max_range), g.max_range)
        pairs = np.stack([ranges, g.angles], axis=-1).tolist()
        laser_scan = self._amcl.create_laser_scan_from_list(pairs, float(g.max_range))
        self._pf.update(laser_scan, self._vec(odom_pose))
        mean = self._pf.get_pose_mean()
        cov = np.array(self._pf.get_pose_covariance().to_list(), dtype=np.float64)
        used = np.zeros(g.num_beams, dtype=bool)
        step = max(1, (g.num_beams - 1) // max(1, self.params.max_beams - 1))
        used[::step] = True  # the beams AMCL's beam model integrates (every step-th)
        return LocalizationEstimate(
            timestamp=scan.timestamp,
            pose=np.array([mean.x, mean.y, mean.theta], dtype=np.float64),
            covariance=cov,
            used_beams=used,
            n_samples=self.params.max_particles,
            updated=True,
            update_seconds=time.perf_counter() - t0,
        )
