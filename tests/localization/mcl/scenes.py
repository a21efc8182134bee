"""Crowds and kidnaps for the MCL tests in the synthetic room."""

from __future__ import annotations

import math

import numpy as np

from tourbot.geometry import compose, relative
from tourbot.localization.mcl import MonteCarloLocalization

from ..conftest import Drive


def errors(est_poses: np.ndarray, truth: np.ndarray) -> np.ndarray:
    return np.hypot(est_poses[:, 0] - truth[:, 0], est_poses[:, 1] - truth[:, 1])


def run(mcl: MonteCarloLocalization, drive: Drive) -> np.ndarray:
    return np.array([mcl.update(drive.odom[k], s).pose for k, s in enumerate(drive.scans)])


def people_in_front(truth: np.ndarray, rng: np.random.Generator) -> list[np.ndarray]:
    """Two people (four legs) 0.8-1.5 m in front of the robot at every pose."""
    out = []
    for p in truth:
        pts = []
        for _ in range(2):
            d = rng.uniform(0.8, 1.5)
            a = rng.uniform(-0.6, 0.6)
            c = compose(p, np.array([d * math.cos(a), d * math.sin(a), 0.0]))
            pts += [c[:2] + np.array([0.0, 0.12]), c[:2] - np.array([0.0, 0.12])]
        out.append(np.array(pts))
    return out


def crowd_around(truth: np.ndarray, rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """``n`` legs (10 cm circles) 0.5-1.5 m from the robot, spread over its field of view."""
    out = []
    for p in truth:
        d = rng.uniform(0.5, 1.5, n)
        a = rng.uniform(-math.pi / 2, math.pi / 2, n)
        out.append(
            np.array(
                [
                    compose(p, np.array([di * math.cos(ai), di * math.sin(ai), 0.0]))[:2]
                    for di, ai in zip(d, a, strict=True)
                ]
            )
        )
    return out


def phantom_kidnap(odom: np.ndarray, at: int, delta: np.ndarray) -> np.ndarray:
    """The odometry after a kidnap before scan ``at`` as :mod:`tourbot.sim.kidnap` makes it: a
    motion ``delta`` that never happened, carried along by every later reading."""
    out = odom.copy()
    correction = compose(compose(odom[at], delta), relative(odom[at], np.zeros(3)))
    out[at:] = compose(correction, odom[at:])
    return out
