"""The loop closed: the world model with doors and furniture in their estimated states.

:class:`ObjectWorld` keeps the static occupancy grid with every object drawn where it was last
*well observed* (a poorly observed estimate changes nothing), and hands the new grid to whoever
reads the world when a state changed by more than a tolerance: MCL's ``set_map`` (the seam agreed
in ``BRIEF.md``: its likelihood field and caster are rebuilt from the grid), and the navigator,
whose planner then plans around a door found closed or a bench that blocks a passage. The users
are anything with ``set_map(grid)`` (:class:`MapUser`).

An object stays drawn in its last well-observed state until it is seen well in another (a door
found closed stays closed until seen open): the localizer and the navigator share one world.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np

from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.objects import ObjectShape
from tourbot.objects.estimator import ObjectEstimate

__all__ = ["MapUser", "ObjectWorld"]


@runtime_checkable
class MapUser(Protocol):
    """Anything that reads the world's grid and can take a new one (MCL's ``set_map`` seam)."""

    def set_map(self, grid: OccupancyGrid) -> None: ...


class ObjectWorld:
    """The static grid plus the objects in their latest well-observed states.

    ``door_tolerance`` (rad), ``position_tolerance`` (m), ``heading_tolerance`` (rad): how far an
    estimate must move from the drawn state before the grid is redrawn and handed on (a redraw
    rebuilds MCL's likelihood field, so not for every degree).
    """

    def __init__(
        self,
        static: OccupancyGrid,
        shapes: Sequence[ObjectShape],
        users: Sequence[MapUser] = (),
        door_tolerance: float = math.radians(5.0),
        position_tolerance: float = 0.05,
        heading_tolerance: float = math.radians(5.0),
    ) -> None:
        self.static = static
        self.shapes = list(shapes)
        self.users = list(users)
        self.tolerances = (door_tolerance, position_tolerance, heading_tolerance)
        self.drawn: dict[str, tuple[float, ...]] = {}
        self.grid = static
        self.redraws = 0

    def _moved(self, shape: ObjectShape, state: tuple[float, ...]) -> bool:
        old = self.drawn.get(shape.name)
        if old is None:
            return True
        door_tol, pos_tol, head_tol = self.tolerances
        if shape.kind == "door":
            return abs(state[0] - old[0]) > door_tol
        _, turn = shape.error(state, old)
        return math.hypot(state[0] - old[0], state[1] - old[1]) > pos_tol or turn > head_tol

    def update(self, estimates: Sequence[ObjectEstimate]) -> bool:
        """Take the estimates; True (and every user given the new grid) when the world changed."""
        by_name = {s.name: s for s in self.shapes}
        changed = False
        for est in estimates:
            shape = by_name.get(est.name)
            if shape is None or est.quality.poor:
                continue
            if not self._moved(shape, est.state):
                continue
            self.drawn[est.name] = est.state
            changed = True
        if not changed:
            return False
        self.grid = self.draw()
        self.redraws += 1
        for user in self.users:
            user.set_map(self.grid)
        return True

    def draw(self) -> OccupancyGrid:
        """The static grid with the drawn objects' outlines filled in as occupied."""
        from tourbot.site.model import rasterize_polygons

        polygons = [
            [(float(x), float(y)) for x, y in s.polygons(np.asarray(self.drawn[s.name]))[0]]
            for s in self.shapes
            if s.name in self.drawn
        ]
        prob = self.static.prob.copy()
        if polygons:
            prob[rasterize_polygons(self.static, polygons)] = 1.0
        g = self.static
        return OccupancyGrid(prob, g.resolution, g.origin, g.occupied_thresh, g.free_thresh)
