"""The simulated 2D laser: ray cast with the project's one ray caster against the world and legs.

The laser sits at about 40 cm above the floor (``DiffDriveConfig.laser_height``): it sees walls,
door leaves, furniture and people's legs, but not low tables or glass cases (the site's invisible
obstacles). Walls come from the static grid's cast, door leaves and furniture from their outlines'
edges (:func:`tourbot.maps.objects.segment_ranges`, the estimator's sensor simulation), legs as
circles. Ranges get Gaussian noise; beams without a return read ``max_range``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import LaserGeometry

__all__ = ["LaserConfig", "SimLaser"]


@dataclass(frozen=True)
class LaserConfig:
    """Beam layout and noise. Default: 360 beams over the full circle (1 degree apart).

    ``fov`` is the angle from the first to the last beam plus one increment (``2 pi`` for a full
    circle, ``pi`` with 181 beams for a SICK LMS-like front laser when ``num_beams`` is odd).
    ``sigma`` is the range noise (m), ``dropout`` the chance a beam returns nothing.
    """

    num_beams: int = 360
    fov: float = 2.0 * math.pi
    max_range: float = 20.0
    sigma: float = 0.01
    dropout: float = 0.002

    def __post_init__(self) -> None:
        if self.num_beams < 1 or not self.max_range > 0 or not 0 < self.fov <= 2 * math.pi:
            raise ValueError("LaserConfig needs num_beams >= 1, max_range > 0 and 0 < fov <= 2 pi")

    def geometry(self) -> LaserGeometry:
        full = abs(self.fov - 2 * math.pi) < 1e-9
        inc = self.fov / self.num_beams if full else self.fov / max(self.num_beams - 1, 1)
        start = -math.pi if full else -self.fov / 2
        return LaserGeometry(
            num_beams=self.num_beams, angle_min=start, angle_increment=inc, max_range=self.max_range
        )


class SimLaser:
    """Casts scans from the true robot pose; :meth:`set_world` after the static grid changes."""

    def __init__(self, config: LaserConfig, grid: OccupancyGrid) -> None:
        self.config = config
        self.geometry = config.geometry()
        self._angles = self.geometry.angles
        self.last_person_hits: NDArray[np.bool_] = np.zeros(config.num_beams, dtype=bool)
        self.set_world(grid)

    def set_world(self, grid: OccupancyGrid) -> None:
        # The distance-transform caster gives the exact DDA ranges several times faster; doors,
        # furniture (edges) and legs (circles) are cast separately, so it is never rebuilt for them.
        from tourbot.maps.raycast import DistanceCaster

        self._caster = DistanceCaster(grid, self.config.max_range)

    def scan(
        self,
        robot_pose: tuple[float, float, float],
        circles_xy: NDArray[np.float64],
        radii: NDArray[np.float64],
        rng: np.random.Generator,
        people: int = 0,
        segments: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64]:
        """One scan ``(num_beams,)`` from the robot at ``robot_pose`` among circles (legs) and the
        edges ``segments`` ``(1, M, 4)`` of doors and furniture.

        The first ``people`` circles are people's legs: :attr:`last_person_hits` then tells which
        beams of this scan returned from a person (ground truth for metrics, e.g. people-filtered
        mapping); the ranges are the same whatever ``people`` is.
        """
        laser_pose = compose(np.asarray(robot_pose, dtype=np.float64), np.asarray(self.geometry.offset))
        poses = laser_pose[None, :]
        c = np.asarray(circles_xy, dtype=np.float64).reshape(-1, 2)
        rad = np.asarray(radii, dtype=np.float64).ravel()
        cast = self._caster.cast_with_circles(poses, self._angles, c[people:], rad[people:])
        if segments is not None and segments.shape[1]:
            from tourbot.maps.objects import segment_ranges

            cast = segment_ranges(poses, self._angles, segments, cast)[:, 0, :]
        without_people = cast[0].copy()
        self._caster.lower_to_circles(cast, poses, self._angles, c[:people], rad[:people])
        r = cast[0].astype(np.float64)
        hit = r < self.config.max_range
        r = r + self.config.sigma * rng.standard_normal(r.shape[0])
        r = np.where(hit, np.clip(r, 0.0, self.config.max_range), self.config.max_range)
        if self.config.dropout > 0:
            r[rng.random(r.shape[0]) < self.config.dropout] = self.config.max_range
        self.last_person_hits = (cast[0] < without_people) & (r < self.config.max_range)
        return r
