"""Pictures: maps, paths and trajectories with matplotlib (the only plotting helpers of tourbot).

``draw_map`` and ``draw_path`` draw on any matplotlib ``Axes``; ``new_map_figure`` sizes a figure
to a map; ``save_figure`` writes it. ``show_log`` is the picture of ``tourbot show``: a log's map,
its reference path, its odometry if asked, and any other trajectories, labelled.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.geometry import compose
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import RobotLog

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    "PATH_COLORS",
    "Trajectory",
    "align_rigid",
    "draw_map",
    "draw_path",
    "new_map_figure",
    "path_length",
    "save_figure",
    "show_log",
]

#: Colours for successive paths (colour-blind safe, Okabe & Ito), the reference path first.
PATH_COLORS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#F0E442", "#000000")

_UNKNOWN_RGB = (0.86, 0.88, 0.91)


@dataclass(frozen=True)
class Trajectory:
    """A labelled path to draw: poses ``(N, 3)`` (times optional, for the record)."""

    label: str
    poses: NDArray[np.float64]
    times: NDArray[np.float64] | None = None


def path_length(poses: ArrayLike) -> float:
    """Length of the path through the positions of ``poses`` ``(N, 3)`` (NaN poses skipped)."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    p = p[~np.isnan(p).any(axis=1)]
    if len(p) < 2:
        return 0.0
    return float(np.hypot(*np.diff(p[:, :2], axis=0).T).sum())


def map_image(grid: OccupancyGrid) -> NDArray[np.float64]:
    """RGB image ``(rows, cols, 3)`` of a grid, row 0 at the bottom: occupied dark, free white."""
    prob = grid.prob.astype(np.float64)
    grey = 1.0 - np.clip(prob, 0.0, 1.0)
    rgb = np.repeat(grey[:, :, None], 3, axis=2)
    rgb[grid.unknown()] = _UNKNOWN_RGB
    return rgb


def draw_map(ax: Axes, grid: OccupancyGrid, *, alpha: float = 1.0) -> Any:
    """Draw ``grid`` in world coordinates (metres), rotated by its origin's yaw; returns the image."""
    from matplotlib.transforms import Affine2D

    ox, oy, yaw = grid.origin
    image = ax.imshow(
        map_image(grid),
        origin="lower",
        extent=(ox, ox + grid.width, oy, oy + grid.height),
        interpolation="nearest",
        alpha=alpha,
        zorder=0,
    )
    if yaw != 0.0:
        image.set_transform(Affine2D().rotate_around(ox, oy, yaw) + ax.transData)
        corners = np.array([[0, 0], [grid.width, 0], [0, grid.height], [grid.width, grid.height]])
        c, s = np.cos(yaw), np.sin(yaw)
        xs = ox + c * corners[:, 0] - s * corners[:, 1]
        ys = oy + s * corners[:, 0] + c * corners[:, 1]
        ax.set_xlim(xs.min(), xs.max())
        ax.set_ylim(ys.min(), ys.max())
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return image


def draw_path(
    ax: Axes,
    poses: ArrayLike,
    label: str,
    *,
    color: str | None = None,
    linewidth: float = 1.4,
    linestyle: str = "-",
    markers: bool = True,
    zorder: int = 3,
) -> None:
    """Draw a path through ``poses`` ``(N, 3)``, labelled; a circle marks its start, a square its end."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    p = p[~np.isnan(p).any(axis=1)]
    if len(p) == 0:
        return
    (line,) = ax.plot(
        p[:, 0], p[:, 1], linestyle, color=color, linewidth=linewidth, label=label, zorder=zorder
    )
    if markers:
        c = line.get_color()
        ax.plot(p[0, 0], p[0, 1], "o", color=c, markersize=6, markeredgecolor="white", zorder=zorder + 1)
        ax.plot(p[-1, 0], p[-1, 1], "s", color=c, markersize=6, markeredgecolor="white", zorder=zorder + 1)


def new_map_figure(grid: OccupancyGrid | None, *, max_inches: float = 11.0) -> tuple[Figure, Axes]:
    """A figure shaped like ``grid`` (landscape or portrait), longest side ``max_inches``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if grid is None:
        width, height = max_inches, max_inches * 0.75
    else:
        aspect = grid.height / grid.width
        width, height = (
            (max_inches, max(4.0, max_inches * aspect))
            if aspect < 1
            else (
                max(5.0, max_inches / aspect) + 1.5,
                max_inches,
            )
        )
    fig, ax = plt.subplots(figsize=(width, height), layout="constrained")
    return fig, ax


