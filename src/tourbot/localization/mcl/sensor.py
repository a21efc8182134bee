"""The sensor model of Monte Carlo localization: the laser on the map, plus any other likelihood.

The perception step (Fox, Burgard, Dellaert & Thrun 1999, Eq. 2 of Fox et al. 1998) weights every
sample by ``p(s | l)``. For the laser this is the likelihood field (Probabilistic Robotics Table
6.3) of the integrated beams; readings are also judged against ray-cast expected ranges under the
beam model (Probabilistic Robotics Table 6.1) with a "short" part for the crowd, and by the
fraction of readings longer than the map allows (Fox et al. 1998, Sec. 4: "too long readings"),
that is readings that pass through a mapped obstacle: the map's *unknown* cells (free space seen
too rarely to be called free, as in a map built from one log) stop the expected ranges of the
beam model, but a reading through them is no reading through a wall.
Other sensors and object states enter as :class:`PoseLikelihood` objects whose log-likelihoods
are added to the laser's; :meth:`LaserSensorModel.set_map` rebuilds the laser's model for a new
occupancy grid (doors and furniture drawn in their estimated states).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose, invert
from tourbot.localization.errors import LocalizationError
from tourbot.localization.mcl.config import SearchConfig, SensorConfig
from tourbot.localization.range_table import ExpectedRangeTable
from tourbot.maps.beam_model import BeamModel
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.likelihood_field import LikelihoodField
from tourbot.maps.raycast import DistanceCaster, RayCaster
from tourbot.records import LaserGeometry

__all__ = ["LaserSensorModel", "PoseLikelihood", "longest_returns"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


@runtime_checkable
class PoseLikelihood(Protocol):
    """A likelihood ``log p(z | pose)`` of the latest measurement the object holds (a ceiling
    camera's sighting, a door's observed state, ...), for poses ``(N, 3)``: ``(N,)`` log values.
    Monte Carlo localization adds it to the laser's log weights in every perception step."""

    def log_likelihood(self, poses: FloatArray) -> FloatArray: ...


def longest_returns(ranges: FloatArray, valid: BoolArray, fraction: float) -> BoolArray:
    """The ``fraction`` longest of the ``valid`` returns: people only ever shorten a beam, so in a
    crowd the longest readings are the ones most likely to see the building."""
    k = int(valid.sum())
    keep = max(1, math.ceil(fraction * k))
    if keep >= k:
        return valid
    cut = np.sort(ranges[valid])[k - keep]
    return valid & (ranges >= cut)


