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


def test_with_a_hold_an_object_not_seen_well_goes_back_to_the_static_map(room: Site) -> None:
    mcl = FakeMCL()
    world = ObjectWorld(room.grid, [door_shape(room.doors[0])], [mcl], hold=10.0)

    def at(t: float, status: Observation = Observation.OBSERVED) -> ObjectEstimate:
        return ObjectEstimate("door", "door", t, (0.0,), (0.01,), Quality(status, 10, 10, 0), 1)

    assert world.update([at(0.0)])
    assert not world.update([at(8.0)])  # seen well again: kept (and its clock restarted)
    assert not world.update([at(15.0, Observation.OCCLUDED)])
    assert "door" in world.drawn
    assert world.update([at(18.5, Observation.OCCLUDED)])  # 10.5 s since it was seen well
    assert world.drawn == {}
    assert mcl.grids[-1].prob.tolist() == room.grid.prob.tolist()
    forever = ObjectWorld(room.grid, [door_shape(room.doors[0])])
    forever.update([at(0.0)])
    forever.update([at(1000.0, Observation.OCCLUDED)])
    assert "door" in forever.drawn
