"""The crowd of museum visitors: a pure, step-able social-force model shared by the simulator and
the crowd overlay on real logs.

Visitors walk the free space of an :class:`~tourbot.maps.grid.OccupancyGrid` at their own preferred
speed (0.5-1.5 m/s), avoid walls and each other with the social-force model of Helbing & Molnár
(1995, Phys. Rev. E 51, Eq. 1-5: driving term, exponential repulsion from other people and from
walls), wander between points in view or visit points of interest (exhibits) where they dwell, in
small groups, and, as in the crowded museum experiments of Fox, Burgard, Thrun & Cremers (1998,
"Position estimation for mobile robots in dynamic environments", Sec. "Experimental results",
Fig. 1a), many of them are drawn to the robot and stand around it for minutes. The laser sees each
visitor as two legs at sensor height (circles that swing with a walking gait) or, if configured,
as one body circle: :meth:`Crowd.legs` and :meth:`Crowd.circles`.

Everything random is drawn from the ``numpy.random.Generator`` given to the constructor and to
:meth:`Crowd.step`, so a crowd is deterministic for a seed. The hot loops (pairwise social forces,
line-of-sight tests) are numba kernels, each with a plain-numpy/Python reference beside it for the
property tests; the geodesic distance field used to walk around walls is the one grid Dijkstra
(:func:`tourbot.maps.dijkstra.grid_dijkstra`).

Internally positions are kept in the grid frame (metres, the frame of cell ``(0, 0)``'s corner);
the public API speaks world coordinates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from tourbot.errors import TourbotError
from tourbot.geometry import compose, invert, transform_points, wrap_angle
from tourbot.maps.dijkstra import grid_dijkstra, unit_costs
from tourbot.maps.grid import OccupancyGrid

__all__ = [
    "PRESETS",
    "Crowd",
    "CrowdConfig",
    "CrowdError",
    "line_of_sight",
    "line_of_sight_reference",
    "move_people",
    "move_people_reference",
    "social_forces",
    "social_forces_reference",
    "steer",
    "steer_reference",
]

FloatArray = NDArray[np.float64]

# Visitor activity: walking to a goal, dwelling at it, or drawn to the robot.
WALK, DWELL, ROBOT = 0, 1, 2

PresetName = Literal["empty", "sparse", "peak"]


class CrowdError(TourbotError):
    """A crowd that cannot be built as asked (no free space, bad parameters)."""


@dataclass(frozen=True)
class CrowdConfig:
    """Every parameter of the crowd, with its source.

    Speeds: preferred walking speeds uniform in ``[speed_min, speed_max]`` = 0.5-1.5 m/s (issue 3
    §2; Helbing & Molnár 1995 use a mean of 1.34 m/s, sd 0.26). Social force (Helbing & Molnár
    1995, Eq. 3-5, per unit mass): relaxation time ``tau`` = 0.5 s, person-person potential
    ``social_strength`` = 2.0 m²/s² over ``social_range`` = 0.08 m (Helbing, Farkas & Vicsek
    2000), wall potential
    ``wall_strength`` U0 = 10 m²/s² over ``wall_range`` R = 0.2 m. Attraction to the robot
    (Fox et al. 1998, Fig. 1a: visitors surround the robot): in the long run a fraction
    ``robot_interest`` of the visitor groups stands around the robot, each for
    ``interest_duration`` seconds on average, at ``stand_distance`` metres inside an arc of
    ``±stand_arc`` radians in front of it (where its screen and face are); only visitors within
    ``notice_distance`` metres who can see the robot become interested, and those left farther
    than ``field_max_distance`` behind lose interest. Legs at sensor height:
    radius 5-8 cm, 20 cm apart, swinging ``leg_swing`` metres with a gait cycle of
    ``stride_length`` metres.
    """

    num_people: int = 40
    # People per square metre of walkable space; when set, it overrides ``num_people``.
    density: float | None = None
    speed_min: float = 0.5
    speed_max: float = 1.5
    # Helbing & Molnár 1995, Eq. 2-5 (per unit mass); the person-person term with the short range
    # of Helbing, Farkas & Vicsek 2000 (A = 2000 N over B = 0.08 m for 80 kg: A·B/m = 2.0 m²/s²),
    # which lets visitors pack as closely around the robot as real ones do.
    tau: float = 0.5
    social_strength: float = 2.0
    social_range: float = 0.08
    wall_strength: float = 10.0
    wall_range: float = 0.2
    person_radius: float = 0.25
    # The robot as an obstacle people keep clear of (RHINO/TOURBOT robots are ~0.5-0.6 m wide).
    robot_radius: float = 0.4
    robot_strength: float = 10.0
    robot_range: float = 0.2
    # Interest in the robot (Fox et al. 1998, Fig. 1a).
    robot_interest: float = 0.3
    interest_duration: float = 120.0
    notice_distance: float = 10.0
    stand_distance: tuple[float, float] = (0.6, 1.6)
    stand_arc: float = math.radians(90.0)
    # Where visitors go when not at the robot.
    points_of_interest: tuple[tuple[float, float], ...] = ()
    poi_probability: float = 0.5
    dwell_time: tuple[float, float] = (3.0, 30.0)
    wander_distance: tuple[float, float] = (2.0, 12.0)
    group_size_max: int = 3
    group_cohesion: float = 0.5
    # What the laser sees.
    target: Literal["legs", "body"] = "legs"
    leg_radius: tuple[float, float] = (0.05, 0.08)
    hip_half_width: float = 0.1
    leg_swing: float = 0.15
    stride_length: float = 1.3
    body_radius: float = 0.22
    # Numerics.
    max_substep: float = 0.1
    field_resolution: float = 0.3
    decision_period: float = 0.5
    field_max_distance: float = 30.0

    def __post_init__(self) -> None:
        checks = [
            (self.num_people >= 0, "num_people must be >= 0"),
            (self.density is None or self.density >= 0.0, "density must be >= 0"),
            (0.0 < self.speed_min <= self.speed_max, "need 0 < speed_min <= speed_max"),
            (0.0 <= self.robot_interest <= 1.0, "robot_interest must be in [0, 1]"),
            (0.0 <= self.poi_probability <= 1.0, "poi_probability must be in [0, 1]"),
            (self.interest_duration > 0.0, "interest_duration must be positive"),
            (self.tau > 0.0 and self.max_substep > 0.0, "tau and max_substep must be positive"),
            (self.group_size_max >= 1, "group_size_max must be >= 1"),
            (0.0 < self.stand_distance[0] <= self.stand_distance[1], "bad stand_distance"),
            (0.0 < self.wander_distance[0] <= self.wander_distance[1], "bad wander_distance"),
            (0.0 <= self.dwell_time[0] <= self.dwell_time[1], "bad dwell_time"),
            (self.target in ("legs", "body"), "target must be 'legs' or 'body'"),
        ]
        for ok, message in checks:
            if not ok:
                raise CrowdError(f"crowd config: {message}")

    @classmethod
    def preset(cls, name: str, **overrides: object) -> CrowdConfig:
        """One of :data:`PRESETS` (``empty``, ``sparse``, ``peak``), with fields overridden."""
        if name not in PRESETS:
            raise CrowdError(f"unknown crowd preset {name!r}; choose one of {', '.join(PRESETS)}")
        return replace(PRESETS[name], **overrides)  # type: ignore[arg-type]


# The paper's two datasets (Fox et al. 1998, Sec. "Experimental results", Fig. 4): "sparse" is the
# museum closed (a few % of the beams corrupted), "peak" the most crowded day at peak hours (on
# average >= 40 % corrupted, stretches above 50 % lasting minutes). Densities and interest were
# calibrated with `tourbot crowd` on the FHW log over its reference map (docs/results.md,
# "Crowd presets"): sparse gives ~2-3 % of the beams corrupted, peak ~45 %.
PRESETS: dict[str, CrowdConfig] = {
    "empty": CrowdConfig(num_people=0, robot_interest=0.0),
    "sparse": CrowdConfig(density=0.015, robot_interest=0.1, interest_duration=30.0),
    "peak": CrowdConfig(density=0.25, robot_interest=0.85, notice_distance=15.0, interest_duration=300.0),
}


# --------------------------------------------------------------------------------------------
# Kernels (numba) and their references
# --------------------------------------------------------------------------------------------


@numba.njit(cache=True)
def social_forces(pos: FloatArray, radius: FloatArray, strength: float, scale: float) -> FloatArray:
    """Pairwise repulsion between people, ``(N, 2)`` accelerations.

    Helbing & Molnár 1995, Eq. 3 in its common circular form: person ``j`` pushes ``i`` along
    ``n_ij = (x_i - x_j)/d_ij`` with magnitude ``(V0/σ) exp((r_i + r_j - d_ij)/σ)``.
    """
    n = pos.shape[0]
    out = np.zeros((n, 2))
    cutoff = 8.0 * scale
    for i in range(n):
        for j in range(i + 1, n):
            dx = pos[i, 0] - pos[j, 0]
            dy = pos[i, 1] - pos[j, 1]
            reach = cutoff + radius[i] + radius[j]
            d2 = dx * dx + dy * dy
            if d2 > reach * reach:
                continue
            d = math.sqrt(d2)
            gap = d - radius[i] - radius[j]
            if d < 1e-9:
                # Coincident people: push apart along a fixed, index-dependent direction.
                dx, dy, d = math.cos(i - j), math.sin(i - j), 1.0
            mag = strength / scale * math.exp(-gap / scale)
            fx = mag * dx / d
            fy = mag * dy / d
            out[i, 0] += fx
            out[i, 1] += fy
            out[j, 0] -= fx
            out[j, 1] -= fy
    return out


def social_forces_reference(pos: FloatArray, radius: FloatArray, strength: float, scale: float) -> FloatArray:
    """Plain-numpy :func:`social_forces` (all pairs, same cutoff) for the property tests."""
    diff = pos[:, None, :] - pos[None, :, :]
    d = np.linalg.norm(diff, axis=-1)
    gap = d - radius[:, None] - radius[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = diff / d[..., None]
    mag = strength / scale * np.exp(-gap / scale)
    mask = (gap <= 8.0 * scale) & ~np.eye(len(pos), dtype=bool) & (d >= 1e-9)
    return np.asarray(np.sum(np.where(mask[..., None], mag[..., None] * unit, 0.0), axis=1))


@numba.njit(cache=True)
def line_of_sight(walkable: NDArray[np.bool_], res: float, a: FloatArray, b: FloatArray) -> NDArray[np.bool_]:
    """Whether the straight segment ``a[k] -> b[k]`` (grid-frame metres) stays on walkable cells.

    Samples the segment every quarter cell; points outside the grid are not walkable.
    """
    rows, cols = walkable.shape
    out = np.empty(a.shape[0], dtype=np.bool_)
    for k in range(a.shape[0]):
        dx = b[k, 0] - a[k, 0]
        dy = b[k, 1] - a[k, 1]
        steps = math.ceil(math.sqrt(dx * dx + dy * dy) / (0.25 * res)) + 1
        ok = True
        for s in range(steps + 1):
            t = s / steps
            c = math.floor((a[k, 0] + t * dx) / res)
            r = math.floor((a[k, 1] + t * dy) / res)
            if r < 0 or r >= rows or c < 0 or c >= cols or not walkable[r, c]:
                ok = False
                break
        out[k] = ok
    return out


def line_of_sight_reference(
    walkable: NDArray[np.bool_], res: float, a: FloatArray, b: FloatArray
) -> NDArray[np.bool_]:
    """Plain-numpy :func:`line_of_sight` for the property tests."""
    out = np.empty(len(a), dtype=bool)
    for k in range(len(a)):
        length = float(np.hypot(*(b[k] - a[k])))
        steps = math.ceil(length / (0.25 * res)) + 1
        t = np.arange(steps + 1) / steps
        pts = a[k] + t[:, None] * (b[k] - a[k])
        cells = np.floor(pts / res).astype(np.int64)
        inside = (
            (cells[:, 1] >= 0)
            & (cells[:, 1] < walkable.shape[0])
            & (cells[:, 0] >= 0)
            & (cells[:, 0] < walkable.shape[1])
        )
        out[k] = bool(inside.all() and walkable[cells[:, 1], cells[:, 0]].all())
    return out


@numba.njit(cache=True)
def steer(
    pos: FloatArray,
    target: FloatArray,
    moving: NDArray[np.bool_],
    in_view: NDArray[np.bool_],
    field_index: NDArray[np.int64],
    fields: FloatArray,
    coarse_res: float,
    speed: FloatArray,
    tau: float,
) -> FloatArray:
    """Desired velocities ``(N, 2)``: towards the target when it is in view, else down the
    geodesic field ``fields[field_index[i]]`` (none when the index is negative); slowing down to
    arrive within about ``tau`` (Helbing & Molnár 1995, Eq. 2: ``v0 e`` with ``e`` the direction
    of the route)."""
    n = pos.shape[0]
    _, rows, cols = fields.shape
    out = np.zeros((n, 2))
    for i in range(n):
        if not moving[i]:
            continue
        dx = target[i, 0] - pos[i, 0]
        dy = target[i, 1] - pos[i, 1]
        dist = math.sqrt(dx * dx + dy * dy)
        want = min(speed[i], dist / (2.0 * tau))
        ex = 0.0
        ey = 0.0
        if in_view[i]:
            if dist > 1e-9:
                ex = dx / dist
                ey = dy / dist
        elif field_index[i] >= 0:
            f = field_index[i]
            c0 = math.floor(pos[i, 0] / coarse_res)
            r0 = math.floor(pos[i, 1] / coarse_res)
            best = np.inf
            br = -1
            bc = -1
            for dr in range(-1, 2):
                for dc in range(-1, 2):
                    r = r0 + dr
                    c = c0 + dc
                    if 0 <= r < rows and 0 <= c < cols and fields[f, r, c] < best:
                        best = fields[f, r, c]
                        br = r
                        bc = c
            if br >= 0 and math.isfinite(best):
                gx = (bc + 0.5) * coarse_res - pos[i, 0]
                gy = (br + 0.5) * coarse_res - pos[i, 1]
                g = math.sqrt(gx * gx + gy * gy)
                if g > 1e-9:
                    ex = gx / g
                    ey = gy / g
        out[i, 0] = want * ex
        out[i, 1] = want * ey
    return out


def steer_reference(
    pos: FloatArray,
    target: FloatArray,
    moving: NDArray[np.bool_],
    in_view: NDArray[np.bool_],
    field_index: NDArray[np.int64],
    fields: FloatArray,
    coarse_res: float,
    speed: FloatArray,
    tau: float,
) -> FloatArray:
    """Plain-numpy :func:`steer` for the property tests."""
    to_target = target - pos
    dist = np.hypot(to_target[:, 0], to_target[:, 1])
    direction = np.where(dist[:, None] > 1e-9, to_target / np.maximum(dist, 1e-9)[:, None], 0.0)
    _, rows, cols = fields.shape
    cells = np.floor(pos / coarse_res).astype(np.int64)  # (N, 2) as (col, row)
    for i in np.flatnonzero(~in_view & (field_index >= 0)):
        r0, c0 = int(cells[i, 1]), int(cells[i, 0])
        window = np.full((3, 3), np.inf)
        for dr in range(3):
            for dc in range(3):
                r, c = r0 + dr - 1, c0 + dc - 1
                if 0 <= r < rows and 0 <= c < cols:
                    window[dr, dc] = fields[field_index[i], r, c]
        k = int(np.argmin(window))
        best = window.flat[k]
        direction[i] = 0.0
        if np.isfinite(best):
            g = (np.array([c0 + k % 3 - 1, r0 + k // 3 - 1]) + 0.5) * coarse_res - pos[i]
            norm = float(np.hypot(g[0], g[1]))
            if norm > 1e-9:
                direction[i] = g / norm
    direction[~in_view & (field_index < 0)] = 0.0
    want = np.where(moving, np.minimum(speed, dist / (2.0 * tau)), 0.0)
    return np.asarray(direction * want[:, None])


# Parameters of move_people, in this order (see CrowdConfig).
_P_TAU, _P_RADIUS, _P_SOC_A, _P_SOC_B, _P_WALL_A, _P_WALL_B = 0, 1, 2, 3, 4, 5
_P_ROBOT_R, _P_ROBOT_A, _P_ROBOT_B, _P_COHESION, _P_STRIDE = 6, 7, 8, 9, 10


@numba.njit(cache=True)
def move_people(
    pos: FloatArray,
    vel: FloatArray,
    desired: FloatArray,
    cap: FloatArray,
    group: NDArray[np.int64],
    at_robot: NDArray[np.bool_],
    phase: FloatArray,
    heading: FloatArray,
    wall_dist: FloatArray,
    wall_dir: FloatArray,
    res: float,
    walkable: NDArray[np.bool_],
    coarse_res: float,
    robot_x: float,
    robot_y: float,
    params: FloatArray,
    h: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """One explicit-Euler step of the social-force model for everyone: new (pos, vel, phase, heading).

    Acceleration (Helbing & Molnár 1995, Eq. 1-5, per unit mass): relaxation to the desired
    velocity over ``tau``; exponential repulsion from other people, from the nearest wall (the
    distance transform of the map) and from the robot; a pull towards the group's leader when
    more than 1.5 m away. Speeds are capped at ``cap``. Then hard constraints: a person closer
    than half a radius to a wall is pushed out, one who would leave the walkable space stays
    where they were (and stops), nobody enters the robot. Legs advance their gait phase with the
    distance walked; walkers face where they go, visitors standing at the robot face it.
    """
    n = pos.shape[0]
    tau = params[_P_TAU]
    radius = params[_P_RADIUS]
    rows, cols = wall_dist.shape
    crows, ccols = walkable.shape
    acc = np.empty((n, 2))
    for i in range(n):
        acc[i, 0] = (desired[i, 0] - vel[i, 0]) / tau
        acc[i, 1] = (desired[i, 1] - vel[i, 1]) / tau
    radii = np.full(n, radius)
    acc += social_forces(pos, radii, params[_P_SOC_A], params[_P_SOC_B])
    new_pos = np.empty((n, 2))
    new_vel = np.empty((n, 2))
    new_phase = np.empty(n)
    new_heading = np.empty(n)
    min_gap = params[_P_ROBOT_R] + 0.5 * radius
    for i in range(n):
        # Wall.
        c = min(max(math.floor(pos[i, 0] / res), 0), cols - 1)
        r = min(max(math.floor(pos[i, 1] / res), 0), rows - 1)
        mag = (
            params[_P_WALL_A] / params[_P_WALL_B] * math.exp(-(wall_dist[r, c] - radius) / params[_P_WALL_B])
        )
        ax = acc[i, 0] + mag * wall_dir[r, c, 0]
        ay = acc[i, 1] + mag * wall_dir[r, c, 1]
        # Robot.
        rx = pos[i, 0] - robot_x
        ry = pos[i, 1] - robot_y
        rd = max(math.sqrt(rx * rx + ry * ry), 1e-9)
        gap = rd - params[_P_ROBOT_R] - radius
        mag = params[_P_ROBOT_A] / params[_P_ROBOT_B] * math.exp(-gap / params[_P_ROBOT_B]) / rd
        ax += mag * rx
        ay += mag * ry
        # Group cohesion.
        lx = pos[group[i], 0] - pos[i, 0]
        ly = pos[group[i], 1] - pos[i, 1]
        if math.sqrt(lx * lx + ly * ly) > 1.5:
            ax += params[_P_COHESION] * lx
            ay += params[_P_COHESION] * ly
        # Integrate with a speed cap.
        vx = vel[i, 0] + h * ax
        vy = vel[i, 1] + h * ay
        sp = math.sqrt(vx * vx + vy * vy)
        scale = min(1.0, cap[i] / max(sp, 1e-9))
        vx *= scale
        vy *= scale
        px = pos[i, 0] + h * vx
        py = pos[i, 1] + h * vy
        # Out of the walls.
        c = min(max(math.floor(px / res), 0), cols - 1)
        r = min(max(math.floor(py / res), 0), rows - 1)
        if wall_dist[r, c] < 0.5 * radius:
            push = 0.5 * radius - wall_dist[r, c]
            px += push * wall_dir[r, c, 0]
            py += push * wall_dir[r, c, 1]
        # Never leave the walkable space.
        oc = math.floor(pos[i, 0] / coarse_res)
        orr = math.floor(pos[i, 1] / coarse_res)
        nc = math.floor(px / coarse_res)
        nr = math.floor(py / coarse_res)
        was_ok = 0 <= orr < crows and 0 <= oc < ccols and walkable[orr, oc]
        now_ok = 0 <= nr < crows and 0 <= nc < ccols and walkable[nr, nc]
        if was_ok and not now_ok:
            # Slide along the blocked side: keep the one coordinate that stays walkable.
            if 0 <= orr < crows and 0 <= nc < ccols and walkable[orr, nc]:
                py = pos[i, 1]
                vy = 0.0
            elif 0 <= nr < crows and 0 <= oc < ccols and walkable[nr, oc]:
                px = pos[i, 0]
                vx = 0.0
            else:
                px = pos[i, 0]
                py = pos[i, 1]
                vx = 0.0
                vy = 0.0
        # Not into the robot.
        rx = px - robot_x
        ry = py - robot_y
        rd = max(math.sqrt(rx * rx + ry * ry), 1e-9)
        if rd < min_gap:
            px = robot_x + rx / rd * min_gap
            py = robot_y + ry / rd * min_gap
        # Gait and heading.
        sp = math.sqrt(vx * vx + vy * vy)
        new_phase[i] = (phase[i] + 2.0 * math.pi * sp * h / params[_P_STRIDE]) % (2.0 * math.pi)
        if sp > 0.1:
            new_heading[i] = math.atan2(vy, vx)
        elif at_robot[i]:
            new_heading[i] = math.atan2(robot_y - py, robot_x - px)
        else:
            new_heading[i] = heading[i]
        new_pos[i, 0] = px
        new_pos[i, 1] = py
        new_vel[i, 0] = vx
        new_vel[i, 1] = vy
    return new_pos, new_vel, new_phase, new_heading


def move_people_reference(
    pos: FloatArray,
    vel: FloatArray,
    desired: FloatArray,
    cap: FloatArray,
    group: NDArray[np.int64],
    at_robot: NDArray[np.bool_],
    phase: FloatArray,
    heading: FloatArray,
    wall_dist: FloatArray,
    wall_dir: FloatArray,
    res: float,
    walkable: NDArray[np.bool_],
    coarse_res: float,
    robot_x: float,
    robot_y: float,
    params: FloatArray,
    h: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Plain-numpy :func:`move_people` for the property tests."""
    tau, radius = params[_P_TAU], params[_P_RADIUS]
    robot = np.array([robot_x, robot_y])

    def wall(points: FloatArray) -> tuple[FloatArray, FloatArray]:
        c = np.clip(np.floor(points[:, 0] / res).astype(np.int64), 0, wall_dist.shape[1] - 1)
        r = np.clip(np.floor(points[:, 1] / res).astype(np.int64), 0, wall_dist.shape[0] - 1)
        return wall_dist[r, c], wall_dir[r, c]

    def is_walkable(points: FloatArray) -> NDArray[np.bool_]:
        c = np.floor(points[:, 0] / coarse_res).astype(np.int64)
        r = np.floor(points[:, 1] / coarse_res).astype(np.int64)
        inside = (r >= 0) & (r < walkable.shape[0]) & (c >= 0) & (c < walkable.shape[1])
        out = np.zeros(len(points), dtype=bool)
        out[inside] = walkable[r[inside], c[inside]]
        return out

    acc = (desired - vel) / tau
    acc += social_forces_reference(pos, np.full(len(pos), radius), params[_P_SOC_A], params[_P_SOC_B])
    wd, wn = wall(pos)
    acc += (params[_P_WALL_A] / params[_P_WALL_B] * np.exp(-(wd - radius) / params[_P_WALL_B]))[:, None] * wn
    rel = pos - robot
    rd = np.maximum(np.linalg.norm(rel, axis=-1), 1e-9)
    gap = rd - params[_P_ROBOT_R] - radius
    acc += (params[_P_ROBOT_A] / params[_P_ROBOT_B] * np.exp(-gap / params[_P_ROBOT_B]) / rd)[:, None] * rel
    to_lead = pos[group] - pos
    acc += params[_P_COHESION] * np.where(np.linalg.norm(to_lead, axis=-1, keepdims=True) > 1.5, to_lead, 0.0)

    new_vel = vel + h * acc
    speed = np.linalg.norm(new_vel, axis=-1)
    new_vel *= np.minimum(1.0, cap / np.maximum(speed, 1e-9))[:, None]
    new_pos = pos + h * new_vel
    nd, nn = wall(new_pos)
    inside = nd < 0.5 * radius
    new_pos = np.where(inside[:, None], new_pos + (0.5 * radius - nd)[:, None] * nn, new_pos)
    bad = ~is_walkable(new_pos) & is_walkable(pos)
    keep_x = bad & is_walkable(np.stack([new_pos[:, 0], pos[:, 1]], axis=-1))
    keep_y = bad & ~keep_x & is_walkable(np.stack([pos[:, 0], new_pos[:, 1]], axis=-1))
    stop = bad & ~keep_x & ~keep_y
    new_pos[keep_x, 1] = pos[keep_x, 1]
    new_vel[keep_x, 1] = 0.0
    new_pos[keep_y, 0] = pos[keep_y, 0]
    new_vel[keep_y, 0] = 0.0
    new_pos[stop] = pos[stop]
    new_vel[stop] = 0.0
    rel = new_pos - robot
    rd = np.maximum(np.linalg.norm(rel, axis=-1), 1e-9)
    min_gap = params[_P_ROBOT_R] + 0.5 * radius
    close = rd < min_gap
    new_pos = np.where(close[:, None], robot + rel / rd[:, None] * min_gap, new_pos)
    speed = np.linalg.norm(new_vel, axis=-1)
    new_phase = np.mod(phase + 2.0 * np.pi * speed * h / params[_P_STRIDE], 2.0 * np.pi)
    face_robot = np.arctan2(robot_y - new_pos[:, 1], robot_x - new_pos[:, 0])
    new_heading = np.where(
        speed > 0.1, np.arctan2(new_vel[:, 1], new_vel[:, 0]), np.where(at_robot, face_robot, heading)
    )
    return new_pos, new_vel, new_phase, new_heading