def save_figure(fig: Figure, path: str | Path, *, dpi: int = 150) -> Path:
    """Write the figure (format from the suffix, PNG usually) and close it."""
    import matplotlib.pyplot as plt

    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out


def align_rigid(poses: ArrayLike, target: ArrayLike) -> NDArray[np.float64]:
    """``poses`` ``(N, 3)`` moved by the rigid motion that best fits their positions onto ``target``.

    Least squares over all positions (2D Kabsch/Umeyama without scale, as ``evo --align``); rows
    with NaN in either are ignored for the fit and stay NaN.
    """
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    q = np.asarray(target, dtype=np.float64).reshape(-1, 3)
    ok = ~(np.isnan(p).any(axis=1) | np.isnan(q).any(axis=1))
    out = np.full_like(p, np.nan)
    if not ok.any():
        return out
    a, b = p[ok, :2], q[ok, :2]
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    da, db = a - ca, b - cb
    angle = float(np.arctan2((da[:, 0] * db[:, 1] - da[:, 1] * db[:, 0]).sum(), (da * db).sum()))
    c, s = np.cos(angle), np.sin(angle)
    t = cb - np.array([c * ca[0] - s * ca[1], s * ca[0] + c * ca[1]])
    motion = np.array([t[0], t[1], angle])
    good = ~np.isnan(p).any(axis=1)
    out[good] = compose(motion, p[good])
    return out


def odometry_in_reference_frame(log: RobotLog) -> NDArray[np.float64]:
    """The odometry path moved onto the reference path by the best rigid fit (its drift shows)."""
    return align_rigid(log.odom_poses, log.reference_poses)


def show_log(
    log: RobotLog | None,
    output: str | Path,
    *,
    grid: OccupancyGrid | None = None,
    trajectories: Sequence[Trajectory] = (),
    odometry: bool = False,
    title: str | None = None,
    map_note: str | None = None,
) -> Path:
    """The picture of a log: ``grid``, the reference path, optionally the odometry, and trajectories."""
    fig, ax = new_map_figure(grid)
    if grid is not None:
        draw_map(ax, grid)
    colors = iter(PATH_COLORS)
    lines = []
    if log is not None and log.scans:
        ref = log.reference_poses
        if not np.isnan(ref).all():
            length = path_length(ref)
            draw_path(ax, ref, f"reference path ({length:.0f} m)", color=next(colors), linewidth=1.6)
            lines.append(f"{len(log)} scans, {log.times[-1] - log.times[0]:.0f} s, {length:.0f} m")
        elif not np.isnan(log.odom_poses).all():
            odom = log.odom_poses
            draw_path(ax, odom, f"odometry ({path_length(odom):.0f} m)", color=next(colors))
            odometry = False
        if odometry and not np.isnan(log.odom_poses).all():
            moved = odometry_in_reference_frame(log)
            draw_path(ax, moved, "odometry (best rigid fit)", color=next(colors), linestyle="--")
    for traj in trajectories:
        draw_path(ax, traj.poses, f"{traj.label} ({path_length(traj.poses):.0f} m)", color=next(colors, None))
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best", framealpha=0.9, fontsize=9)
    heading = title or (Path(log.source).name if log is not None else "map")
    sub = "; ".join([*lines, *([map_note] if map_note else [])])
    ax.set_title(heading + (f"\n{sub}" if sub else ""), fontsize=11)
    ax.grid(True, color="#999999", linewidth=0.3, alpha=0.5)
    return save_figure(fig, output)
