"""Wheel odometry with systematic and random error.

The error model is the classic one for differential drives (Borenstein and Feng 1996, "Measurement
and correction of systematic odometry errors"; random part as in the odometry motion model of
Thrun, Burgard and Fox, Probabilistic Robotics, Table 5.6): each step's true motion, decomposed into
rotation-translation-rotation, is scaled by fixed factors (unequal wheel diameters, wrong wheelbase)
and perturbed by zero-mean noise whose spread grows with the motion.

Defaults give, over the FHW tour lengths, drift of the order measured on the real FHW log
(``../shared/data/README.md``: mean absolute per-scan error of 6.4 cm / 1.7 deg against the
corrected poses, over stretches between scans).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["OdometryError", "OdometryErrorConfig"]


@dataclass(frozen=True)
class OdometryErrorConfig:
    """Systematic scale errors and random noise of the odometry.

    ``translation_scale`` and ``rotation_scale``: factors on every measured translation and
    rotation (1 = none). ``drift``: rad of spurious rotation per metre driven (unequal wheels).
    ``alpha1..alpha4``: Probabilistic Robotics Table 5.6 noise (rot from rot, rot from trans,
    trans from trans, trans from rot), as standard deviations per unit motion.
    """

    translation_scale: float = 1.015
    rotation_scale: float = 0.985
    drift: float = math.radians(0.5)
    alpha1: float = 0.02
    alpha2: float = math.radians(0.5)
    alpha3: float = 0.02
    alpha4: float = 0.005


class OdometryError:
    """Accumulates the odometry pose the wheel encoders report as the true robot moves."""

    def __init__(self, config: OdometryErrorConfig, start: tuple[float, float, float] = (0.0, 0.0, 0.0)):
        self.config = config
        self.pose = (float(start[0]), float(start[1]), float(start[2]))

    def step(
        self,
        true_before: tuple[float, float, float],
        true_after: tuple[float, float, float],
        rng: np.random.Generator,
    ) -> tuple[float, float, float]:
        """Advance by the true motion between two poses; returns the new odometry pose."""
        c = self.config
        x0, y0, th0 = true_before
        cb, sb = math.cos(th0), math.sin(th0)
        gx, gy = true_after[0] - x0, true_after[1] - y0
        dx, dy = cb * gx + sb * gy, -sb * gx + cb * gy  # the motion in the frame of the start
        dth = math.remainder(true_after[2] - th0, 2.0 * math.pi)
        trans = math.hypot(dx, dy)
        rot1 = math.atan2(dy, dx) if trans > 1e-6 else 0.0
        rot2 = math.remainder(dth - rot1, 2.0 * math.pi)
        s_rot1 = c.alpha1 * abs(rot1) + c.alpha2 * trans
        s_trans = c.alpha3 * trans + c.alpha4 * (abs(rot1) + abs(rot2))
        s_rot2 = c.alpha1 * abs(rot2) + c.alpha2 * trans
        n = rng.standard_normal(3)
        rot1_m = rot1 * c.rotation_scale + s_rot1 * n[0]
        trans_m = trans * c.translation_scale + s_trans * n[1]
        rot2_m = rot2 * c.rotation_scale + s_rot2 * n[2] + c.drift * trans
        x, y, th = self.pose
        x += trans_m * math.cos(th + rot1_m)
        y += trans_m * math.sin(th + rot1_m)
        th = math.remainder(th + rot1_m + rot2_m, 2.0 * math.pi)
        self.pose = (x, y, th)
        return self.pose
