"""Move around an exhibit: the viewpoints from which the robot shows it from several directions.

Burgard et al. (section 6.1): "the user may request the robot to move around an exhibit in order to
view it from several directions." An exhibit is known by its viewing pose: where the robot stands to
present it, facing it from ``distance`` away. The exhibit stands ``distance`` ahead of that pose; the
viewpoints lie on the circle of that radius around it, every ``360 / views`` degrees from the
viewing pose, each facing the exhibit. A viewpoint the robot's map forbids (a wall, an exhibit case,
too close to either, or not reachable from the viewing pose) is left out: against a wall the robot
shows the exhibit from the sides it can reach.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tourbot.geometry import wrap_angle
from tourbot.navigation.planner import CostMap

__all__ = ["AroundConfig", "exhibit_centre", "viewpoints_around"]


@dataclass(frozen=True)
class AroundConfig:
    """``distance``: from the viewing pose to the exhibit (m; the sites' viewing poses stand 1.2 m
    from their exhibits); ``views``: directions on the circle; ``dwell``: seconds at each."""

    distance: float = 1.2
    views: int = 6
    dwell: float = 3.0

    def __post_init__(self) -> None:
        if not self.distance > 0 or self.views < 2 or self.dwell < 0:
            raise ValueError("AroundConfig needs distance > 0, at least 2 views and dwell >= 0")


def exhibit_centre(pose: tuple[float, float, float], distance: float) -> tuple[float, float]:
    """Where the exhibit viewed from ``pose`` stands: ``distance`` ahead of it."""
    x, y, theta = pose
    return x + distance * math.cos(theta), y + distance * math.sin(theta)


def viewpoints_around(
    pose: tuple[float, float, float], costmap: CostMap, config: AroundConfig | None = None
) -> list[tuple[float, float, float]]:
    """The poses around the exhibit viewed from ``pose``, each facing the exhibit, that ``costmap``
    lets the robot stand at and reach from the viewing pose, in the order of one sweep around it:
    counter-clockwise from the viewing pose on a free circle, else from one end of the free arc
    to the other (the robot never crosses back over the side it cannot reach)."""
    cfg = config or AroundConfig()
    cx, cy = exhibit_centre(pose, cfg.distance)
    start = pose[2] + math.pi  # the viewing pose's direction seen from the exhibit
    reach = costmap.field(pose[:2]) if costmap.traversable(pose[:2]) else None
    free: dict[int, tuple[float, float, float]] = {}
    for k in range(cfg.views):
        phi = start + 2.0 * math.pi * k / cfg.views
        x, y = cx + cfg.distance * math.cos(phi), cy + cfg.distance * math.sin(phi)
        if not costmap.traversable((x, y)):
            continue
        if reach is not None:
            r, c = costmap.cell((x, y))
            if not np.isfinite(reach[r, c]):
                continue
        free[k] = (x, y, float(wrap_angle(phi + math.pi)))
    order = sorted(free)
    if 0 < len(order) < cfg.views:
        # start after the widest gap of the circle: the sweep goes from one end of the arc to the other
        gaps = [(order[(i + 1) % len(order)] - order[i]) % cfg.views or cfg.views for i in range(len(order))]
        first = (int(np.argmax(gaps)) + 1) % len(order)
        order = order[first:] + order[:first]
    return [free[k] for k in order]
