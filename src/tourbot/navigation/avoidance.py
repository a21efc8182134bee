"""Local collision avoidance among moving people: the dynamic window approach.

Fox, Burgard and Thrun (1997, "The dynamic window approach to collision avoidance", the method of
the museum tour-guide robots RHINO and MINERVA): search the velocities ``(v, w)`` reachable within
one control cycle under the acceleration limits (the dynamic window), keep the admissible ones
(the robot can stop before reaching any obstacle point on the circular arc it would drive), and
pick the one maximising ``alpha * heading + beta * clearance + gamma * velocity`` (their Eq. 6).
Obstacle points are the laser's endpoints (people's legs, doors, furniture) plus the site's
invisible obstacles, all in the robot frame; the hot loop (clearance of every candidate arc to
every point) is a numba kernel with a numpy reference beside it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import wrap_angle

__all__ = ["DWAConfig", "DynamicWindow", "arc_clearance", "arc_clearance_reference"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class DWAConfig:
    """Dynamic window parameters; weights after Fox et al. (1997), Sec. 4 (heading 0.8 / 2 / 0.1
    there on a different scale; tuned here for 0.6 m/s among people)."""

    horizon: float = 2.0  # s: arcs are checked this far ahead
    steps: int = 8  # points per arc
    n_speeds: int = 5
    n_turns: int = 11
    margin: float = 0.08  # m beyond the robot's radius
    squeeze: float = 0.01  # m an arc may come closer than now when the robot is inside the margin
    heading_weight: float = 1.0
    clearance_weight: float = 0.4
    velocity_weight: float = 0.3
    clearance_cap: float = 1.0  # m: more clearance than this earns nothing
    control_period: float = 0.3  # s: the dynamic window is what the limits reach in this time


@numba.njit(cache=True)
def arc_clearance(
    speeds: FloatArray, turns: FloatArray, points: FloatArray, horizon: float, steps: int
) -> tuple[FloatArray, FloatArray]:
    """For each candidate ``(v, w)``: the smallest distance from the robot's centre to any point
    along the arc over ``horizon``, and the distance driven before that closest approach.

    ``points`` ``(P, 2)`` are in the robot frame. Returns ``(clearance (S,), distance (S,))``.
    """
    s = speeds.shape[0]
    clear = np.full(s, np.inf)
    along = np.full(s, np.inf)
    for i in range(s):
        v = speeds[i]
        w = turns[i]
        for k in range(1, steps + 1):
            t = horizon * k / steps
            if abs(w) < 1e-9:
                x = v * t
                y = 0.0
            else:
                x = v / w * math.sin(w * t)
                y = v / w * (1.0 - math.cos(w * t))
            for j in range(points.shape[0]):
                dx = points[j, 0] - x
                dy = points[j, 1] - y
                d = math.sqrt(dx * dx + dy * dy)
                if d < clear[i]:
                    clear[i] = d
                    along[i] = abs(v) * t
        # the start counts too (a point already inside the robot)
        for j in range(points.shape[0]):
            d = math.sqrt(points[j, 0] ** 2 + points[j, 1] ** 2)
            if d < clear[i]:
                clear[i] = d
                along[i] = 0.0
    return clear, along


def arc_clearance_reference(
    speeds: FloatArray, turns: FloatArray, points: FloatArray, horizon: float, steps: int
) -> tuple[FloatArray, FloatArray]:
    """Numpy reference of :func:`arc_clearance` (same ties: the earliest closest approach)."""
    t = horizon * np.arange(0, steps + 1) / steps  # (T,), t = 0 first
    v = speeds[:, None]
    w = turns[:, None]
    straight = np.abs(w) < 1e-9
    safe_w = np.where(straight, 1.0, w)
    x = np.where(straight, v * t, v / safe_w * np.sin(safe_w * t))
    y = np.where(straight, 0.0, v / safe_w * (1.0 - np.cos(safe_w * t)))
    if points.shape[0] == 0:
        inf = np.full(speeds.shape[0], np.inf)
        return inf, inf.copy()
    d = np.hypot(points[None, None, :, 0] - x[:, :, None], points[None, None, :, 1] - y[:, :, None])
    per_t = d.min(axis=2)  # (S, T)
    # the kernel visits t = dt..horizon then t = 0, keeping the first strict minimum
    order = np.r_[np.arange(1, steps + 1), 0]
    per_t = per_t[:, order]
    k = np.argmin(per_t, axis=1)
    clear = per_t[np.arange(len(k)), k]
    along = np.abs(speeds) * t[order][k]
    return clear, along


class DynamicWindow:
    """Chooses ``(v, w)`` toward a carrot point among obstacle points (both in the robot frame)."""

    def __init__(
        self,
        config: DWAConfig,
        *,
        radius: float,
        max_speed: float,
        max_turn_rate: float,
        max_accel: float,
        max_turn_accel: float,
    ) -> None:
        self.config = config
        self.radius = radius
        self.max_speed = max_speed
        self.max_turn = max_turn_rate
        self.accel = max_accel
        self.turn_accel = max_turn_accel

    def choose(
        self, speed: float, turn: float, carrot: tuple[float, float], points: FloatArray
    ) -> tuple[float, float, bool]:
        """Best ``(v, w)`` and whether any forward motion was admissible (False: blocked)."""
        cfg = self.config
        dt = cfg.control_period
        v_lo, v_hi = max(0.0, speed - self.accel * dt), min(self.max_speed, speed + self.accel * dt)
        w_lo, w_hi = (
            max(-self.max_turn, turn - self.turn_accel * dt),
            min(self.max_turn, turn + self.turn_accel * dt),
        )
        vs = np.unique(np.r_[np.linspace(v_lo, v_hi, cfg.n_speeds), 0.0])
        ws = np.unique(
            np.r_[np.linspace(w_lo, w_hi, cfg.n_turns), 0.0]
            if w_lo <= 0 <= w_hi
            else np.linspace(w_lo, w_hi, cfg.n_turns)
        )
        V, W = np.meshgrid(vs, ws, indexing="ij")
        V, W = V.ravel(), W.ravel()
        pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
        clear, along = arc_clearance(V, W, pts, cfg.horizon, cfg.steps)
        # The margin keeps the robot off obstacles; a robot already inside it (the planned path
        # cut a corner, a person stepped close) keeps what clearance it has: arcs that come no
        # closer than now (within ``squeeze``) stay admissible, or it could never move again.
        here = float(np.min(np.hypot(pts[:, 0], pts[:, 1]))) if len(pts) else math.inf
        margin = min(cfg.margin, max(here - self.radius - cfg.squeeze, 0.0))
        gap = clear - self.radius - margin
        # admissible: not touching, and able to brake within the free distance (DWA Eq. 4)
        free_run = np.where(np.isfinite(along), np.maximum(along + gap, 0.0), np.inf)
        admissible = (gap > 0.0) & (2.0 * self.accel * free_run >= V * V)
        # heading: how well the arc's end points at the carrot
        t_end = cfg.horizon * 0.5
        th = W * t_end
        straight = np.abs(W) < 1e-9
        safe_w = np.where(straight, 1.0, W)
        xe = np.where(straight, V * t_end, V / safe_w * np.sin(th))
        ye = np.where(straight, 0.0, V / safe_w * (1.0 - np.cos(th)))
        bearing = np.arctan2(carrot[1] - ye, carrot[0] - xe) - th
        heading = 1.0 - np.abs(wrap_angle(bearing)) / math.pi
        dist_goal = math.hypot(*carrot)
        score = (
            cfg.heading_weight * heading
            + cfg.clearance_weight
            * np.minimum(np.where(np.isfinite(gap), gap, cfg.clearance_cap), cfg.clearance_cap)
            / cfg.clearance_cap
            + cfg.velocity_weight * V / self.max_speed * min(1.0, dist_goal)
        )
        moving = admissible & (V > 0.05)
        if moving.any():
            k = int(np.argmax(np.where(moving, score, -np.inf)))
            return float(V[k]), float(W[k]), True
        # blocked: stop, and turn on the spot toward the carrot if that is safe
        bearing0 = math.atan2(carrot[1], carrot[0])
        spin = admissible & (V == 0.0)
        if spin.any() and abs(bearing0) > 0.3:
            cand = np.where(spin, -np.abs(W - math.copysign(self.max_turn * 0.5, bearing0)), -np.inf)
            k = int(np.argmax(cand))
            return 0.0, float(W[k]), False
        return 0.0, 0.0, False
