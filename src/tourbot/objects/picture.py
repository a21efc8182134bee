"""The picture of an object replay: the map, the robot's path, every object in its estimated state
(black: well observed, orange: poorly observed) and, when known, in its true state (green)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.objects import ObjectShape
from tourbot.objects.estimator import ObjectEstimate

__all__ = ["draw_objects_figure"]


def draw_objects_figure(
    path: str | Path,
    grid: OccupancyGrid,
    shapes: Sequence[ObjectShape],
    estimates: Sequence[ObjectEstimate],
    robot_path: NDArray[np.float64],
    truth: Sequence[NDArray[np.float64]] | None = None,
    title: str = "",
    reference: NDArray[np.float64] | None = None,
) -> Path:
    """Write the picture to ``path`` (PNG); ``truth[i]`` the true state of ``shapes[i]``."""
    from matplotlib.patches import Polygon

    from tourbot.plotting import draw_map, draw_path, new_map_figure, save_figure

    fig, ax = new_map_figure(grid)
    draw_map(ax, grid)
    if reference is not None and len(reference):
        draw_path(ax, reference, "reference", color="tab:gray", linewidth=0.8, markers=False)
    if len(robot_path):
        draw_path(ax, robot_path, "robot (estimate)", color="tab:blue", linewidth=1.0)
    for i, (shape, est) in enumerate(zip(shapes, estimates, strict=True)):
        if truth is not None:
            poly = shape.polygons(truth[i])[0]
            ax.add_patch(
                Polygon(poly, closed=True, fill=False, edgecolor="tab:green", linewidth=1.6, zorder=5)
            )
        poly = shape.polygons(np.asarray(est.state))[0]
        colour = "black" if not est.quality.poor else "tab:orange"
        ax.add_patch(
            Polygon(poly, closed=True, fill=True, facecolor=colour, edgecolor=colour, alpha=0.8, zorder=6)
        )
        x, y = poly.mean(axis=0)
        ax.annotate(f"{shape.name} ({est.quality.status})", (x, y), fontsize=6, zorder=7)
    ax.set_aspect("equal")
    ax.legend(loc="best", fontsize=7)
    if title:
        ax.set_title(title)
    return save_figure(fig, path)
