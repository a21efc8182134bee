"""Doors that open and close and furniture that is moved, on a schedule or at random.

The true states of the site's doors and movable furniture (Schulz and Burgard 2001, Sec. 3: the
object-based world model whose states the robot estimates). Every object is an
:class:`tourbot.maps.objects.ObjectShape`, the geometry the estimator uses too: the laser sees the
outlines' edges exactly (:meth:`DynamicObjects.segments`, cast by
:func:`tourbot.maps.objects.segment_ranges` over the static map's ranges), so a swinging door or
a moved desk needs no rebuild of the caster. :meth:`DynamicObjects.grid` draws the furniture into
the static occupancy grid for what needs cells (collisions, the drawn world).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.objects import ObjectShape, shapes_of_site
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
        self.shapes: list[ObjectShape] = shapes_of_site(self.doors, self.furniture)
        self._segments_key: tuple[float, ...] | None = None
        self._segments: NDArray[np.float64] = np.zeros((1, 0, 4))

    @staticmethod
    def _interval(schedule: Schedule, rng: np.random.Generator) -> float:
        return float(rng.exponential(schedule.period)) if schedule.random else schedule.period

    def step(self, time: float, dt: float, rng: np.random.Generator) -> bool:
        """Advance to ``time``; True when the grid must be redrawn."""
        if not self.enabled:
            return self._key() != self._drawn_key  # states set by hand (:meth:`set_states`)
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

    def set_states(
        self, door_fractions: dict[int, float] | None = None, furniture_poses: dict[int, int] | None = None
    ) -> None:
        """Put doors at opening fractions and furniture at one of its site poses now (a scripted
        scene; with ``enabled=False`` nothing else changes them)."""
        for i, f in (door_fractions or {}).items():
            self.door_open[i] = self.door_target[i] = float(np.clip(f, 0.0, 1.0))
        for j, k in (furniture_poses or {}).items():
            if not 0 <= k < len(self.furniture[j].poses):
                raise ValueError(f"furniture {self.furniture[j].name!r} has no pose {k}")
            self.furniture_index[j] = k

    def _key(self) -> tuple[int, ...]:
        return tuple(int(k) for k in self.furniture_index)

    def states(self) -> list[NDArray[np.float64]]:
        """The true state of every shape (:attr:`shapes` order): door angle ``(1,)``, furniture ``(3,)``."""
        out = [np.array([f * d.opening_angle]) for d, f in zip(self.doors, self.door_open, strict=True)]
        for item, k in zip(self.furniture, self.furniture_index, strict=True):
            out.append(np.asarray(item.poses[int(k)], dtype=np.float64))
        return out

    def segments(self) -> NDArray[np.float64]:
        """The edges ``(1, M, 4)`` of every door leaf and piece of furniture in its current state."""
        key = tuple(float(f) for f in self.door_open) + tuple(float(k) for k in self.furniture_index)
        if self._segments_key == key:
            return self._segments
        parts = [shape.segments(state)[0] for shape, state in zip(self.shapes, self.states(), strict=True)]
        self._segments = np.concatenate(parts, axis=0)[None] if parts else np.zeros((1, 0, 4))
        self._segments_key = key
        return self._segments

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
