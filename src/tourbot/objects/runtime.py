"""The object state estimator as a runtime estimator, and the object states as plain data.

:class:`ObjectsEstimator` takes every scan (``ScanShare.ALL``, the default) or the odd scans only
(``ScanShare.ALTERNATE``: Table 1 of Schulz and Burgard, the pose and the objects never updated
from the same reading). ``tourbot bench objects`` measures both: with every scan the doors' mean
error is 0.8 deg against 1.1 deg alternating (docs/results/objects.md), so every scan is the
default. Its snapshot contribution is the
doors and furniture in their estimated states, with how well each was observed. With an
:class:`~tourbot.objects.world.ObjectWorld` it closes the loop: every update goes to the world,
which hands the map with the objects drawn in to its users (MCL, the navigator) when a state moved.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tourbot.interfaces import EstimatorOutput, PoseBelief, ScanShare
from tourbot.maps.objects import ObjectShape
from tourbot.objects.estimator import ObjectEstimate, ObjectStateEstimator
from tourbot.objects.world import ObjectWorld
from tourbot.records import Odometry, Scan
from tourbot.snapshot import DoorState, FurnitureState

__all__ = ["ObjectsEstimator", "door_state", "furniture_state", "quality_dict"]


def door_state(estimate: ObjectEstimate, opening_angle: float) -> DoorState:
    """A door's estimate as the snapshot's :class:`DoorState`."""
    a = estimate.state[0]
    return DoorState(estimate.name, float(a), float(a / opening_angle) if opening_angle else 0.0)


def furniture_state(estimate: ObjectEstimate) -> FurnitureState:
    x, y, th = estimate.state
    return FurnitureState(estimate.name, float(x), float(y), float(th))


def quality_dict(
    estimate: ObjectEstimate, shape: ObjectShape | None = None, held: tuple[float, ...] | None = None
) -> dict[str, Any]:
    """How well an estimate was observed, as plain data (the snapshot's ``extra``, the CSV); with
    its ``shape`` and the state the world model ``held`` (the latest well-observed one), also the
    ``outline`` in that state (world, cm precision: what the web draws)."""
    q = estimate.quality
    out: dict[str, Any] = {
        "name": estimate.name,
        "kind": estimate.kind,
        "status": str(q.status),
        "beams": q.beams,
        "explained": q.explained,
        "occluded": q.occluded,
        "std": [round(v, 5) for v in estimate.std],
        "time": estimate.time,
    }
    if shape is not None and held is not None:
        outline = shape.polygons(np.asarray(held, dtype=np.float64))[0]
        out["outline"] = [[round(float(x), 2), round(float(y), 2)] for x, y in outline]
    return out


class ObjectsEstimator:
    """A runtime :class:`~tourbot.interfaces.Estimator` over an :class:`ObjectStateEstimator`."""

    name = "objects"

    def __init__(
        self,
        estimator: ObjectStateEstimator,
        opening_angles: dict[str, float],
        scan_share: ScanShare = ScanShare.ALL,
        world: ObjectWorld | None = None,
    ) -> None:
        self.estimator = estimator
        self.opening_angles = opening_angles
        self.scan_share = scan_share
        self.world = world
        self.history: list[list[ObjectEstimate]] = []

    def on_odometry(self, odom: Odometry) -> None:  # noqa: ARG002 - the objects need no odometry
        return None

    def on_scan(self, scan: Scan, belief: PoseBelief) -> None:
        updated = self.estimator.update(scan, belief.samples, belief.weights)
        if updated:
            self.history.append(updated)
            if self.world is not None:
                self.world.update(updated)

    def state(self) -> EstimatorOutput:
        estimates = self.estimator.estimates()
        doors = tuple(
            door_state(e, self.opening_angles.get(e.name, 0.0)) for e in estimates if e.kind == "door"
        )
        furniture = tuple(furniture_state(e) for e in estimates if e.kind != "door")
        shapes = self.estimator.shapes
        held = self.world.drawn if self.world is not None else {}
        extra = {
            "objects": [quality_dict(e, s, held.get(e.name)) for e, s in zip(estimates, shapes, strict=True)]
        }
        return EstimatorOutput(doors=doors, furniture=furniture, extra=extra)