class LaserSensorModel:
    """The laser's models on one occupancy grid, built lazily once per laser range.

    ``crowd`` is the beam model that judges poses with ray-cast expected ranges."""

    def __init__(self, grid: OccupancyGrid, config: SensorConfig, crowd: BeamModel) -> None:
        self.config = config
        self.crowd = crowd
        self.set_map(grid)

    def set_map(self, grid: OccupancyGrid) -> None:
        """Use ``grid`` from now on: the likelihood fields, casters and tables are rebuilt."""
        free = grid.free()
        if not free.any():
            raise LocalizationError("the map has no free cell to localize in")
        self.grid = grid
        self.free = free
        self.free_cells: IntArray = np.argwhere(free)
        self._fields: dict[float, LikelihoodField] = {}
        self._casters: dict[float, RayCaster] = {}
        self._wall_casters: dict[float, RayCaster] = {}
        self._tables: dict[tuple[float, float, int], ExpectedRangeTable] = {}

    # ------------------------------------------------------------------ models

    def field(self, geometry: LaserGeometry) -> LikelihoodField:
        """The likelihood field for this laser's maximum range."""
        key = float(geometry.max_range)
        f = self._fields.get(key)
        if f is None:
            f = LikelihoodField.from_grid(self.grid, replace(self.config.field, max_range=key))
            self._fields[key] = f
        return f

    def caster(self, max_range: float) -> RayCaster:
        """The project's ray caster for expected ranges up to ``max_range``."""
        c = self._casters.get(max_range)
        if c is None:
            c = DistanceCaster(self.grid, max_range)
            self._casters[max_range] = c
        return c

    def wall_caster(self, max_range: float) -> RayCaster:
        """The project's ray caster stopped by occupied cells only (unknown cells let rays pass),
        for ranges up to ``max_range``: how far a reading may reach before it is through a wall."""
        c = self._wall_casters.get(max_range)
        if c is None:
            c = DistanceCaster(self.grid, max_range, unknown_blocks=False)
            self._wall_casters[max_range] = c
        return c

    def table(self, max_range: float, spacing: float, directions: int) -> ExpectedRangeTable:
        """The expected-range table of a ``spacing`` lattice over the free space."""
        key = (max_range, spacing, directions)
        t = self._tables.get(key)
        if t is None:
            t = ExpectedRangeTable.on_lattice(self.grid, self.caster(max_range), spacing, directions)
            self._tables[key] = t
        return t

    # ------------------------------------------------------------------ judging poses

    def crowd_log_likelihood(
        self, poses: FloatArray, ranges: FloatArray, geometry: LaserGeometry, beams: BoolArray
    ) -> FloatArray:
        """The scan's log-likelihood per pose under the crowd beam model with expected ranges ray
        cast in the map (Fox et al. 1998 Sec. 2.3; Probabilistic Robotics Table 6.1): visitors
        only shorten a beam, a reading through a mapped wall only has the small "random" part."""
        idx = np.flatnonzero(beams)
        if idx.size == 0 or poses.shape[0] == 0:
            return np.zeros(poses.shape[0])
        laser = compose(poses, np.asarray(geometry.offset, dtype=np.float64))
        expected = self.caster(float(geometry.max_range)).cast(laser, geometry.angles[idx])
        return self.crowd.log_likelihood(expected, ranges[idx], float(geometry.max_range))

    def too_long_fraction(
        self,
        poses: FloatArray,
        ranges: FloatArray,
        geometry: LaserGeometry,
        valid: BoolArray,
        margin: float,
        min_beams: int,
    ) -> float:
        """Of the returns not shorter than expected, the fraction longer than expected by more
        than ``margin`` (readings through mapped walls), the smallest over ``poses`` ``(K, 3)``;
        NaN when every pose has fewer than ``min_beams`` such returns.

        Expected here is the range to the first *occupied* cell (:meth:`wall_caster`): a reading
        that only crosses unknown cells passes through no mapped wall. (With unknown cells
        blocking, as the beam model's casts do, a correct pose on the FHW log found up to 41 % of
        its readings "too long" where the reference map had seen the free space only 1-3 times,
        and the track was dropped for a far guess.)"""
        if not valid.any():
            return math.nan
        laser = compose(poses, np.asarray(geometry.offset, dtype=np.float64))
        expected = self.wall_caster(float(geometry.max_range)).cast(laser, geometry.angles[valid])
        measured = ranges[valid][None, :]
        longer = measured > expected + margin
        n_seen = (longer | (measured >= expected - margin)).sum(axis=1)
        judged = n_seen >= min_beams
        if not judged.any():
            return math.nan
        return float(np.min(longer.sum(axis=1)[judged] / n_seen[judged]))

    def table_poses(
        self, ranges: FloatArray, geometry: LaserGeometry, valid: BoolArray, search: SearchConfig
    ) -> FloatArray:
        """The ``table_survivors`` best robot poses of the expected-range table's lattice by the
        crowd beam model of ``table_beams`` returns spread evenly over the scan."""
        idx = np.flatnonzero(valid)
        if search.table_survivors <= 0 or idx.size == 0:
            return np.zeros((0, 3))
        table = self.table(float(geometry.max_range), search.table_spacing, search.table_directions)
        pick = np.round(np.linspace(0, idx.size - 1, min(search.table_beams, idx.size))).astype(np.int64)
        idx = idx[np.unique(pick)]
        laser, _ = table.screen(ranges[idx], geometry.angles[idx], self.crowd, search.table_survivors)
        return compose(laser, invert(np.asarray(geometry.offset, dtype=np.float64)))

    # ------------------------------------------------------------------ the free space

    def in_free_space(self, poses: FloatArray) -> BoolArray:
        """Whether each pose ``(N, 3)`` lies in a free cell of the map."""
        rc = self.grid.world_to_cell(poses[:, :2])
        inside = self.grid.inside(rc)
        out = np.zeros(poses.shape[0], dtype=bool)
        out[inside] = self.free[rc[inside, 0], rc[inside, 1]]
        return out

    def uniform_free_poses(self, n: int, rng: np.random.Generator) -> FloatArray:
        """``n`` poses uniform over the free cells (uniform inside each cell, uniform heading)."""
        return uniform_free_poses(self.grid, self.free_cells, n, rng)


def uniform_free_poses(grid: OccupancyGrid, cells: IntArray, n: int, rng: np.random.Generator) -> FloatArray:
    """``n`` poses uniform over the free ``cells`` of ``grid`` (uniform heading)."""
    pick = cells[rng.integers(0, cells.shape[0], n)]
    local = (pick[:, ::-1] + rng.random((n, 2))) * grid.resolution  # (col, row) -> (x, y)
    th = rng.uniform(-math.pi, math.pi, n)
    return grid.grid_to_world(np.column_stack([local, th - grid.origin[2]]))
