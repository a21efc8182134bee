"""An animation (GIF) of a recorded run: the map, the robot, its samples, the people, the paths.

Frames are drawn from :class:`~tourbot.snapshot.StateSnapshot` recordings only, so any
run (simulated or replayed) can be animated. GIF through imageio (needs no video encoder).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tourbot.maps.grid import OccupancyGrid
from tourbot.snapshot import StateSnapshot

__all__ = ["animate", "view_bounds"]


def view_bounds(
    grid: OccupancyGrid, points: NDArray[np.float64], margin: float = 4.0
) -> tuple[float, float, float, float]:
    """``(xmin, xmax, ymin, ymax)``: the box around ``points`` (K, 2) plus ``margin``, within the map."""
    lo = points.min(axis=0) - margin
    hi = points.max(axis=0) + margin
    gx0, gy0 = grid.origin[0], grid.origin[1]
    return (
        max(lo[0], gx0),
        min(hi[0], gx0 + grid.width),
        max(lo[1], gy0),
        min(hi[1], gy0 + grid.height),
    )


def animate(
    snapshots: Sequence[StateSnapshot],
    grid: OccupancyGrid,
    path: str | Path,
    *,
    bounds: tuple[float, float, float, float] | None = None,
    frame_every: float = 2.0,
    fps: int = 10,
    title: str = "",
    exhibits: Sequence[tuple[str, float, float]] = (),
    max_frames: int = 400,
) -> Path:
    """Write a GIF of ``snapshots``: one frame every ``frame_every`` seconds of run time."""
    import imageio.v2 as imageio
    import matplotlib

    from tourbot.io.output import output_file

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tourbot.plotting import draw_map

    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    if not snapshots:
        raise ValueError("nothing to animate: no snapshots")
    frames = _pick(snapshots, frame_every, max_frames)
    if bounds is None:
        xy = [s.truth.pose[:2] for s in snapshots if s.truth is not None]
        xy += [(s.pose.x, s.pose.y) for s in snapshots if s.pose is not None]
        bounds = view_bounds(grid, np.array(xy))
    x0, x1, y0, y1 = bounds
    width = 6.0
    height = min(10.0, max(3.0, width * (y1 - y0) / max(x1 - x0, 1e-6)))
    fig, ax = plt.subplots(figsize=(width, height), dpi=70)
    draw_map(ax, grid)  # the project's one map drawing (tourbot.plotting)
    for name, ex, ey in exhibits:
        ax.plot(ex, ey, marker="*", color="goldenrod", ms=8)
        ax.annotate(name, (ex, ey), fontsize=5, color="saddlebrown")
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    (true_path,) = ax.plot([], [], "-", color="tab:green", lw=1.2, label="true path")
    (est_path,) = ax.plot([], [], "--", color="tab:blue", lw=1.0, label="estimated path")
    (plan,) = ax.plot([], [], ":", color="tab:orange", lw=1.0, label="plan")
    samples = ax.scatter([], [], s=1, color="tab:red", alpha=0.4, label="samples")
    people = ax.scatter([], [], s=14, color="tab:purple", label="people")
    robot = plt.Circle((0, 0), 0.3, color="tab:blue", fill=False, lw=1.5)
    ax.add_patch(robot)
    (heading,) = ax.plot([], [], "-", color="tab:blue", lw=1.5)
    ax.legend(loc="lower left", fontsize=6, framealpha=0.8)
    text = ax.set_title(title, fontsize=8)
    fig.tight_layout()
    truth_xy: list[tuple[float, float]] = []
    est_xy: list[tuple[float, float]] = []
    i_frame = 0
    # written whole or not at all: Ctrl-C while the frames are drawn keeps any previous GIF
    with output_file(out) as tmp, imageio.get_writer(tmp, mode="I", duration=1.0 / fps, loop=0) as writer:
        for s in snapshots:
            if s.truth is not None:
                truth_xy.append(s.truth.pose[:2])
            if s.pose is not None:
                est_xy.append((s.pose.x, s.pose.y))
            if i_frame >= len(frames) or s is not frames[i_frame]:
                continue
            i_frame += 1
            if truth_xy:
                true_path.set_data(*np.array(truth_xy).T)
            if est_xy:
                est_path.set_data(*np.array(est_xy).T)
            nav = s.navigation
            plan.set_data(*(np.array(nav.path).T if nav.path else ([], [])))
            if s.samples is not None and s.samples.poses:
                samples.set_offsets(np.array(s.samples.poses)[:, :2])
            crowd = s.truth.people if s.truth is not None else s.people
            people.set_offsets(np.array([(p.x, p.y) for p in crowd]) if crowd else np.zeros((0, 2)))
            if s.pose is not None:
                robot.center = (s.pose.x, s.pose.y)
                heading.set_data(
                    [s.pose.x, s.pose.x + 0.5 * np.cos(s.pose.theta)],
                    [s.pose.y, s.pose.y + 0.5 * np.sin(s.pose.theta)],
                )
            err = s.position_error
            err_txt = f"  error {100 * err:.0f} cm" if err is not None else ""
            text.set_text(
                f"{title}  t={s.time:.0f} s  {nav.mode.value}"
                f"{'  ' + nav.current_exhibit if nav.current_exhibit else ''}"
                f"  {len(nav.visited)}/{nav.exhibits_total}{err_txt}"
            )
            fig.canvas.draw()
            frame = np.asarray(fig.canvas.buffer_rgba())[..., :3]  # type: ignore[attr-defined]
            writer.append_data(frame)  # type: ignore[attr-defined]
    plt.close(fig)
    return out


def _pick(snapshots: Sequence[StateSnapshot], every: float, max_frames: int) -> list[StateSnapshot]:
    span = snapshots[-1].time - snapshots[0].time
    every = max(every, span / max(max_frames - 1, 1))
    picked: list[StateSnapshot] = []
    next_t = snapshots[0].time
    for s in snapshots:
        if s.time >= next_t:
            picked.append(s)
            next_t = s.time + every
    if picked[-1] is not snapshots[-1]:
        picked.append(snapshots[-1])
    return picked
