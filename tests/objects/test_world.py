"""The world with the estimated objects, handed to map users (MCL's set_map seam, a fake here)."""

from __future__ import annotations

import math

import numpy as np

from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.objects import door_shape
from tourbot.objects.estimator import ObjectEstimate, Observation, Quality
from tourbot.objects.world import MapUser, ObjectWorld
from tourbot.site.model import Site


class FakeMCL:
    """Stands in for MonteCarloLocalization.set_map until the mclrefactor branch lands."""

    def __init__(self) -> None:
        self.grids: list[OccupancyGrid] = []

    def set_map(self, grid: OccupancyGrid) -> None:
        self.grids.append(grid)


def _estimate(angle: float, status: Observation = Observation.OBSERVED) -> ObjectEstimate:
    return ObjectEstimate("door", "door", 0.0, (angle,), (0.01,), Quality(status, 10, 10, 0), 1)


def test_a_door_found_closed_blocks_the_doorway_in_the_new_map(room: Site) -> None:
    mcl = FakeMCL()
    assert isinstance(mcl, MapUser)
    world = ObjectWorld(room.grid, [door_shape(room.doors[0])], [mcl])
    assert world.update([_estimate(0.0)])
    closed = mcl.grids[-1]
    cell = closed.world_to_cell(np.array([[3.45, 3.975]]))[0]
    assert closed.occupied()[cell[0], cell[1]]
    assert not room.grid.occupied()[cell[0], cell[1]]
    # a small change is not worth a new map; a poorly observed estimate changes nothing
    assert not world.update([_estimate(math.radians(2.0))])
    assert not world.update([_estimate(math.radians(80.0), Observation.OCCLUDED)])
    assert len(mcl.grids) == 1
    assert world.update([_estimate(math.radians(90.0))])
    opened = mcl.grids[-1]
    assert not opened.occupied()[cell[0], cell[1]]


def test_an_object_stays_drawn_in_its_last_well_observed_state_however_long_unseen(room: Site) -> None:
    mcl = FakeMCL()
    world = ObjectWorld(room.grid, [door_shape(room.doors[0])], [mcl])

    def at(t: float, status: Observation = Observation.OBSERVED) -> ObjectEstimate:
        return ObjectEstimate("door", "door", t, (0.0,), (0.01,), Quality(status, 10, 10, 0), 1)

    assert world.update([at(0.0)])
    assert not world.update([at(1000.0, Observation.OCCLUDED)])
    assert world.drawn == {"door": (0.0,)}
    assert len(mcl.grids) == 1
