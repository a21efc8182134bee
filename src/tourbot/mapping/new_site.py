"""A new site from one robot log: the people-filtered graph-SLAM map, the line map and suggested doors.

Burgard et al. (Sec. 7.1) set a new exhibition up in under two days, mapping included; here the
map comes from one log (:class:`tourbot.mapping.graph_slam.GraphSlam` with the people filter as
its front end, Sec. 2 and 5), the line map from the same log by feature-based mapping (Sec. 2.2,
:class:`tourbot.mapping.features.FeatureMapper`), the doors are suggested where the map's walls
have a door-wide gap (:func:`tourbot.maps.doors.suggest_doorways`), and the site file holds the
map and the doors; exhibits are then placed on the map (the admin page, ``tourbot site exhibit``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from tourbot.mapping.features import FeatureMap, FeatureMapper
from tourbot.mapping.graph_slam import GraphSlam, GraphSlamParams
from tourbot.mapping.incremental import MapperParams, MappingError
from tourbot.mapping.people_filter import PeopleFilteredMapper, PeopleMappingConfig
from tourbot.maps.doors import Doorway
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import RobotLog

__all__ = [
    "MIN_SCANS",
    "check_log",
    "line_map_log",
    "map_log",
    "require_odometry",
    "site_document",
    "tour_stops",
]

MIN_SCANS = 50  # fewer scans than this do not make a building's map


def require_odometry(log: RobotLog, source: str) -> None:
    """Refuse, in one line, a log some of whose scans have no odometry pose."""
    missing = sum(s.odom is None for s in log.scans)
    if missing:
        raise MappingError(
            f"{source}: {missing} of {len(log.scans)} scans have no odometry pose; mapping needs the "
            "odometry of every scan"
        )


def check_log(log: RobotLog, source: str) -> None:
    """Refuse a log that cannot be mapped, in one line: no scans, too few, no odometry."""
    if len(log.scans) < MIN_SCANS:
        raise MappingError(f"{source}: {len(log.scans)} laser scans; a site's map needs at least {MIN_SCANS}")
    require_odometry(log, source)
    odom = log.odom_poses
    travelled = float(np.sum(np.hypot(np.diff(odom[:, 0]), np.diff(odom[:, 1]))))
    if travelled < 1.0:
        raise MappingError(f"{source}: the odometry moves {travelled:.2f} m in all; nothing to map")


def map_log(log: RobotLog, seed: int = 0, resolution: float = 0.05) -> tuple[OccupancyGrid, GraphSlam]:
    """The people-filtered, loop-closed map of ``log`` (its frame: the first odometry pose)."""
    params = MapperParams(resolution=resolution)
    people = PeopleFilteredMapper.create(PeopleMappingConfig(mapper=params), seed=seed)
    slam = GraphSlam(GraphSlamParams(mapper=params), people=people)
    for scan in log.scans:
        slam.add_scan(scan)
    slam.finish()
    return slam.grid(), slam


def line_map_log(log: RobotLog) -> FeatureMap:
    """The line map of ``log`` (walls and corners; its frame, like :func:`map_log`'s: the first
    odometry pose)."""
    return FeatureMapper().run(log.scans)


def tour_stops(poses: np.ndarray, count: int = 4) -> list[tuple[float, float, float]]:
    """``count`` poses of the mapped path, evenly spread along it (the robot stood there, so they
    are free): provisional viewing poses until the staff place the real exhibits."""
    p = np.asarray(poses, dtype=np.float64)
    along = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1])))])
    marks = along[-1] * (np.arange(count) + 0.5) / count
    idx = np.searchsorted(along, marks).clip(0, len(p) - 1)
    return [(float(p[i, 0]), float(p[i, 1]), float(p[i, 2])) for i in idx]


def site_document(
    name: str, source: str, doorways: list[Doorway], stops: list[tuple[float, float, float]]
) -> dict[str, Any]:
    """The site file's content: the map next to it, a door in each suggested doorway (hinged at
    one end, closed across the gap, open to start with, changing every ten minutes), and
    provisional exhibits at ``stops`` (each 1 m ahead of its viewing pose) in a tour
    ``highlights``, so that the simulator and the web site can run at once."""
    exhibits = [
        {
            "name": f"stop-{k + 1}",
            "position": [round(x + math.cos(th), 3), round(y + math.sin(th), 3)],
            "viewing_pose": [round(x, 3), round(y, 3), round(th, 4)],
            "text": "A provisional stop on the mapped path: place the real exhibit in the admin page.",
        }
        for k, (x, y, th) in enumerate(stops)
    ]
    doors = []
    for k, d in enumerate(doorways):
        direction = math.atan2(d.b[1] - d.a[1], d.b[0] - d.a[0])
        doors.append(
            {
                "name": f"door-{k + 1}",
                "hinge": [round(d.a[0], 3), round(d.a[1], 3)],
                "leaf_length": round(d.width, 3),
                "closed_direction": round(direction, 4),
                "opening_angle": round(math.pi / 2, 4),
                "schedule": {"period": 600.0, "start_open": True},
            }
        )
    return {
        "name": name,
        "description": f"Mapped from the log {source} by `tourbot site new` (graph SLAM, people filtered); "
        f"{len(doors)} doors suggested where the walls have a door-wide gap.",
        "map": {"grid": "map.yaml"},
        "exhibits": exhibits,
        "tours": [{"name": "highlights", "exhibits": [e["name"] for e in exhibits]}] if exhibits else [],
        "doors": doors,
    }
