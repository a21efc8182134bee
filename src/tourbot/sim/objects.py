"""Doors that open and close and furniture that is moved, on a schedule or at random.

The true states of the site's doors and movable furniture (Schulz and Burgard 2001, Sec. 3: the
object-based world model whose states the robot estimates). Furniture moves rarely and at once:
:meth:`DynamicObjects.grid` draws it into the static occupancy grid (the laser's caster is rebuilt
then). Door leaves swing continuously, so they are given to the ray caster as a chain of small
circles along the leaf (:meth:`DynamicObjects.door_circles`), like people's legs: the one caster's
grid-plus-circles cast, with no rebuild while a door moves.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from tourbot.maps.grid import OccupancyGrid
from tourbot.site.model import Door, Furniture, Schedule, Site, rasterize_polygons
from tourbot.snapshot import DoorState, FurnitureState

__all__ = ["DynamicObjects"]

DOOR_SPEED = 0.6  # rad/s: a door pushed open at walking pace


class DynamicObjects:
    """Doors and furniture of a site, changing over time; deterministic for the generator given."""

    def __init__(self, site: Site, static: OccupancyGrid, rng: np.random.Generator, enabled: bool = True):
        self.site = site
        self.static = static
        self.enabled = enabled
        self.doors: list[Door] = list(site.doors)
        self.furniture: list[Furniture] = list(site.furniture)
        self.door_open = np.array([1.0 if d.schedule.start_open else 0.0 for d in self.doors])
        self.door_target = self.door_open.copy()
        self.furniture_index = np.zeros(len(self.furniture), dtype=np.int64)
        self._door_next = np.array([self._interval(d.schedule, rng) for d in self.doors])
        self._furniture_next = np.array([self._interval(f.schedule, rng) for f in self.furniture])
        self._drawn_key: tuple[int, ...] | None = None
        self._grid = static
        self._circles_key: tuple[float, ...] | None = None
        self._circles: tuple[NDArray[np.float64], NDArray[np.float64]] = (np.zeros((0, 2)), np.zeros(0))

    @staticmethod
    def _interval(schedule: Schedule, rng: np.random.Generator) -> float:
        return float(rng.exponential(schedule.period)) if schedule.random else schedule.period

    def step(self, time: float, dt: float, rng: np.random.Generator) -> bool:
        """Advance to ``time``; True when the grid must be redrawn."""
        if not self.enabled:
            return False
        for i, door in enumerate(self.doors):
            if time >= self._door_next[i]:
                self.door_target[i] = 1.0 - self.door_target[i]
                self._door_next[i] = time + self._interval(door.schedule, rng)
            rate = DOOR_SPEED * dt / max(abs(door.opening_angle), 1e-6)
            delta = self.door_target[i] - self.door_open[i]
            self.door_open[i] += math.copysign(min(abs(delta), rate), delta)
        for j, item in enumerate(self.furniture):
            if time >= self._furniture_next[j] and len(item.poses) > 1:
                choices = [k for k in range(len(item.poses)) if k != self.furniture_index[j]]
                self.furniture_index[j] = choices[int(rng.integers(len(choices)))]
                self._furniture_next[j] = time + self._interval(item.schedule, rng)
        return self._key() != self._drawn_key  # doors need no redraw: they are circles

    def _key(self) -> tuple[int, ...]:
        return tuple(int(k) for k in self.furniture_index)

    def door_circles(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Door leaves as chains of circles (centres ``(K, 2)``, radii ``(K,)``) of the leaf's
        thickness, overlapping so no beam slips between them."""
        key = tuple(float(f) for f in self.door_open)
        if self._circles_key == key:
            return self._circles
        centres, radii = [], []
        for door, f in zip(self.doors, self.door_open, strict=True):
            (x0, y0), (x1, y1) = door.leaf(float(f))
            r = door.thickness / 2
            n = max(2, math.ceil(door.leaf_length / r) + 1)
            t = np.linspace(0.0, 1.0, n)
            centres.append(np.stack([x0 + t * (x1 - x0), y0 + t * (y1 - y0)], axis=-1))
            radii.append(np.full(n, r))
        self._circles_key = key
        if not centres:
            self._circles = (np.zeros((0, 2)), np.zeros(0))
        else:
            self._circles = (np.vstack(centres), np.concatenate(radii))
        return self._circles

    def grid(self) -> OccupancyGrid:
        """The static grid with the furniture drawn in at its current poses."""
        key = self._key()
        if key == self._drawn_key:
            return self._grid
        polys = []
        for item, k in zip(self.furniture, self.furniture_index, strict=True):
            polys.append(item.polygon(item.poses[int(k)]))
        prob = self.static.prob.copy()
        if polys:
            prob[rasterize_polygons(self.static, polys)] = 1.0
        g = self.static
        self._grid = OccupancyGrid(prob, g.resolution, g.origin, g.occupied_thresh, g.free_thresh)
        self._drawn_key = key
        return self._grid

    def door_states(self) -> tuple[DoorState, ...]:
        return tuple(
            DoorState(d.name, float(f * d.opening_angle), float(f))
            for d, f in zip(self.doors, self.door_open, strict=True)
        )

    def furniture_states(self) -> tuple[FurnitureState, ...]:
        out = []
        for item, k in zip(self.furniture, self.furniture_index, strict=True):
            x, y, th = item.poses[int(k)]
            out.append(FurnitureState(item.name, x, y, th))
        return tuple(out)
