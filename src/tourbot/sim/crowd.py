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

    Walking (measured on the ETH/UCY pedestrian recordings with ``tourbot bench crowd``, see
    :mod:`tourbot.sim.crowd_stats`): preferred speeds normal with mean ``speed_mean`` = 1.2 m/s and
    sd ``speed_sd`` = 0.25 m/s, clipped to ``[speed_min, speed_max]`` (Helbing & Molnár 1995:
    1.34 ± 0.26 m/s; the Zara and Hotel walkers' medians are 1.2-1.5 m/s). Social force
    (Helbing & Molnár 1995, Eq. 3-5, per unit mass): relaxation time ``tau`` = 0.5 s,
    person-person potential ``social_strength`` = 2.0 m²/s² over ``social_range`` = 0.08 m
    (Helbing, Farkas & Vicsek 2000) between personal-space radii drawn per visitor from
    ``personal_radius``, weighted by the anisotropy ``anisotropy`` (λ of Helbing et al. 2005:
    people mind who is in front more than who is behind); walls with the same short-range term
    (Helbing, Farkas & Vicsek 2000 use A and B alike for walls: ``wall_strength`` 2.0 m²/s² over
    ``wall_range`` 0.08 m from the body's edge; the 10 m²/s² over 0.2 m of Helbing & Molnár 1995
    are measured from the centre, and from the edge they held walkers 0.8 m off every wall, stuck
    in doorways). Groups (Moussaïd et al. 2010): sizes 1-5 with the
    weights ``group_weights`` (the recordings: 50-90 % of the groups are singles, 20-40 % pairs),
    members walking abreast of their leader ``group_spacing`` apart.

    Museum behaviour (Fox, Burgard, Thrun & Cremers 1998, Sec. "Experimental results", Fig. 1a;
    Burgard et al. 1999, "Experiences with an interactive museum tour-guide robot", Sec. 5-6):
    in the long run a fraction ``robot_interest`` of the visitor groups gathers at the robot, each
    for ``interest_duration`` seconds on average; only visitors within ``notice_distance`` metres
    who can see the robot become interested, and those left farther than ``field_max_distance``
    behind lose interest. Those at the robot stand in a loose ring: spots at ``stand_distance``
    metres within ``±stand_arc`` of its heading (in front, where its screen and face are), two
    visitors at least the mean of their personal distances apart, each drawn from
    ``stand_spacing`` (Hall's personal distance, 0.45-1.2 m); one who finds no room there stands
    in a looser row up to 1.5 m farther out, and a group that finds none does not join. While the
    robot stands the ring stays where it is; when it drives they come along at its pace (a tour
    group following it; a group left more than ``give_up_distance`` metres behind its spot gives
    up), and whoever stands in its way
    (``corridor`` metres either side of its path, ``lookahead`` metres ahead) steps aside. A share
    ``blocker_share`` of the groups blocks it on purpose: they stand right in front and keep there
    as it moves, for ``block_duration`` seconds on average. Visitors pick a near exhibit more often
    than a far one (weights ``exp(-walking distance / exhibit_reach)``). At exhibits they stand in a loose
    ring ``exhibit_distance`` metres away for a log-normal time (median ``dwell_median``,
    log-sd ``dwell_sigma``, clipped to ``dwell_time``); walkers pause at the points they wander
    to for ``pause_mean`` seconds on average; one held up on the way for ``give_up_after``
    seconds stops there and goes elsewhere. Legs at sensor height: radius 5-8 cm, 20 cm apart,
    swinging ``leg_swing`` metres with a gait cycle of ``stride_length`` metres.
    """

    num_people: int = 40
    # People per square metre of walkable space; when set, it overrides ``num_people``.
    density: float | None = None
    speed_mean: float = 1.2
    speed_sd: float = 0.25
    speed_min: float = 0.5
    speed_max: float = 1.8
    # Helbing & Molnár 1995, Eq. 2-5 (per unit mass); the person-person term with the short range
    # of Helbing, Farkas & Vicsek 2000 (A = 2000 N over B = 0.08 m for 80 kg: A·B/m = 2.0 m²/s²).
    tau: float = 0.5
    social_strength: float = 2.0
    social_range: float = 0.08
    personal_radius: tuple[float, float] = (0.22, 0.32)
    anisotropy: float = 0.3
    wall_strength: float = 2.0
    wall_range: float = 0.08
    person_radius: float = 0.25
    # The robot as an obstacle people keep clear of (RHINO/TOURBOT robots are ~0.5-0.6 m wide).
    robot_radius: float = 0.4
    robot_strength: float = 10.0
    robot_range: float = 0.2
    # Interest in the robot (Fox et al. 1998, Fig. 1a; Burgard et al. 1999).
    robot_interest: float = 0.3
    interest_duration: float = 120.0
    notice_distance: float = 10.0
    stand_distance: tuple[float, float] = (0.9, 3.2)
    stand_arc: float = math.radians(95.0)
    stand_spacing: tuple[float, float] = (0.5, 1.4)
    corridor: float = 0.9
    give_up_distance: float = 8.0
    lookahead: float = 3.0
    blocker_share: float = 0.1
    block_duration: float = 15.0
    # Where visitors go when not at the robot.
    points_of_interest: tuple[tuple[float, float], ...] = ()
    poi_probability: float = 0.5
    exhibit_distance: tuple[float, float] = (1.0, 2.5)
    exhibit_reach: float = 10.0
    dwell_median: float = 12.0
    dwell_sigma: float = 0.8
    dwell_time: tuple[float, float] = (2.0, 120.0)
    pause_mean: float = 2.0
    give_up_after: float = 5.0
    wander_distance: tuple[float, float] = (2.0, 12.0)
    group_weights: tuple[float, ...] = (0.6, 0.27, 0.09, 0.03, 0.01)
    group_spacing: float = 0.75
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
            (self.speed_sd >= 0.0, "speed_sd must be >= 0"),
            (0.0 <= self.robot_interest <= 1.0, "robot_interest must be in [0, 1]"),
            (0.0 <= self.poi_probability <= 1.0, "poi_probability must be in [0, 1]"),
            (0.0 <= self.blocker_share <= 1.0, "blocker_share must be in [0, 1]"),
            (0.0 <= self.anisotropy <= 1.0, "anisotropy must be in [0, 1]"),
            (self.interest_duration > 0.0, "interest_duration must be positive"),
            (self.block_duration > 0.0 and self.pause_mean > 0.0, "durations must be positive"),
            (self.tau > 0.0 and self.max_substep > 0.0, "tau and max_substep must be positive"),
            (
                len(self.group_weights) >= 1 and min(self.group_weights) >= 0 and sum(self.group_weights) > 0,
                "group_weights must be non-negative with a positive sum",
            ),
            (0.0 < self.stand_distance[0] <= self.stand_distance[1], "bad stand_distance"),
            (0.0 < self.stand_spacing[0] <= self.stand_spacing[1], "bad stand_spacing"),
            (0.0 < self.personal_radius[0] <= self.personal_radius[1], "bad personal_radius"),
            (0.0 < self.exhibit_distance[0] <= self.exhibit_distance[1], "bad exhibit_distance"),
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
# "Crowd presets").
PRESETS: dict[str, CrowdConfig] = {
    "empty": CrowdConfig(num_people=0, robot_interest=0.0),
    "sparse": CrowdConfig(density=0.015, robot_interest=0.1, interest_duration=30.0),
    "peak": CrowdConfig(density=0.3, robot_interest=0.85, notice_distance=15.0, interest_duration=60.0),
}


# --------------------------------------------------------------------------------------------
# Kernels (numba) and their references
# --------------------------------------------------------------------------------------------


@numba.njit(cache=True)
def social_forces(
    pos: FloatArray,
    radius: FloatArray,
    heading: FloatArray,
    standing: NDArray[np.bool_],
    strength: float,
    scale: float,
    anisotropy: float,
) -> FloatArray:
    """Pairwise repulsion between people, ``(N, 2)`` accelerations.

    Helbing & Molnár 1995, Eq. 3 in its common circular form: person ``j`` pushes ``i`` along
    ``n_ij = (x_i - x_j)/d_ij`` with magnitude ``(V0/σ) exp((r_i + r_j - d_ij)/σ)``, weighted by
    the anisotropy of Helbing & Molnár 1995, Eq. 7 in the form of Helbing, Buzna, Johansson &
    Werner 2005 (Transp. Sci. 39, Eq. 3): ``w = λ + (1 - λ)(1 + cos φ_ij)/2`` with ``φ_ij`` the
    angle between ``i``'s heading and the direction to ``j`` (people react less to those behind
    them; ``λ = 1`` is isotropic and the forces cancel pairwise). Two people ``standing`` still do
    not push each other unless they touch (``d_ij <= r_i + r_j``): the exponential tail would
    otherwise spread standing crowds into an even lattice, which real ones are not; a walker still
    pushes and is pushed by them.
    """
    n = pos.shape[0]
    out = np.zeros((n, 2))
    cutoff = 8.0 * scale
    for i in range(n):
        ci = math.cos(heading[i])
        si = math.sin(heading[i])
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
            ux = dx / d
            uy = dy / d
            # cos φ: for i the other is at -u, for j at +u.
            wi = anisotropy + (1.0 - anisotropy) * 0.5 * (1.0 - (ci * ux + si * uy))
            wj = anisotropy + (1.0 - anisotropy) * 0.5 * (
                1.0 + (math.cos(heading[j]) * ux + math.sin(heading[j]) * uy)
            )
            if gap > 0.0 and standing[i] and standing[j]:
                continue
            out[i, 0] += wi * mag * ux
            out[i, 1] += wi * mag * uy
            out[j, 0] -= wj * mag * ux
            out[j, 1] -= wj * mag * uy
    return out


def social_forces_reference(
    pos: FloatArray,
    radius: FloatArray,
    heading: FloatArray,
    standing: NDArray[np.bool_],
    strength: float,
    scale: float,
    anisotropy: float,
) -> FloatArray:
    """Plain-numpy :func:`social_forces` (all pairs, same cutoff) for the property tests."""
    diff = pos[:, None, :] - pos[None, :, :]
    d = np.linalg.norm(diff, axis=-1)
    gap = d - radius[:, None] - radius[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = diff / d[..., None]
    mag = strength / scale * np.exp(-gap / scale)
    facing = np.stack([np.cos(heading), np.sin(heading)], axis=-1)
    cos_phi = -np.einsum("ik,ijk->ij", facing, unit)
    weight = anisotropy + (1.0 - anisotropy) * 0.5 * (1.0 + cos_phi)
    reach = 8.0 * scale + radius[:, None] + radius[None, :]
    mask = (d <= reach) & ~np.eye(len(pos), dtype=bool) & (d >= 1e-9)
    mask &= (gap <= 0.0) | ~(standing[:, None] & standing[None, :])
    return np.asarray(np.sum(np.where(mask[..., None], (weight * mag)[..., None] * unit, 0.0), axis=1))


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
_P_ROBOT_R, _P_ROBOT_A, _P_ROBOT_B, _P_COHESION, _P_STRIDE, _P_ANISOTROPY = 6, 7, 8, 9, 10, 11


@numba.njit(cache=True)
def move_people(
    pos: FloatArray,
    vel: FloatArray,
    desired: FloatArray,
    cap: FloatArray,
    radii: FloatArray,
    group: NDArray[np.int64],
    facing: NDArray[np.int64],
    phase: FloatArray,
    heading: FloatArray,
    wall_dist: FloatArray,
    wall_dir: FloatArray,
    res: float,
    walkable: NDArray[np.bool_],
    coarse_res: float,
    robots: FloatArray,
    params: FloatArray,
    h: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """One explicit-Euler step of the social-force model for everyone: new (pos, vel, phase, heading).

    Acceleration (Helbing & Molnár 1995, Eq. 1-5, per unit mass): relaxation to the desired
    velocity over ``tau``; exponential, anisotropic repulsion from other people, each with their own
    personal-space radius ``radii`` (:func:`social_forces`; those with no desired velocity stand),
    from the nearest wall (the
    distance transform of the map) and from each robot (``robots`` ``(M, 2)``, several in one
    museum); a pull towards the group's leader when more than 1.5 m away. Speeds are capped at
    ``cap``. Then hard constraints: a person closer than half a radius to a wall is pushed out,
    one who would leave the walkable space stays where they were (and stops), nobody enters a
    robot. Legs advance their gait phase with the distance walked; walkers face where they go,
    visitors standing at a robot (``facing[i]``, its index in ``robots``; -1 for none) face it.
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
    standing = np.empty(n, dtype=np.bool_)
    for i in range(n):
        standing[i] = desired[i, 0] == 0.0 and desired[i, 1] == 0.0
    acc += social_forces(
        pos, radii, heading, standing, params[_P_SOC_A], params[_P_SOC_B], params[_P_ANISOTROPY]
    )
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
        # Robots.
        for k in range(robots.shape[0]):
            rx = pos[i, 0] - robots[k, 0]
            ry = pos[i, 1] - robots[k, 1]
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
        # Not into a robot.
        for k in range(robots.shape[0]):
            rx = px - robots[k, 0]
            ry = py - robots[k, 1]
            rd = max(math.sqrt(rx * rx + ry * ry), 1e-9)
            if rd < min_gap:
                px = robots[k, 0] + rx / rd * min_gap
                py = robots[k, 1] + ry / rd * min_gap
        # Gait and heading.
        sp = math.sqrt(vx * vx + vy * vy)
        new_phase[i] = (phase[i] + 2.0 * math.pi * sp * h / params[_P_STRIDE]) % (2.0 * math.pi)
        if sp > 0.1:
            new_heading[i] = math.atan2(vy, vx)
        elif facing[i] >= 0:
            new_heading[i] = math.atan2(robots[facing[i], 1] - py, robots[facing[i], 0] - px)
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
    radii: FloatArray,
    group: NDArray[np.int64],
    facing: NDArray[np.int64],
    phase: FloatArray,
    heading: FloatArray,
    wall_dist: FloatArray,
    wall_dir: FloatArray,
    res: float,
    walkable: NDArray[np.bool_],
    coarse_res: float,
    robots: FloatArray,
    params: FloatArray,
    h: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Plain-numpy :func:`move_people` for the property tests."""
    tau, radius = params[_P_TAU], params[_P_RADIUS]

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
    standing = (desired[:, 0] == 0.0) & (desired[:, 1] == 0.0)
    acc += social_forces_reference(
        pos, radii, heading, standing, params[_P_SOC_A], params[_P_SOC_B], params[_P_ANISOTROPY]
    )
    wd, wn = wall(pos)
    acc += (params[_P_WALL_A] / params[_P_WALL_B] * np.exp(-(wd - radius) / params[_P_WALL_B]))[:, None] * wn
    for robot in robots:
        rel = pos - robot
        rd = np.maximum(np.linalg.norm(rel, axis=-1), 1e-9)
        gap = rd - params[_P_ROBOT_R] - radius
        acc += (params[_P_ROBOT_A] / params[_P_ROBOT_B] * np.exp(-gap / params[_P_ROBOT_B]) / rd)[
            :, None
        ] * rel
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
    min_gap = params[_P_ROBOT_R] + 0.5 * radius
    for robot in robots:
        rel = new_pos - robot
        rd = np.maximum(np.linalg.norm(rel, axis=-1), 1e-9)
        close = rd < min_gap
        new_pos = np.where(close[:, None], robot + rel / rd[:, None] * min_gap, new_pos)
    speed = np.linalg.norm(new_vel, axis=-1)
    new_phase = np.mod(phase + 2.0 * np.pi * speed * h / params[_P_STRIDE], 2.0 * np.pi)
    faced = robots[np.maximum(facing, 0)] if len(robots) else np.zeros((len(pos), 2))
    face_robot = np.arctan2(faced[:, 1] - new_pos[:, 1], faced[:, 0] - new_pos[:, 0])
    new_heading = np.where(
        speed > 0.1, np.arctan2(new_vel[:, 1], new_vel[:, 0]), np.where(facing >= 0, face_robot, heading)
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
    radius: FloatArray  # personal-space radius
    spacing: FloatArray  # personal distance kept to others when standing at the robot
    mode: NDArray[np.int64]
    goal: FloatArray
    goal_poi: NDArray[np.int64]  # index of the point of interest walked to, -1 for none
    timer: FloatArray  # dwell time left, s
    interested: NDArray[np.bool_]
    robot: NDArray[np.int64]  # the robot a visitor at a robot (mode ROBOT) stands at, its index
    stand: FloatArray  # (N, 2) polar (distance, bearing) of the standing spot, that robot's frame
    block_until: FloatArray  # time until which the visitor blocks the robot on purpose
    phase: FloatArray  # gait phase, rad
    leg_radius: FloatArray  # (N, 2)
    group: NDArray[np.int64]  # index of the group's leader
    slot: FloatArray  # offset beside the leader while walking (m, + = left), 0 for leaders
    stuck: FloatArray  # seconds a walking leader has been held up (slower than 0.2 m/s)


class Crowd:
    """Visitors walking in a map's free space; step it with the robots' poses.

    ``Crowd(config, grid, rng, robot_pose)`` spawns ``config.num_people`` visitors in groups in
    the free space, clear of the robots: ``robot_pose`` is one pose ``(3,)`` or the poses ``(M, 3)``
    of the ``M`` robots of one museum (WebFAIR's several robots), each of which the visitors gather
    at, follow and step aside for as they do for one (a visitor drawn to the robots joins the
    nearest one it sees). :meth:`step` advances them by ``dt`` seconds (in substeps of at most
    ``config.max_substep``; the robots are taken to be at ``robot_pose`` throughout, so callers
    with moving robots step at their own rate; their velocities are given, or taken from the poses
    of consecutive steps). :meth:`legs` gives what a laser at leg height hits.
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
        self._poses = self._local_poses(robot_pose)  # (M, 3), grid frame
        self._robots = np.ascontiguousarray(self._poses[:, :2])
        m = len(self._poses)
        # The pose each robot's standing ring is laid out from: the robot's while it drives, kept
        # while it stands (so the ring stays put as it turns on the spot).
        self._anchor = self._poses.copy()
        self._moving = np.zeros(m, dtype=bool)
        self._robot_vel = np.zeros((m, 2))
        self._poi = np.array(
            [self._local_point(p) for p in config.points_of_interest], dtype=np.float64
        ).reshape(-1, 2)
        # Geodesic fields: 0..M-1 to the robots (computed when needed), M.. to the exhibits.
        self._fields = np.full((m + len(self._poi), *self._space.walkable.shape), np.inf)
        for j, poi in enumerate(self._poi):
            self._fields[m + j] = self._space.field_to(poi, config.field_max_distance * 4.0)
        self._field_robot_at = np.full((m, 2), np.inf)
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
                config.anisotropy,
            ]
        )

    # ---- frames ------------------------------------------------------------------------------

    def _local_pose(self, pose: ArrayLike) -> FloatArray:
        return compose(invert(self.grid.origin), np.asarray(pose, dtype=np.float64))

    def _local_poses(self, poses: ArrayLike) -> FloatArray:
        """One pose ``(3,)`` or several ``(M, 3)`` (world) as ``(M, 3)`` in the grid frame."""
        arr = np.asarray(poses, dtype=np.float64)
        if arr.ndim == 1:
            arr = arr[None, :]
        if arr.ndim != 2 or arr.shape[1] != 3 or len(arr) == 0:
            raise CrowdError(f"robot poses must be (3,) or (M, 3) with M >= 1, got shape {arr.shape}")
        return np.array([self._local_pose(p) for p in arr])

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
    def num_robots(self) -> int:
        return len(self._poses)

    @property
    def at_robot(self) -> NDArray[np.bool_]:
        """Which visitors are currently drawn to a robot, ``(N,)``."""
        return self._people.mode == ROBOT

    @property
    def robot_of(self) -> NDArray[np.int64]:
        """The index of the robot each visitor is drawn to (its standing ring), -1 for none, ``(N,)``."""
        p = self._people
        return np.where(p.mode == ROBOT, p.robot, -1)

    @property
    def groups(self) -> NDArray[np.int64]:
        """The index of each visitor's group leader, ``(N,)`` (a leader's is its own)."""
        return self._people.group.copy()

    @property
    def blocking(self) -> NDArray[np.bool_]:
        """Which visitors are blocking their robot's way on purpose now, ``(N,)``."""
        p = self._people
        return (p.mode == ROBOT) & (p.block_until > self.time)

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

    def place(self, positions: ArrayLike, velocities: ArrayLike, time: float | None = None) -> None:
        """Put the visitors at ``positions`` with ``velocities`` (world, ``(N, 2)`` each, as many
        as the crowd has), its clock at ``time``: a crowd carried on from where another one left
        off (the museum's world restarted). Only where they are and how they move is taken; each
        goes on from there with the plans this crowd drew for it."""
        pos = self._local_point(np.asarray(positions, dtype=np.float64)).reshape(-1, 2)
        vel = np.asarray(velocities, dtype=np.float64).reshape(-1, 2)
        if len(pos) != self.num_people or len(vel) != self.num_people:
            raise CrowdError(f"a crowd of {self.num_people} placed at {len(pos)} positions")
        th = -self.grid.origin[2]
        c, s = math.cos(th), math.sin(th)
        p = self._people
        p.pos = pos
        p.vel = np.stack([c * vel[:, 0] - s * vel[:, 1], s * vel[:, 0] + c * vel[:, 1]], axis=-1)
        p.goal[p.mode == DWELL] = pos[p.mode == DWELL]
        if time is not None:
            self.time = self._last_decision = self._next_decision = float(time)

    # ---- spawning ----------------------------------------------------------------------------

    def _random_free_points(self, rng: np.random.Generator, n: int) -> FloatArray:
        cells = self._space.free_cells[rng.integers(0, len(self._space.free_cells), size=n)]
        jitter = rng.uniform(0.2, 0.8, size=(n, 2))
        res = self._space.coarse_res
        return np.stack([(cells[:, 1] + jitter[:, 0]) * res, (cells[:, 0] + jitter[:, 1]) * res], axis=-1)

    def _dwell(self, rng: np.random.Generator, n: int) -> FloatArray:
        """Log-normal times at an exhibit, clipped to ``dwell_time``."""
        cfg = self.config
        t = cfg.dwell_median * np.exp(cfg.dwell_sigma * rng.standard_normal(n))
        return np.asarray(np.clip(t, cfg.dwell_time[0], cfg.dwell_time[1]))

    def _spawn(self, rng: np.random.Generator) -> _People:
        cfg = self.config
        n = self._count
        # Groups with sizes drawn from group_weights; the first of each group leads, the others
        # walk beside it, alternately left and right.
        weights = np.asarray(cfg.group_weights, dtype=np.float64)
        weights /= weights.sum()
        group = np.empty(n, dtype=np.int64)
        slot = np.zeros(n)
        i = 0
        while i < n:
            size = min(int(rng.choice(len(weights), p=weights)) + 1, n - i)
            group[i : i + size] = i
            for k in range(1, size):
                slot[i + k] = cfg.group_spacing * ((k + 1) // 2) * (1.0 if k % 2 else -1.0)
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
                if ok and self._robot_distances(cand[None])[0].min() > keep_clear:
                    break
            pos[k] = cand
        speed = np.clip(rng.normal(cfg.speed_mean, cfg.speed_sd, size=n), cfg.speed_min, cfg.speed_max)
        speed = speed[group]  # a group walks at its leader's pace
        heading = rng.uniform(-np.pi, np.pi, size=n)
        dist = self._robot_distances(pos)
        nearest = np.argmin(dist, axis=1)
        near = dist.min(axis=1) < cfg.notice_distance
        interested = ((rng.random(n) < cfg.robot_interest) & near)[group]
        people = _People(
            pos=pos,
            vel=np.zeros((n, 2)),
            heading=heading,
            speed=speed,
            radius=rng.uniform(cfg.personal_radius[0], cfg.personal_radius[1], size=n),
            spacing=rng.uniform(cfg.stand_spacing[0], cfg.stand_spacing[1], size=n),
            mode=np.full(n, DWELL, dtype=np.int64),
            goal=pos.copy(),
            goal_poi=np.full(n, -1, dtype=np.int64),
            timer=rng.exponential(cfg.pause_mean, size=n),
            interested=np.zeros(n, dtype=bool),
            robot=np.zeros(n, dtype=np.int64),
            stand=np.zeros((n, 2)),
            block_until=np.full(n, -np.inf),
            phase=rng.uniform(0.0, 2.0 * np.pi, size=n),
            leg_radius=rng.uniform(cfg.leg_radius[0], cfg.leg_radius[1], size=(n, 2)),
            group=group,
            slot=slot,
            stuck=np.zeros(n),
        )
        self._people = people
        leaders = interested & (group == np.arange(n))
        for k in range(self.num_robots):
            self._join_robot(np.flatnonzero(leaders & (nearest == k)), k, rng)
        return people

    def _robot_distances(self, pos: FloatArray) -> FloatArray:
        """Distances ``(K, M)`` from points ``(K, 2)`` (grid frame) to each robot."""
        return np.asarray(np.linalg.norm(pos[:, None, :] - self._poses[None, :, :2], axis=-1))

    # ---- the ring at the robot ---------------------------------------------------------------

    def _anchor_points(self, stand: FloatArray, robot: int | NDArray[np.int64]) -> FloatArray:
        """Grid-frame points of polar spots ``(K, 2)`` around the anchor pose of ``robot`` (one
        index, or one per spot)."""
        a = self._anchor[robot]
        ang = a[..., 2] + stand[:, 1]
        return np.stack(
            [a[..., 0] + stand[:, 0] * np.cos(ang), a[..., 1] + stand[:, 0] * np.sin(ang)], axis=-1
        )

    def _ring_points(self, ring: NDArray[np.bool_]) -> FloatArray:
        """The spots of the visitors ``ring`` (at robots), each around its own robot's anchor."""
        p = self._people
        return self._anchor_points(p.stand[ring], p.robot[ring])

    def _taken_spots(
        self, robot: int, exclude: NDArray[np.bool_] | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Spots taken near ``robot`` and their personal distances: the rings' (at every robot),
        and where the others stand nearby (at an exhibit, waiting); ``exclude`` leaves some
        visitors out."""
        cfg = self.config
        p = self._people
        anchor = self._anchor[robot]
        near = np.hypot(p.pos[:, 0] - anchor[0], p.pos[:, 1] - anchor[1]) < cfg.stand_distance[1] + 3.0
        ring = p.mode == ROBOT
        standing = (p.mode == DWELL) & near
        if exclude is not None:
            ring, standing = ring & ~exclude, standing & ~exclude
        points = np.concatenate([self._ring_points(ring), p.pos[standing]])
        return points, np.concatenate([p.spacing[ring], p.spacing[standing]])

    def _find_spot(
        self,
        who: int,
        taken: FloatArray,
        space: FloatArray,
        rng: np.random.Generator,
        robot: int,
        *,
        beside: FloatArray | None = None,
        blocker: bool = False,
    ) -> tuple[float, float] | None:
        """A free spot ``(distance, bearing)`` around ``robot``'s anchor pose for visitor ``who``: walkable,
        and the mean of the two personal distances away from every spot ``taken`` (random
        sequential placement, a few tries only, so the ring stays loose): in front of the robot
        for a blocker, ``beside`` a group mate's spot, else in the ring; in a looser row up to
        1.5 m farther out after 16 tries; None
        when there is no room."""
        cfg = self.config
        lo, hi = cfg.stand_distance
        anchor = self._anchor[robot]
        for attempt in range(24):
            outer = attempt >= 16
            if blocker and not outer:
                d, b = rng.uniform(0.8, 1.5), rng.uniform(-0.45, 0.45)
            elif beside is not None and not outer:
                ang = rng.uniform(-np.pi, np.pi)
                rel = beside + rng.uniform(0.6, 1.1) * np.array([math.cos(ang), math.sin(ang)]) - anchor[:2]
                d = float(np.hypot(rel[0], rel[1]))
                b = float(wrap_angle(math.atan2(rel[1], rel[0]) - anchor[2]))
                if not (lo <= d <= hi + 1.0):
                    continue
            else:
                d = rng.uniform(hi, hi + 1.5) if outer else rng.uniform(lo, hi)
                b = rng.uniform(-cfg.stand_arc, cfg.stand_arc)
            pt = self._anchor_points(np.array([[d, b]]), robot)
            if not self._space.is_walkable(pt)[0]:
                continue
            if len(taken):
                gaps = np.linalg.norm(taken - pt, axis=1)
                if np.any(gaps < 0.5 * (space + self._people.spacing[who])):
                    continue
            return d, b
        return None

    def _join_robot(self, leaders: NDArray[np.int64], robot: int, rng: np.random.Generator) -> None:
        """Groups of ``leaders`` that find room in the loose ring around ``robot`` join it, each
        member at a spot of :meth:`_find_spot` (members beside their leader); a group with a
        member without room does not join. A share ``blocker_share`` of the groups blocks the
        robot on purpose."""
        cfg = self.config
        p = self._people
        if not len(leaders):
            return
        taken, space = self._taken_spots(robot)
        for lead in leaders.tolist():
            members = np.flatnonzero(p.group == lead)
            blocker = bool(rng.random() < cfg.blocker_share)
            spots: list[tuple[float, float]] = []
            mine = taken
            for m in members.tolist():
                first = self._anchor_points(np.array([spots[0]]), robot)[0] if spots else None
                found = self._find_spot(
                    m,
                    mine,
                    space[: len(mine)]
                    if len(spots) == 0
                    else np.concatenate([space, p.spacing[members[: len(spots)]]]),
                    rng,
                    robot,
                    beside=first,
                    blocker=blocker,
                )
                if found is None:
                    break
                spots.append(found)
                mine = np.concatenate([taken, self._anchor_points(np.array(spots), robot)])
            if len(spots) < len(members):
                continue
            p.stand[members] = np.array(spots)
            p.robot[members] = robot
            p.mode[members] = ROBOT
            p.interested[members] = True
            p.block_until[members] = self.time + rng.exponential(cfg.block_duration) if blocker else -np.inf
            taken = mine
            space = np.concatenate([space, p.spacing[members]])

    def _relocate(self, rng: np.random.Generator) -> None:
        """Visitors at a driving robot whose spot has moved into a wall (the robot drove on) or who
        have fallen far behind it take a new free spot (no spot: the nearest walkable one)."""
        cfg = self.config
        p = self._people
        ring_mask = (p.mode == ROBOT) & (p.block_until <= self.time) & self._moving[p.robot]
        ring = np.flatnonzero(ring_mask)
        if not len(ring):
            return
        spot = self._ring_points(ring_mask)
        bad = ~self._space.is_walkable(spot)
        bad |= np.hypot(spot[:, 0] - p.pos[ring, 0], spot[:, 1] - p.pos[ring, 1]) > cfg.stand_distance[1]
        for i in ring[bad].tolist():
            exclude = np.zeros(self.num_people, dtype=bool)
            exclude[i] = True
            robot = int(p.robot[i])
            taken, space = self._taken_spots(robot, exclude)
            found = self._find_spot(i, taken, space, rng, robot)
            if found is not None:
                p.stand[i] = found

    def _step_aside(self, robot: int, rng: np.random.Generator) -> None:
        """While ``robot`` drives, those standing at a robot in its way (not the blockers) and
        those standing still in its path move sideways out of the corridor: its own ring's
        visitors, and those of another robot it passes, take a spot beside its corridor."""
        cfg = self.config
        p = self._people
        rx, ry, rth = self._poses[robot]
        c, s = math.cos(rth), math.sin(rth)
        rel = p.pos - np.array([rx, ry])
        fwd = rel[:, 0] * c + rel[:, 1] * s
        lat = -rel[:, 0] * s + rel[:, 1] * c
        in_way = (fwd > 0.0) & (fwd < cfg.lookahead) & (np.abs(lat) < cfg.corridor)
        side = np.where(lat >= 0.0, 1.0, -1.0)
        ring_mask = in_way & (p.mode == ROBOT) & (p.block_until <= self.time)
        ring = np.flatnonzero(ring_mask)
        if len(ring):
            # The new spot, in the driving robot's frame: as far ahead as the visitor's spot is
            # now, beside the corridor; then in the frame of the robot the visitor stands at.
            spot = self._ring_points(ring_mask) - np.array([rx, ry])
            f = np.maximum(spot[:, 0] * c + spot[:, 1] * s, 0.3)
            new_lat = side[ring] * (cfg.corridor + rng.uniform(0.2, 0.6, size=len(ring)))
            new = np.array([rx, ry]) + f[:, None] * np.array([c, s]) + new_lat[:, None] * np.array([-s, c])
            anchor = self._anchor[p.robot[ring]]
            d = new - anchor[:, :2]
            p.stand[ring, 0] = np.hypot(d[:, 0], d[:, 1])
            p.stand[ring, 1] = wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - anchor[:, 2])
        still = np.flatnonzero(in_way & (p.mode == DWELL) & (np.abs(lat) < cfg.corridor))
        if len(still):
            shift = side[still] * (cfg.corridor + 0.3 - np.abs(lat[still]))
            cand = p.pos[still] + shift[:, None] * np.array([-s, c])[None, :]
            ok = self._space.is_walkable(cand)
            p.goal[still[ok]] = cand[ok]
            p.mode[still[ok]] = WALK
            p.goal_poi[still[ok]] = -1

    # ---- stepping ----------------------------------------------------------------------------

    def step(
        self,
        dt: float,
        robot_pose: ArrayLike,
        rng: np.random.Generator,
        velocities: ArrayLike | None = None,
    ) -> None:
        """Advance the crowd by ``dt`` seconds with the robots at ``robot_pose`` (world, ``(3,)``
        or ``(M, 3)``, as many robots as the crowd was made with): the visitors gather at each
        robot, follow it and step out of its way, and walk around every robot's body, never into
        it. ``velocities`` ``(M, 2)`` (world, m/s): the robots' own (a robot stepped apart from the
        crowd, another process); else taken from the poses of the last step."""
        if dt < 0:
            raise CrowdError(f"cannot step a crowd backwards in time (dt={dt})")
        poses = self._local_poses(robot_pose)
        if len(poses) != self.num_robots:
            raise CrowdError(f"a crowd made with {self.num_robots} robots stepped with {len(poses)}")
        if velocities is not None:
            vel = np.asarray(velocities, dtype=np.float64).reshape(-1, 2)
            th = -self.grid.origin[2]
            c, s = math.cos(th), math.sin(th)
            self._robot_vel = np.stack(
                [c * vel[:, 0] - s * vel[:, 1], s * vel[:, 0] + c * vel[:, 1]], axis=-1
            )
        elif dt > 0:
            self._robot_vel = (poses[:, :2] - self._poses[:, :2]) / dt
        if velocities is not None or dt > 0:
            self._moving = np.hypot(self._robot_vel[:, 0], self._robot_vel[:, 1]) > 0.05
        self._poses = poses
        self._robots = np.ascontiguousarray(poses[:, :2])
        self._anchor[self._moving] = poses[self._moving]
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
            every = self._robot_distances(p.pos)  # (N, M)
            nearest = np.argmin(every, axis=1)  # the robot a visitor drawn to the robots notices
            dist = np.where(p.interested, every[np.arange(len(p.pos)), p.robot], every.min(axis=1))
            candidates = leader & ~p.interested & (dist < cfg.notice_distance)
            flip_on = candidates & (u < 1.0 - math.exp(-on_rate * h))
            if flip_on.any():
                sees = line_of_sight(
                    self._space.walkable,
                    self._space.coarse_res,
                    p.pos[flip_on],
                    self._poses[nearest[flip_on], :2],
                )
                flip_on[np.flatnonzero(flip_on)[~sees]] = False
            # Leaders left behind by their driving robot give up following it.
            spot = self._anchor_points(p.stand, p.robot)
            behind = (
                self._moving[p.robot]
                & (p.mode == ROBOT)
                & (p.block_until <= self.time)
                & (np.hypot(spot[:, 0] - p.pos[:, 0], spot[:, 1] - p.pos[:, 1]) > cfg.give_up_distance)
            )
            flip_off = (
                leader
                & p.interested
                & ((u < 1.0 - math.exp(-off_rate * h)) | (dist > cfg.field_max_distance) | behind)
            )
            lead_state = p.interested.copy()
            lead_state[flip_off] = False
            p.interested = lead_state[p.group]
            for k in range(self.num_robots) if flip_on.any() else ():
                self._join_robot(np.flatnonzero(flip_on & (nearest == k)), k, rng)
        stop = ~p.interested & (p.mode == ROBOT)
        if stop.any():
            p.mode[stop] = DWELL
            p.timer[stop] = 0.0
            p.block_until[stop] = -np.inf

    def _exhibit_spots(
        self, j: NDArray[np.int64], who: NDArray[np.int64], rng: np.random.Generator
    ) -> FloatArray:
        """Spots for visitors ``who`` in a loose ring around exhibits ``j``: the nearest of a few
        random candidates (out to 2 m beyond ``exhibit_distance``) that keeps the visitor's
        personal distance from every spot taken there and from the ring at the robot; NaN where
        there is no room."""
        cfg = self.config
        p = self._people
        out = np.full((len(j), 2), np.nan)
        ring = self._ring_points(p.mode == ROBOT)
        for k, (e, i) in enumerate(zip(j.tolist(), who.tolist(), strict=True)):
            tries = 16
            r = np.sort(rng.uniform(cfg.exhibit_distance[0], cfg.exhibit_distance[1] + 2.0, size=tries))
            a = rng.uniform(-np.pi, np.pi, size=tries)
            cand = self._poi[e] + r[:, None] * np.stack([np.cos(a), np.sin(a)], axis=-1)
            ok = self._space.is_walkable(cand)
            others = np.concatenate([p.goal[(p.goal_poi == e) & (p.mode != ROBOT)], ring])
            if len(others):
                gap = np.linalg.norm(cand[:, None, :] - others[None, :, :], axis=-1).min(axis=1)
                ok &= gap >= p.spacing[i]
            if ok.any():
                out[k] = cand[int(np.argmax(ok))]
        return out

    def _choose_goals(self, who: NDArray[np.int64], rng: np.random.Generator) -> None:
        """New goals for leaders whose dwell ended: a spot at an exhibit or a point in view."""
        cfg = self.config
        p = self._people
        sp = self._space
        leaders = who[p.group[who] == who]
        # Leaders: an exhibit...
        to_poi = rng.random(len(leaders)) < (cfg.poi_probability if len(self._poi) else 0.0)
        poi = leaders[to_poi]
        if len(poi):
            # The next exhibit: a near one more likely (weights exp(-walking distance / 10 m)).
            cells = np.floor(p.pos[poi] / sp.coarse_res).astype(np.int64)
            rows = np.clip(cells[:, 1], 0, sp.walkable.shape[0] - 1)
            cols = np.clip(cells[:, 0], 0, sp.walkable.shape[1] - 1)
            metres = self._fields[self.num_robots :, rows, cols].T * sp.coarse_res  # (len(poi), exhibits)
            w = np.where(np.isfinite(metres), np.exp(-np.minimum(metres, 1e3) / cfg.exhibit_reach), 0.0)
            w[w.sum(axis=1) == 0] = 1.0
            cum = np.cumsum(w / w.sum(axis=1, keepdims=True), axis=1)
            j = np.minimum((cum < rng.random(len(poi))[:, None]).sum(axis=1), len(self._poi) - 1)
            spots = self._exhibit_spots(j, poi, rng)
            room = np.isfinite(spots[:, 0])
            p.goal_poi[poi[room]] = j[room]
            p.goal[poi[room]] = spots[room]
            p.mode[poi[room]] = WALK
            to_poi[np.flatnonzero(to_poi)[~room]] = False  # no room there: wander instead
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

    def _decide(self, elapsed: float, rng: np.random.Generator) -> None:
        """The visitors' decisions, taken every ``decision_period`` seconds: interest in the robot,
        stepping out of its way, new goals when a dwell ends, arrivals, the group members' state
        after their leader's, and whether each one sees where they go."""
        cfg = self.config
        p = self._people
        sp = self._space
        self._update_interest(elapsed, rng)
        for k in np.flatnonzero(self._moving).tolist():
            self._step_aside(k, rng)
        if self._moving.any():
            self._relocate(rng)
        leader = p.group == np.arange(self.num_people)
        # Dwelling leaders whose time is up pick a new goal.
        p.timer = np.where(p.mode == DWELL, p.timer - elapsed, p.timer)
        done = np.flatnonzero(leader & (p.mode == DWELL) & (p.timer <= 0.0))
        if len(done):
            self._choose_goals(done, rng)
        target = self._targets()
        dist = np.hypot(target[:, 0] - p.pos[:, 0], target[:, 1] - p.pos[:, 1])
        # Arrivals: walking leaders start dwelling (at an exhibit for a log-normal time, a short
        # pause elsewhere).
        # (or held up by others within 1.5 m of it, or near the exhibit it stands at).
        slow = np.hypot(p.vel[:, 0], p.vel[:, 1]) < 0.2
        near = (dist < 0.5) | ((dist < 1.5) & slow)
        if len(self._poi):
            j = np.maximum(p.goal_poi, 0)
            to_poi = np.hypot(self._poi[j, 0] - p.pos[:, 0], self._poi[j, 1] - p.pos[:, 1])
            near |= (p.goal_poi >= 0) & slow & (to_poi < cfg.exhibit_distance[1] + 1.0)
        # A leader held up for ``give_up_after`` seconds on the way (a jam in a doorway) gives up
        # that goal and picks another after a pause.
        p.stuck = np.where((p.mode == WALK) & slow & ~near, p.stuck + elapsed, 0.0)
        near |= p.stuck > cfg.give_up_after
        p.stuck[near] = 0.0
        arrived = np.flatnonzero(leader & (p.mode == WALK) & near)
        if len(arrived):
            p.mode[arrived] = DWELL
            at_poi = p.goal_poi[arrived] >= 0
            p.timer[arrived] = np.where(
                at_poi, self._dwell(rng, len(arrived)), rng.exponential(cfg.pause_mean, size=len(arrived))
            )
        # Members walk when their leader walks and stand when it stands.
        member = ~leader & (p.mode != ROBOT)
        lead_mode = p.mode[p.group]
        p.mode[member & (lead_mode == WALK)] = WALK
        p.mode[member & (lead_mode != WALK)] = DWELL
        p.goal_poi[member] = p.goal_poi[p.group[member]]
        target = self._targets()
        self._in_view = line_of_sight(sp.walkable, sp.coarse_res, p.pos, target)
        # A wanderer pushed out of view of its goal picks another one at the next decision.
        lost = leader & (p.mode == WALK) & ~self._in_view & (p.goal_poi < 0)
        p.mode[lost] = DWELL
        p.timer[lost] = 0.0

    def _refresh_robot_field(self, k: int) -> None:
        """Recompute the field to robot ``k`` once it has moved a cell since the last one."""
        robot = self._poses[k, :2]
        if np.hypot(*(robot - self._field_robot_at[k])) >= self._space.coarse_res:
            self._fields[k] = self._space.field_to(robot, self.config.field_max_distance)
            self._field_robot_at[k] = robot

    def _targets(self) -> FloatArray:
        """Where everyone heads: the goal; a spot in the ring at the robot (laid out from the
        anchor pose; blockers' from the robot itself, so they keep in front of it); the place
        beside the leader for group members walking with it (behind it where that is a wall)."""
        p = self._people
        out = p.goal.copy()
        at_robot = p.mode == ROBOT
        if at_robot.any():
            out[at_robot] = self._ring_points(at_robot)
            block = np.flatnonzero(at_robot & (p.block_until > self.time))
            if len(block):
                robot = self._poses[p.robot[block]]
                rx, ry, rth = robot[:, 0], robot[:, 1], robot[:, 2]
                st = p.stand[block]
                out[block] = np.stack(
                    [rx + st[:, 0] * np.cos(rth + st[:, 1]), ry + st[:, 0] * np.sin(rth + st[:, 1])], axis=-1
                )
        walking = np.flatnonzero((p.mode == WALK) & (p.group != np.arange(self.num_people)))
        if len(walking):
            lead = p.group[walking]
            th = p.heading[lead]
            side = np.stack([-np.sin(th), np.cos(th)], axis=-1)
            beside = p.pos[lead] + p.slot[walking][:, None] * side
            behind = p.pos[lead] - 0.8 * np.stack([np.cos(th), np.sin(th)], axis=-1)
            ok = self._space.is_walkable(beside)
            out[walking] = np.where(ok[:, None], beside, behind)
        return out

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
        # Those who cannot see where they go walk down a geodesic field around the walls: to their
        # robot (fields 0..M-1, refreshed as the robots move) or to their exhibit (fields M..).
        m = self.num_robots
        field_index = np.where(at_robot, p.robot, np.where(p.goal_poi >= 0, p.goal_poi + m, -1))
        for k in np.unique(p.robot[moving & ~self._in_view & at_robot]).tolist():
            self._refresh_robot_field(k)
        desired = steer(
            p.pos, target, moving, self._in_view, field_index, self._fields, sp.coarse_res, p.speed, cfg.tau
        )
        # Group members walking beside their leader match its velocity, plus what closes the gap;
        # those keeping a spot at the driving robot match the robot's.
        lead = p.group
        beside = (p.mode == WALK) & (lead != np.arange(self.num_people)) & self._in_view & (dist < 2.0)
        desired[beside] += p.vel[lead[beside]]
        driving = at_robot & self._moving[p.robot]  # at a robot that drives
        if driving.any():
            along = driving & self._in_view & (dist < 2.0)
            desired[along] += self._robot_vel[p.robot[along]]

        # Social forces, integration, hard constraints and gait (Helbing & Molnár 1995, Eq. 1-5).
        cap = np.minimum(cfg.speed_max, 1.3 * p.speed)
        if driving.any():
            # Those left behind by their driving robot hurry to catch up.
            hurry = driving & (dist > 1.5)
            cap[hurry] = cfg.speed_max
            desired[hurry] *= (cfg.speed_max / np.maximum(p.speed[hurry], 1e-9))[:, None]
        p.pos, p.vel, p.phase, p.heading = move_people(
            p.pos,
            p.vel,
            desired,
            cap,
            p.radius,
            p.group,
            np.where(at_robot, p.robot, -1),
            p.phase,
            p.heading,
            sp.wall_dist,
            sp.wall_dir,
            sp.res,
            sp.walkable,
            sp.coarse_res,
            self._robots,
            self._params,
            h,
        )
