"""Input a command cannot use, flagged before the work: one line each, or a warning with ``--force``.

A localizer or a mapper given a log with a handful of odometry readings for hundreds of scans, an
odometry that never moves, or a map of another building runs to the end and prints figures that
mean nothing. These checks look first: too few odometry readings for the scans, no motion, and
a map whose ray casts from the log's reference poses miss the measured ranges (median error).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from tourbot.errors import InputError
from tourbot.geometry import wrap_angle
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import RobotLog

__all__ = ["ForceOpt", "LogChecks", "McapOpt", "check_before_work", "log_problems", "map_problem"]

McapOpt = Annotated[
    Path | None,
    typer.Option(
        "--mcap",
        help="Also write the run as MCAP (ROS 2 messages: scans, odometry, TF, map, estimate, particles; "
        "beams where the localizer gives them) for Foxglove; an existing file is replaced only with "
        "--force.",
    ),
]

ForceOpt = Annotated[
    bool,
    typer.Option(
        "--force",
        help="Go on (with a warning) where the log or map looks unusable: too little odometry, "
        "no motion, a map that does not fit.",
    ),
]


@dataclass(frozen=True)
class LogChecks:
    """The thresholds: below them the input is refused (or, forced, warned about)."""

    scans_per_reading: float = 10.0  # at least one odometry reading per this many scans
    min_motion_m: float = 0.05  # the odometry must move this far ...
    min_turn_rad: float = math.radians(5.0)  # ... or turn this much
    map_median_error_m: float = 0.3  # a building's own map explains its ranges to a few cm
    map_scans: int = 60  # scans the map is measured on, spread over the log
    shorter_ignored_m: float = 0.2  # beams shorter than the cast by more may be visitors: left out
    min_kept: float = 0.2  # ... but a map where most beams end before its walls is another building


def log_problems(log: RobotLog, checks: LogChecks = LogChecks()) -> list[str]:
    """What makes ``log`` unusable for following the robot by its odometry (empty when nothing)."""
    problems = []
    n = len(log.scans)
    readings = len(log.odometry)
    # a log with no stream carries its odometry on the laser lines, one pose per scan
    if readings and readings * checks.scans_per_reading < n:
        problems.append(
            f"only {readings} odometry reading{'s' if readings != 1 else ''} for {n} scans (at least one per "
            f"{checks.scans_per_reading:g} scans is needed to follow the robot between scans)"
        )
    odom = log.odom_poses
    odom = odom[~np.isnan(odom).any(axis=1)]
    if len(odom) >= 2:
        moved = float(np.hypot(*np.diff(odom[:, :2], axis=0).T).sum())
        turned = float(np.abs(wrap_angle(np.diff(odom[:, 2]))).sum())
        if moved < checks.min_motion_m and turned < checks.min_turn_rad:
            problems.append(
                f"the odometry does not move ({moved:.3f} m, {math.degrees(turned):.1f} deg over {n} scans)"
            )
    return problems


def map_problem(log: RobotLog, grid: OccupancyGrid, checks: LogChecks = LogChecks()) -> str | None:
    """Why ``grid`` does not fit ``log`` (median ray-cast error at the reference poses), None if it fits.

    Measurable only on a log with reference poses (a corrected log); otherwise None.
    """
    from tourbot.maps.reference import map_quality

    if not log.scans or not any(s.reference is not None for s in log.scans):
        return None
    # visitors only shorten beams: those shorter than the cast are no evidence against the map
    quality = map_quality(grid, log, max_scans=checks.map_scans, shorter_ignored=checks.shorter_ignored_m)
    median = quality["median_abs_error"]
    if quality["kept"] < checks.min_kept:
        return (
            f"the map does not fit the log: {100 * (1 - quality['kept']):.0f} % of the beams end before the "
            "map's walls at the reference poses (a crowd shortens about half of them at most)"
        )
    if not median <= checks.map_median_error_m:
        return (
            f"the map does not fit the log: ray casts from the reference poses miss the ranges by "
            f"{100 * median:.0f} cm (median over the beams not shortened, as by a visitor; a building's "
            "own map: a few cm)"
        )
    return None


def check_before_work(problems: list[str], *, path: str | Path, force: bool) -> list[str]:
    """Refuse in one line (the first problem, and that ``--force`` overrides), or return the warnings."""
    if problems and not force:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise InputError(f"{problems[0]}{more}; --force goes on anyway", path=path)
    return [f"{path}: {p} (going on: --force)" for p in problems]
