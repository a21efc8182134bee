"""The simulated robot: a differential drive with velocity and acceleration limits.

The limits (:class:`tourbot.robot.DiffDriveConfig`) are the robot's description, shared with the
navigator; this module moves a simulated base within them.
"""

from __future__ import annotations

import math

from tourbot.robot import DiffDriveConfig

__all__ = ["DiffDrive", "integrate_arc"]


def integrate_arc(
    pose: tuple[float, float, float], v: float, w: float, dt: float
) -> tuple[float, float, float]:
    """Exact motion along the circular arc of constant ``(v, w)`` for ``dt`` seconds."""
    x, y, th = pose
    if abs(w) < 1e-9:
        x += v * dt * math.cos(th)
        y += v * dt * math.sin(th)
    else:
        r = v / w
        x += r * (math.sin(th + w * dt) - math.sin(th))
        y -= r * (math.cos(th + w * dt) - math.cos(th))
    th = math.remainder(th + w * dt, 2.0 * math.pi)
    return (x, y, th)


class DiffDrive:
    """The true state of the base: pose and velocities, following commands within the limits."""

    def __init__(self, config: DiffDriveConfig, pose: tuple[float, float, float]) -> None:
        self.config = config
        self.pose = (float(pose[0]), float(pose[1]), float(pose[2]))
        self.speed = 0.0
        self.turn_rate = 0.0
        self.cmd_speed = 0.0
        self.cmd_turn = 0.0

    def command(self, speed: float, turn_rate: float) -> None:
        """Set the commanded velocities; they are clipped to the limits."""
        c = self.config
        self.cmd_speed = min(max(float(speed), -c.max_reverse), c.max_speed)
        self.cmd_turn = min(max(float(turn_rate), -c.max_turn_rate), c.max_turn_rate)

    def next_velocities(self, dt: float) -> tuple[float, float]:
        """Velocities after ``dt`` of accelerating toward the command at the acceleration limits."""
        c = self.config
        dv = min(max(self.cmd_speed - self.speed, -c.max_accel * dt), c.max_accel * dt)
        dw = min(max(self.cmd_turn - self.turn_rate, -c.max_turn_accel * dt), c.max_turn_accel * dt)
        return self.speed + dv, self.turn_rate + dw

    def propose(self, dt: float) -> tuple[tuple[float, float, float], float, float]:
        """The pose and velocities ``dt`` from now, without moving (the simulator checks collisions)."""
        v, w = self.next_velocities(dt)
        # mean velocity over the step: the acceleration is constant within it
        pose = integrate_arc(self.pose, 0.5 * (self.speed + v), 0.5 * (self.turn_rate + w), dt)
        return pose, v, w

    def apply(self, pose: tuple[float, float, float], v: float, w: float) -> None:
        self.pose, self.speed, self.turn_rate = pose, v, w

    def halt(self) -> None:
        """Stop dead (a bump): velocities to zero, pose unchanged."""
        self.speed = self.turn_rate = 0.0