# --------------------------------------------------------------------------------------------
# The walkable space of a map
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Space:
    """Where people can be: wall distances on the map grid, walkable cells on a coarser grid."""

    res: float  # map resolution
    wall_dist: NDArray[np.float64]  # (R, C) metres to the nearest non-free cell
    wall_dir: NDArray[np.float64]  # (R, C, 2) unit vectors pointing away from it (grid frame)
    coarse_res: float
    walkable: NDArray[np.bool_]  # (Rc, Cc)
    free_cells: NDArray[np.int64]  # (K, 2) walkable coarse (row, col)

    @classmethod
    def from_grid(cls, grid: OccupancyGrid, clearance: float, coarse_res: float) -> _Space:
        blocked = ~grid.free()
        dist, idx = ndimage.distance_transform_edt(~blocked, return_indices=True)
        rows, cols = np.indices(blocked.shape)
        away = np.stack([cols - idx[1], rows - idx[0]], axis=-1).astype(np.float64)
        norm = np.linalg.norm(away, axis=-1, keepdims=True)
        away = np.divide(away, norm, out=np.zeros_like(away), where=norm > 0)
        # Distances from cell centre to the nearest blocked cell's boundary (half a cell less).
        wall_dist = np.maximum(dist * grid.resolution - 0.5 * grid.resolution, 0.0)
        k = max(1, round(coarse_res / grid.resolution))
        cres = k * grid.resolution
        rc, cc = blocked.shape[0] // k, blocked.shape[1] // k
        centres = wall_dist[k // 2 : rc * k : k, k // 2 : cc * k : k][:rc, :cc]
        walkable = np.ascontiguousarray(centres >= clearance)
        return cls(
            res=grid.resolution,
            wall_dist=wall_dist,
            wall_dir=away,
            coarse_res=cres,
            walkable=walkable,
            free_cells=np.argwhere(walkable),
        )

    def wall(self, pos: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Distance to the nearest wall and the unit vector away from it, for points (N, 2)."""
        rows, cols = self.wall_dist.shape
        c = np.clip(np.floor(pos[:, 0] / self.res).astype(np.int64), 0, cols - 1)
        r = np.clip(np.floor(pos[:, 1] / self.res).astype(np.int64), 0, rows - 1)
        return self.wall_dist[r, c], self.wall_dir[r, c]

    def is_walkable(self, pos: FloatArray) -> NDArray[np.bool_]:
        rows, cols = self.walkable.shape
        c = np.floor(pos[:, 0] / self.coarse_res).astype(np.int64)
        r = np.floor(pos[:, 1] / self.coarse_res).astype(np.int64)
        inside = (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
        out = np.zeros(len(pos), dtype=bool)
        out[inside] = self.walkable[r[inside], c[inside]]
        return out

    def field_to(self, point: FloatArray, max_distance: float) -> FloatArray:
        r = math.floor(point[1] / self.coarse_res)
        c = math.floor(point[0] / self.coarse_res)
        r, c = self._nearest_walkable(r, c)
        return grid_dijkstra(unit_costs(self.walkable), r, c, max_distance / self.coarse_res)

    def _nearest_walkable(self, r: int, c: int) -> tuple[int, int]:
        rows, cols = self.walkable.shape
        if 0 <= r < rows and 0 <= c < cols and self.walkable[r, c]:
            return r, c
        d2 = (self.free_cells[:, 0] - r) ** 2 + (self.free_cells[:, 1] - c) ** 2
        best = self.free_cells[int(np.argmin(d2))]
        return int(best[0]), int(best[1])


# --------------------------------------------------------------------------------------------
# The crowd
# --------------------------------------------------------------------------------------------


@dataclass
class _People:
    pos: FloatArray
    vel: FloatArray
    heading: FloatArray
    speed: FloatArray  # preferred speed
    mode: NDArray[np.int64]
    goal: FloatArray
    goal_poi: NDArray[np.int64]  # index of the point of interest walked to, -1 for none
    timer: FloatArray  # dwell time left, s
    interested: NDArray[np.bool_]
    stand: FloatArray  # (N, 2) polar (distance, bearing) of the standing spot, robot frame
    phase: FloatArray  # gait phase, rad
    leg_radius: FloatArray  # (N, 2)
    group: NDArray[np.int64]  # index of the group's leader


class Crowd:
    """Visitors walking in a map's free space; step it with the robot's pose.

    ``Crowd(config, grid, rng, robot_pose)`` spawns ``config.num_people`` visitors in groups in
    the free space, clear of the robot. :meth:`step` advances them by ``dt`` seconds (in substeps
    of at most ``config.max_substep``; the robot is taken to be at ``robot_pose`` throughout, so
    callers with a moving robot step at their own rate). :meth:`legs` gives what a laser at leg
    height hits.
    """

    def __init__(
        self,
        config: CrowdConfig,
        grid: OccupancyGrid,
        rng: np.random.Generator,
        robot_pose: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        self.config = config
        self.grid = grid
        self.time = 0.0
        # People may brush past furniture: walkable cells keep half a body radius from obstacles.
        self._space = _Space.from_grid(grid, 0.5 * config.person_radius, config.field_resolution)
        area = len(self._space.free_cells) * self._space.coarse_res**2
        self._count = config.num_people if config.density is None else round(config.density * area)
        if self._count > 0 and len(self._space.free_cells) == 0:
            raise CrowdError("the map has no free space wide enough for a person")
        self._robot = self._local_pose(robot_pose)
        self._poi = np.array(
            [self._local_point(p) for p in config.points_of_interest], dtype=np.float64
        ).reshape(-1, 2)
        # Geodesic fields: 0 to the robot (computed when needed), 1.. to the exhibits.
        self._fields = np.full((1 + len(self._poi), *self._space.walkable.shape), np.inf)
        for j, poi in enumerate(self._poi):
            self._fields[1 + j] = self._space.field_to(poi, config.field_max_distance * 4.0)
        self._field_robot_at = np.array([np.inf, np.inf])
        self._people = self._spawn(rng)
        self._in_view = np.zeros(self.num_people, dtype=bool)
        self._last_decision = 0.0
        self._next_decision = 0.0
        self._params = np.array(
            [
                config.tau,
                config.person_radius,
                config.social_strength,
                config.social_range,
                config.wall_strength,
                config.wall_range,
                config.robot_radius,
                config.robot_strength,
                config.robot_range,
                config.group_cohesion,
                config.stride_length,
            ]
        )

    # ---- frames ------------------------------------------------------------------------------

    def _local_pose(self, pose: ArrayLike) -> FloatArray:
        return compose(invert(self.grid.origin), np.asarray(pose, dtype=np.float64))

    def _local_point(self, point: ArrayLike) -> FloatArray:
        return transform_points(invert(self.grid.origin), np.asarray(point, dtype=np.float64))

    def _to_world(self, points: FloatArray) -> FloatArray:
        return transform_points(self.grid.origin, points)

    def _vec_to_world(self, vectors: FloatArray) -> FloatArray:
        th = self.grid.origin[2]
        c, s = math.cos(th), math.sin(th)
        return np.stack(
            [c * vectors[:, 0] - s * vectors[:, 1], s * vectors[:, 0] + c * vectors[:, 1]], axis=-1
        )

    # ---- public state ------------------------------------------------------------------------

    @property
    def num_people(self) -> int:
        return len(self._people.pos)

    @property
    def positions(self) -> FloatArray:
        """Centres of the visitors in the world, ``(N, 2)``."""
        return self._to_world(self._people.pos)

    @property
    def velocities(self) -> FloatArray:
        """Velocities in the world, ``(N, 2)`` m/s."""
        return self._vec_to_world(self._people.vel)

    @property
    def headings(self) -> FloatArray:
        """Facing directions in the world, ``(N,)`` rad."""
        return np.asarray(wrap_angle(self._people.heading + self.grid.origin[2]))

    @property
    def at_robot(self) -> NDArray[np.bool_]:
        """Which visitors are currently drawn to the robot, ``(N,)``."""
        return self._people.mode == ROBOT

    def legs(self) -> tuple[FloatArray, FloatArray]:
        """Two legs per person at sensor height: world centres ``(2N, 2)`` and radii ``(2N,)``.

        Legs ``2i`` and ``2i+1`` belong to person ``i``; they sit ``hip_half_width`` either side
        of the body and swing ``± leg_swing · sin(phase)`` along the heading while walking.
        """
        p = self._people
        cfg = self.config
        fwd = np.stack([np.cos(p.heading), np.sin(p.heading)], axis=-1)
        side = np.stack([-fwd[:, 1], fwd[:, 0]], axis=-1)
        speed = np.linalg.norm(p.vel, axis=-1)
        swing = (cfg.leg_swing * np.sin(p.phase) * np.minimum(1.0, speed / 0.5))[:, None]
        left = p.pos + cfg.hip_half_width * side + swing * fwd
        right = p.pos - cfg.hip_half_width * side - swing * fwd
        centres = np.stack([left, right], axis=1).reshape(-1, 2)
        return self._to_world(centres), p.leg_radius.reshape(-1).copy()

    def circles(self) -> tuple[FloatArray, FloatArray]:
        """What the laser sees, per ``config.target``: :meth:`legs`, or one body circle each."""
        if self.config.target == "legs":
            return self.legs()
        n = self.num_people
        return self.positions, np.full(n, self.config.body_radius)

    # ---- spawning ----------------------------------------------------------------------------

    def _random_free_points(self, rng: np.random.Generator, n: int) -> FloatArray:
        cells = self._space.free_cells[rng.integers(0, len(self._space.free_cells), size=n)]
        jitter = rng.uniform(0.2, 0.8, size=(n, 2))
        res = self._space.coarse_res
        return np.stack([(cells[:, 1] + jitter[:, 0]) * res, (cells[:, 0] + jitter[:, 1]) * res], axis=-1)

    def _spawn(self, rng: np.random.Generator) -> _People:
        cfg = self.config
        n = self._count
        # Groups of 1..group_size_max visitors; the first of each group leads.
        group = np.empty(n, dtype=np.int64)
        i = 0
        while i < n:
            size = min(int(rng.integers(1, cfg.group_size_max + 1)), n - i)
            group[i : i + size] = i
            i += size
        pos = np.empty((n, 2))
        keep_clear = cfg.robot_radius + cfg.person_radius + 0.3
        for k in range(n):
            for _ in range(100):
                if group[k] == k:
                    cand = self._random_free_points(rng, 1)[0]
                else:
                    cand = pos[group[k]] + rng.normal(0.0, 0.6, size=2)
                ok = self._space.is_walkable(cand[None])[0]
                if ok and np.hypot(*(cand - self._robot[:2])) > keep_clear:
                    break
            pos[k] = cand
        speed = rng.uniform(cfg.speed_min, cfg.speed_max, size=n)
        speed = speed[group]  # a group walks at its leader's pace
        heading = rng.uniform(-np.pi, np.pi, size=n)
        near = np.hypot(pos[:, 0] - self._robot[0], pos[:, 1] - self._robot[1]) < cfg.notice_distance
        interested = ((rng.random(n) < cfg.robot_interest) & near)[group]
        stand = np.stack(
            [
                rng.uniform(cfg.stand_distance[0], cfg.stand_distance[1], size=n),
                rng.uniform(-cfg.stand_arc, cfg.stand_arc, size=n),
            ],
            axis=-1,
        )
        return _People(
            pos=pos,
            vel=np.zeros((n, 2)),
            heading=heading,
            speed=speed,
            mode=np.where(interested, ROBOT, DWELL).astype(np.int64),
            goal=pos.copy(),
            goal_poi=np.full(n, -1, dtype=np.int64),
            timer=rng.uniform(0.0, cfg.dwell_time[1], size=n),
            interested=interested,
            stand=stand,
            phase=rng.uniform(0.0, 2.0 * np.pi, size=n),
            leg_radius=rng.uniform(cfg.leg_radius[0], cfg.leg_radius[1], size=(n, 2)),
            group=group,
        )

    # ---- stepping ----------------------------------------------------------------------------

    def step(self, dt: float, robot_pose: ArrayLike, rng: np.random.Generator) -> None:
        """Advance the crowd by ``dt`` seconds with the robot at ``robot_pose`` (world)."""
        if dt < 0:
            raise CrowdError(f"cannot step a crowd backwards in time (dt={dt})")
        self._robot = self._local_pose(robot_pose)
        if self.num_people == 0:
            self.time += dt
            return
        n_sub = max(1, math.ceil(dt / self.config.max_substep - 1e-9))
        h = dt / n_sub
        for _ in range(n_sub):
            self._substep(h, rng)

    def _update_interest(self, h: float, rng: np.random.Generator) -> None:
        """Leaders start or stop being drawn to the robot (a two-state Markov chain whose
        stationary share is ``robot_interest`` and mean stay ``interest_duration``); their group
        follows."""
        cfg = self.config
        p = self._people
        if cfg.robot_interest <= 0.0:
            p.interested[:] = False
        else:
            off_rate = 1.0 / cfg.interest_duration
            on_rate = off_rate * cfg.robot_interest / max(1e-9, 1.0 - cfg.robot_interest)
            u = rng.random(len(p.pos))
            leader = p.group == np.arange(len(p.pos))
            robot = self._robot[:2]
            dist = np.hypot(p.pos[:, 0] - robot[0], p.pos[:, 1] - robot[1])
            candidates = leader & ~p.interested & (dist < cfg.notice_distance)
            flip_on = candidates & (u < 1.0 - math.exp(-on_rate * h))
            if flip_on.any():
                sees = line_of_sight(
                    self._space.walkable,
                    self._space.coarse_res,
                    p.pos[flip_on],
                    np.repeat(robot[None], int(flip_on.sum()), axis=0),
                )
                flip_on[np.flatnonzero(flip_on)[~sees]] = False
            flip_off = (
                leader
                & p.interested
                & ((u < 1.0 - math.exp(-off_rate * h)) | (dist > cfg.field_max_distance))
            )
            lead_state = p.interested.copy()
            lead_state[flip_on] = True
            lead_state[flip_off] = False
            p.interested = lead_state[p.group]
            if flip_on.any():
                # A new standing spot around the robot for each member of the groups that join.
                joined = flip_on[p.group]
                m = int(joined.sum())
                p.stand[joined, 0] = rng.uniform(cfg.stand_distance[0], cfg.stand_distance[1], size=m)
                p.stand[joined, 1] = rng.uniform(-cfg.stand_arc, cfg.stand_arc, size=m)
        start = p.interested & (p.mode != ROBOT)
        p.mode[start] = ROBOT
        stop = ~p.interested & (p.mode == ROBOT)
        if stop.any():
            p.mode[stop] = DWELL
            p.timer[stop] = 0.0

    def _choose_goals(self, who: NDArray[np.int64], rng: np.random.Generator) -> None:
        """New goals for people whose dwell ended: leaders pick an exhibit or a point in view,
        the members of a group follow their leader's goal (or wait for the leader to pick one)."""
        cfg = self.config
        p = self._people
        sp = self._space
        leaders = who[p.group[who] == who]
        members = who[p.group[who] != who]
        # Leaders: an exhibit...
        to_poi = rng.random(len(leaders)) < (cfg.poi_probability if len(self._poi) else 0.0)
        poi = leaders[to_poi]
        if len(poi):
            j = rng.integers(0, len(self._poi), size=len(poi))
            p.goal[poi] = self._poi[j] + rng.normal(0.0, 0.7, size=(len(poi), 2))
            p.goal_poi[poi] = j
            p.mode[poi] = WALK
        # ... or the first of a few random points in view.
        wander = leaders[~to_poi]
        if len(wander):
            tries = 10
            dist = rng.uniform(cfg.wander_distance[0], cfg.wander_distance[1], size=(len(wander), tries))
            ang = rng.uniform(-np.pi, np.pi, size=(len(wander), tries))
            cand = p.pos[wander][:, None, :] + dist[..., None] * np.stack([np.cos(ang), np.sin(ang)], axis=-1)
            flat = cand.reshape(-1, 2)
            ok = sp.is_walkable(flat) & line_of_sight(
                sp.walkable, sp.coarse_res, np.repeat(p.pos[wander], tries, axis=0), flat
            )
            ok = ok.reshape(len(wander), tries)
            found = ok.any(axis=1)
            first = ok.argmax(axis=1)
            go = wander[found]
            p.goal[go] = cand[found, first[found]]
            p.goal_poi[wander] = -1
            p.mode[go] = WALK
            stay = wander[~found]
            p.timer[stay] = rng.uniform(0.5, 2.0, size=len(stay))
        # Members.
        lead = p.group[members]
        follow = members[p.mode[lead] == WALK]
        p.goal[follow] = p.goal[p.group[follow]] + rng.normal(0.0, 0.4, size=(len(follow), 2))
        p.goal_poi[follow] = p.goal_poi[p.group[follow]]
        p.mode[follow] = WALK
        wait = members[p.mode[lead] != WALK]
        p.timer[wait] = rng.uniform(1.0, 3.0, size=len(wait))

    def _decide(self, elapsed: float, rng: np.random.Generator) -> None:
        """The visitors' decisions, taken every ``decision_period`` seconds: interest in the robot,
        new goals when a dwell ends, arrivals, and whether each one sees where they go."""
        cfg = self.config
        p = self._people
        sp = self._space
        self._update_interest(elapsed, rng)
        # Dwelling people whose time is up pick a new goal.
        p.timer = np.where(p.mode == DWELL, p.timer - elapsed, p.timer)
        done = np.flatnonzero((p.mode == DWELL) & (p.timer <= 0.0))
        if len(done):
            self._choose_goals(done, rng)
        target = self._targets()
        dist = np.hypot(target[:, 0] - p.pos[:, 0], target[:, 1] - p.pos[:, 1])
        # Arrivals: walkers start dwelling.
        arrived = (p.mode == WALK) & (dist < 0.5)
        if arrived.any():
            p.mode[arrived] = DWELL
            p.timer[arrived] = rng.uniform(cfg.dwell_time[0], cfg.dwell_time[1], size=int(arrived.sum()))
        self._in_view = line_of_sight(sp.walkable, sp.coarse_res, p.pos, target)
        # A wanderer pushed out of view of its goal picks another one at the next decision.
        lost = (p.mode == WALK) & ~self._in_view & (p.goal_poi < 0)
        p.mode[lost] = DWELL
        p.timer[lost] = 0.0

    def _refresh_robot_field(self) -> None:
        """Recompute the field to the robot once it has moved a cell since the last one."""
        robot = self._robot[:2]
        if np.hypot(*(robot - self._field_robot_at)) >= self._space.coarse_res:
            self._fields[0] = self._space.field_to(robot, self.config.field_max_distance)
            self._field_robot_at = robot.copy()

    def _targets(self) -> FloatArray:
        """Where everyone heads: the goal, or the standing spot in front of the robot."""
        p = self._people
        rx, ry, rth = self._robot
        spot_x = rx + p.stand[:, 0] * np.cos(rth + p.stand[:, 1])
        spot_y = ry + p.stand[:, 0] * np.sin(rth + p.stand[:, 1])
        at_robot = p.mode == ROBOT
        return np.stack(
            [np.where(at_robot, spot_x, p.goal[:, 0]), np.where(at_robot, spot_y, p.goal[:, 1])], axis=-1
        )

    def _substep(self, h: float, rng: np.random.Generator) -> None:
        cfg = self.config
        p = self._people
        sp = self._space
        if self.time >= self._next_decision:
            self._decide(self.time - self._last_decision, rng)
            self._last_decision = self.time
            self._next_decision = self.time + cfg.decision_period
        self.time += h

        at_robot = p.mode == ROBOT
        target = self._targets()
        dist = np.hypot(target[:, 0] - p.pos[:, 0], target[:, 1] - p.pos[:, 1])
        moving = (p.mode == WALK) | (at_robot & (dist > 0.15))
        # Those who cannot see where they go walk down a geodesic field around the walls: to the
        # robot (field 0, refreshed as the robot moves) or to their exhibit (fields 1..).
        field_index = np.where(at_robot, 0, np.where(p.goal_poi >= 0, p.goal_poi + 1, -1))
        if (moving & ~self._in_view & at_robot).any():
            self._refresh_robot_field()
        desired = steer(
            p.pos, target, moving, self._in_view, field_index, self._fields, sp.coarse_res, p.speed, cfg.tau
        )

        # Social forces, integration, hard constraints and gait (Helbing & Molnár 1995, Eq. 1-5).
        cap = np.minimum(cfg.speed_max, 1.3 * p.speed)
        p.pos, p.vel, p.phase, p.heading = move_people(
            p.pos,
            p.vel,
            desired,
            cap,
            p.group,
            at_robot,
            p.phase,
            p.heading,
            sp.wall_dist,
            sp.wall_dir,
            sp.res,
            sp.walkable,
            sp.coarse_res,
            float(self._robot[0]),
            float(self._robot[1]),
            self._params,
            h,
        )
