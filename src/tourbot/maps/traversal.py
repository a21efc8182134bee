"""Grid traversal: the one walk of a ray through the cells of a grid (Amanatides & Woo 1987).

A ray ``o + t d`` runs in cell units (``x`` along columns, ``y`` along rows, ``d`` a unit vector).
It leaves its cell ``(cx, cy)`` at the nearer of two grid-line crossings,
``((cx + ax) - ox) * (1 / dx)`` and ``((cy + ay) - oy) * (1 / dy)``, where ``ax`` is 1 when the
ray heads to larger ``x``, else 0. It then enters the neighbour across that line
(:func:`leave`). Each crossing is computed from the cell it leaves, never accumulated along the
ray. So the cell is the whole state of the walk, and the crossings do not drift over long rays.
A plain-numpy twin that cuts the ray at every grid line gets the same floats. A direction
component under ``AXIS`` counts as 0 (:func:`axis`), so a ray a hair off a grid axis runs along
it. A piece of ray shorter than ``EPS`` (a ray through a cell corner) visits no cell.

The walk has two modes:

trace (:func:`trace_ray`)
    visits every cell a beam crosses up to its length. Each cell counts as a miss, or as the
    beam's hit: these are the counts of the reference map
    (:func:`tourbot.maps.reference.trace_beams`).
cast (:func:`cast_ray`, or :func:`cast_start` then :func:`cast_step` one table read at a time)
    walks a padded ``uint8`` table (:func:`tourbot.maps.raycast.padded_table`) to the first
    ``BLOCKED`` or ``OUTSIDE`` cell. This is the range of every caster
    (:func:`tourbot.maps.raycast.cast_rays_kernel`, the novelty filter's casts). In the table,
    a free cell holds how many whole cells a ray may jump from it without meeting a blocking
    cell (a distance transform). Where that is not 0, the walk jumps along the ray in 32.32
    fixed point instead of stepping: ray marching, range_libc's "RM" (Walsh & Karaman 2018).
    Near obstacles, where no jump is safe, it takes the exact steps, so the range is the
    steps' range.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "AXIS",
    "BLOCKED",
    "EPS",
    "MAX_JUMP",
    "OUTSIDE",
    "axis",
    "cast_ray",
    "cast_start",
    "cast_step",
    "leave",
    "snap",
    "trace_ray",
]

AXIS = 1e-12  # direction components smaller than this are zero
EPS = 1e-12  # pieces of a ray shorter than this (through a cell corner) visit no cell
_HUGE = 1e300  # 1/d of a component that is zero: a crossing that never comes first, and no inf * 0

# the cast mode's padded table (values of the cells; free cells hold their jump, 0 to MAX_JUMP)
BLOCKED = 255
OUTSIDE = 254
MAX_JUMP = 253
_FIX = 4294967296.0  # 2**32: 32.32 fixed point for the jumps


@numba.njit(cache=True, inline="always")
def axis(d: float) -> tuple[int, int, float]:
    """The walk's constants along one axis of direction component ``d``.

    Returns ``(step, ahead, inv)``: the cell step (+1, -1, or 0 along the other axis), the
    offset of the next grid line from the cell's index (1 ahead, 0 behind), and ``1 / d``.
    A component under ``AXIS`` gets a huge finite ``inv``, so its crossing never comes first.
    """
    if d >= AXIS:
        return 1, 1, 1.0 / d
    if d <= -AXIS:
        return -1, 0, 1.0 / d
    return 0, 1, _HUGE


@numba.njit(cache=True, inline="always")
def snap(d: float) -> float:
    """A direction component as the walk takes it: 0 under ``AXIS``, as in :func:`axis`."""
    return 0.0 if -AXIS < d < AXIS else d


@numba.njit(cache=True, inline="always")
def leave(
    cx: np.int64, cy: np.int64, ax: int, ay: int, ox: float, oy: float, ix: float, iy: float
) -> tuple[float, np.int64]:
    """Where the ray from ``(ox, oy)`` leaves cell ``(cx, cy)``: ``(t, across_x)``.

    ``t`` is the nearer of the cell's two crossings ahead. ``across_x`` is 1 if the ray leaves
    across the vertical line. On a tie (through a corner) it crosses the horizontal line
    first. The next cell is ``(cx + sx * across_x, cy + sy * (1 - across_x))``.
    """
    # along a zero component the line is never crossed: not "distance * huge", which is tiny when
    # the origin is a subnormal hair below a grid line (-5e-324), and the walk would stay put
    nx = (cx + ax - ox) * ix if ix < _HUGE else np.inf
    ny = (cy + ay - oy) * iy if iy < _HUGE else np.inf
    return min(nx, ny), np.int64(nx < ny)


# --------------------------------------------------------------------------------------------------
# trace mode


@numba.njit(cache=True, inline="always")
def trace_ray(
    ox: float,
    oy: float,
    dx: float,
    dy: float,
    length: float,
    is_hit: bool,
    crossing: bool,
    rows: int,
    cols: int,
    hits: NDArray[np.int32],
    misses: NDArray[np.int32],
) -> None:
    """Count one beam's misses and its hit in ``hits``/``misses`` ``(rows, cols)``.

    The beam runs from ``(ox, oy)`` along unit ``(dx, dy)`` for ``length`` cells. Every cell it
    crosses before its end is a miss. If ``is_hit``, the cell that holds the end is the hit.
    With ``crossing``, the hit is instead the cell the beam enters at the crossing nearest to
    the end. Cells off the grid are walked through but not counted.
    """
    if not is_hit and length <= 0.0:
        return  # an empty beam crosses no cell
    sx, ax, ix = axis(dx)
    sy, ay, iy = axis(dy)
    cx = np.int64(math.floor(ox))
    cy = np.int64(math.floor(oy))
    t_enter = 0.0  # where the beam entered the current cell
    while True:
        t_next, mi = leave(cx, cy, ax, ay, ox, oy, ix, iy)  # where it leaves the cell
        if t_next - t_enter > EPS:
            inside = 0 <= cx < cols and 0 <= cy < rows
            # past the end: the current cell holds it; with ``crossing`` it is the hit cell only
            # if the beam entered it nearer to the end than where it leaves it
            if is_hit and t_next > length and (not crossing or length - t_enter <= t_next - length):
                if inside:
                    hits[cy, cx] += 1
                return
            if inside:
                misses[cy, cx] += 1
            if not is_hit and t_next >= length:
                return
            t_enter = t_next
        cx += sx * mi
        cy += sy * (1 - mi)


# --------------------------------------------------------------------------------------------------
# cast mode
#
# The table is flat and row-major: the grid's cells shifted by one inside a ring of ``OUTSIDE``
# cells, so a walk always stops on the table and needs no bounds checks. The cast mode walks in
# padded cells: grid cell (cx, cy) is padded cell (cx + 1, cy + 1), at ``(cy + 1) * width + cx +
# 1``, and the grid lines ahead of a padded cell are at offset ``ahead - 1``.


@numba.njit(cache=True, inline="always")
def _entry(
    x0: float, y0: float, dx: float, dy: float, cols: int, rows: int, outside_blocks: bool
) -> tuple[float, int]:
    """Where the ray enters the grid, ``(t0, status)``.

    ``status`` 0: walk from ``t0``; 1: range 0 (origin off the grid, where outside blocks);
    2: the ray misses the grid (outside is empty).
    """
    if 0.0 <= x0 < cols and 0.0 <= y0 < rows:
        return 0.0, 0
    if outside_blocks:
        return 0.0, 1
    # outside is empty: clip the ray to the box [0, cols] x [0, rows] (slab method)
    t0 = 0.0
    t1 = np.inf
    if dx != 0.0:
        a = (0.0 - x0) / dx
        b = (cols - x0) / dx
        t0 = max(t0, min(a, b))
        t1 = min(t1, max(a, b))
    elif not 0.0 <= x0 < cols:
        return 0.0, 2
    if dy != 0.0:
        a = (0.0 - y0) / dy
        b = (rows - y0) / dy
        t0 = max(t0, min(a, b))
        t1 = min(t1, max(a, b))
    elif not 0.0 <= y0 < rows:
        return 0.0, 2
    if t0 >= t1:
        return 0.0, 2
    return t0, 0


@numba.njit(cache=True, inline="always")
def cast_start(
    table: NDArray[np.uint8],
    width: int,
    rows: int,
    cols: int,
    ox: float,
    oy: float,
    dx: float,
    dy: float,
    max_cells: float,
    outside_blocks: bool,
) -> tuple[bool, float, float, np.int64, np.int64, np.int64]:
    """The start of a cast for :func:`cast_step`: ``(done, range, t, cx, cy, v)``.

    The ray starts in padded cell ``(cx, cy)``, of table value ``v``, at ``t``. ``range``
    counts only once ``done``.
    """
    dx = snap(dx)
    dy = snap(dy)
    t, status = _entry(ox, oy, dx, dy, cols, rows, outside_blocks)
    done = status != 0 or t >= max_cells
    res = 0.0 if status == 1 else max_cells
    # the (padded) cell where the ray starts, clamped: where it enters the grid, rounding may
    # put it off
    cx = np.int64(min(max(ox + t * dx, 0.0), cols - 1.0)) + 1
    cy = np.int64(min(max(oy + t * dy, 0.0), rows - 1.0)) + 1
    return done, res, t, cx, cy, np.int64(table[cy * width + cx])


@numba.njit(cache=True, inline="always")
def cast_step(
    table: NDArray[np.uint8],
    width: int,
    ox: float,
    oy: float,
    dx: float,
    dy: float,
    max_cells: float,
    outside_blocks: bool,
    done: bool,
    res: float,
    t: float,
    cx: np.int64,
    cy: np.int64,
    v: np.int64,
    fx: np.int64,
    fy: np.int64,
    fixed: bool,
) -> tuple[bool, float, float, np.int64, np.int64, np.int64, np.int64, np.int64, bool]:
    """One table read of a cast: a jump, or a step to the next cell, as a pure function.

    The ray is in padded cell ``(cx, cy)`` at ``t`` (where it entered the cell, or where a jump
    landed) and ``v`` is the cell's table value. Along a run of jumps (``fixed``), ``(fx, fy)``
    is the ray's position in fixed point. ``(dx, dy)`` is the direction as :func:`snap` gives it,
    so that a jump along a grid line stays on the side the steps take. Returns the next state,
    with ``done`` and the range once the cast ends. A blocking cell that the ray only clips at a
    corner (for less than ``EPS``) is stepped through, as in trace mode.

    Because the step is pure, :func:`tourbot.maps.raycast.cast_rays_kernel` can advance four rays
    in turn. Their table reads do not depend on each other, so the CPU overlaps them.
    """
    if 0 < v < OUTSIDE:  # a safe jump, in fixed point
        if not fixed:  # padded coordinates: positive, so >> 32 is floor
            fx = np.int64((ox + 1.0 + t * dx) * _FIX)
            fy = np.int64((oy + 1.0 + t * dy) * _FIX)
            fixed = True
        t += v
        fx += v * np.int64(dx * _FIX)
        fy += v * np.int64(dy * _FIX)
        cx = fx >> 32
        cy = fy >> 32
    else:
        sx, ax, ix = axis(dx)
        sy, ay, iy = axis(dy)
        t_exit, mi = leave(cx, cy, ax - 1, ay - 1, ox, oy, ix, iy)
        if v >= OUTSIDE and (fixed or t_exit - t > EPS):  # the end
            res = t if (v == BLOCKED or outside_blocks) else max_cells
            return True, res, t, cx, cy, v, fx, fy, fixed
        # a step across the nearer grid line
        fixed = False
        t = t_exit
        cx += sx * mi
        cy += sy * (1 - mi)
    if t >= max_cells:
        return True, max_cells, t, cx, cy, v, fx, fy, fixed
    v = np.int64(table[cy * width + cx])
    return done, res, t, cx, cy, v, fx, fy, fixed


@numba.njit(cache=True, inline="always")
def cast_ray(
    table: NDArray[np.uint8],
    width: int,
    rows: int,
    cols: int,
    ox: float,
    oy: float,
    dx: float,
    dy: float,
    max_cells: float,
    outside_blocks: bool,
) -> float:
    """Range in cells of one ray from ``(ox, oy)`` along unit ``(dx, dy)`` on a padded table.

    ``max_cells`` if nothing blocks before ``max_cells``. Off the grid counts as blocking if
    ``outside_blocks``, else as empty.
    """
    dx = snap(dx)
    dy = snap(dy)
    done, res, t, cx, cy, v = cast_start(table, width, rows, cols, ox, oy, dx, dy, max_cells, outside_blocks)
    fx = np.int64(0)
    fy = np.int64(0)
    fixed = False
    while not done:
        done, res, t, cx, cy, v, fx, fy, fixed = cast_step(
            table, width, ox, oy, dx, dy, max_cells, outside_blocks,
            done, res, t, cx, cy, v, fx, fy, fixed,
        )  # fmt: skip
    return res
