"""Several robots in one museum: their true poses shared between the robots' processes.

Each simulated robot runs in its own process (``tourbot serve --robots N``) with its own
simulator. A :class:`FleetPoses` is a small block of shared memory (``multiprocessing.
shared_memory``) holding every robot's true pose: each simulator writes its own after each step
and reads the others', whose bodies then stand in its world. Its laser sees them (as discs of the
robots' radius) and its base stops against them, so the navigators, which only see the laser,
avoid each other as they avoid visitors. The poses are truth, used by the simulators only; a
robot's estimators never read them.

A pose is three doubles written without a lock: a reader may, rarely, see one robot's pose
half-updated from one step to the next, at most one step (10 cm) off, which the laser's noise
already exceeds.
"""

from __future__ import annotations

import math
from multiprocessing import shared_memory

import numpy as np
from numpy.typing import NDArray

__all__ = ["FleetPoses"]

_FIELDS = 4  # x, y, theta, present (1.0 once the robot has written its pose)


class FleetPoses:
    """The true poses of ``size`` robots in shared memory; the creator unlinks it on :meth:`close`."""

    def __init__(self, size: int, name: str | None = None) -> None:
        if size < 1:
            raise ValueError("a fleet has at least one robot")
        self.size = size
        nbytes = size * _FIELDS * 8
        if name is None:
            self._shm = shared_memory.SharedMemory(create=True, size=nbytes)
            self._owner = True
        else:
            self._shm = shared_memory.SharedMemory(name=name)
            self._owner = False
        self._poses: NDArray[np.float64] = np.ndarray((size, _FIELDS), dtype=np.float64, buffer=self._shm.buf)
        if self._owner:
            self._poses[:] = 0.0

    @property
    def name(self) -> str:
        """What another process gives :class:`FleetPoses` to attach to the same poses."""
        return str(self._shm.name)

    def write(self, index: int, pose: tuple[float, float, float]) -> None:
        """Robot ``index``'s true pose now."""
        self._poses[index, :3] = pose
        self._poses[index, 3] = 1.0

    def others(self, index: int) -> NDArray[np.float64]:
        """The positions ``(M, 2)`` of the other robots that have written a pose."""
        rows = self._poses.copy()
        keep = (rows[:, 3] == 1.0) & (np.arange(self.size) != index)
        out = rows[keep, :2]
        return out[np.isfinite(out).all(axis=1)]

    def close(self) -> None:
        """Detach (and, for the creator, free the memory)."""
        del self._poses
        self._shm.close()
        if self._owner:
            self._shm.unlink()


def nearest(others: NDArray[np.float64], x: float, y: float) -> float:
    """The distance from ``(x, y)`` to the nearest of ``others`` (inf when there is none)."""
    if not len(others):
        return math.inf
    return float(np.min(np.hypot(others[:, 0] - x, others[:, 1] - y)))
