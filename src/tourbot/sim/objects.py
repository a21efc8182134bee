"""Doors that open and close and furniture that is moved, on a schedule or at random.

The true states of the site's doors and movable furniture (Schulz and Burgard 2001, Sec. 3: the
object-based world model whose states the robot estimates). :meth:`DynamicObjects.grid` draws them
into the static occupancy grid, which the laser casts against and collisions are checked on.
"""

from __future__ import annotations

import math

import numpy as np

from tourbot.maps.grid import OccupancyGrid
from tourbot.runtime.snapshot import DoorState, FurnitureState
from tourbot.site.model import Door, Furniture, Schedule, Site, rasterize_polygons

__all__ = ["DynamicObjects"]

DOOR_SPEED = 0.6  # rad/s: a door pushed open at walking pace
_QUANT = 24  # door positions drawn into the grid (steps from closed to open)


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
        return self._key() != self._drawn_key

    def _key(self) -> tuple[int, ...]:
        doors = tuple(round(float(f) * _QUANT) for f in self.door_open)
        return doors + tuple(int(k) for k in self.furniture_index)

    def grid(self) -> OccupancyGrid:
        """The static grid with the doors and furniture drawn in at their current states."""
        key = self._key()
        if key == self._drawn_key:
            return self._grid
        polys = []
        for door, f in zip(self.doors, self.door_open, strict=True):
            a, b = door.leaf(round(f * _QUANT) / _QUANT)
            polys.append(_thick_segment(a, b, door.thickness))
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


def _thick_segment(a: tuple[float, float], b: tuple[float, float], width: float) -> list[tuple[float, float]]:
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = math.hypot(dx, dy) or 1.0
    ox, oy = -dy / n * width / 2, dx / n * width / 2
    return [(a[0] + ox, a[1] + oy), (b[0] + ox, b[1] + oy), (b[0] - ox, b[1] - oy), (a[0] - ox, a[1] - oy)]
