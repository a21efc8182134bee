"""Several robots in one museum: one world shared between the robots' processes.

Each simulated robot runs in its own process (``tourbot serve --robots N``) with its own
simulator. A :class:`FleetPoses` is a small block of shared memory (``multiprocessing.
shared_memory``) holding the world they share:

* every robot's true pose and velocity: each simulator writes its own after each step (and its
  start pose when it is built) and reads the others', whose bodies then stand in its world. Its
  laser sees them (as discs of the robots' radius) and its base stops against them, so the
  navigators, which only see the laser, avoid each other as they avoid visitors;
* the visitors: one crowd, stepped by the museum's world (:class:`tourbot.sim.world.MuseumWorld`,
  a process of its own under ``tourbot serve``) with every robot's pose, and written here after
  each of its steps (centres, velocities and the legs the laser sees); the robots' simulators
  read it and run no crowd of their own. So every laser sees the same visitors, every base stops
  at them, and the visitors gather at, follow and step aside for every robot.

Why the crowd is not in a robot's process (it was, in the first robot's): a robot's process that
dies is restarted by the server, and the crowd would restart with it (every visitor put back
where the crowd was drawn). Owned by the world, it goes on walking: the dead robot's body stays
where it stopped (its last pose), and the restarted robot writes its pose again.

Truth, used by the simulators only; a robot's estimators never read it. A pose is three doubles
written without a lock: a reader may, rarely, see one robot's pose half-updated from one step to
the next, at most one step (10 cm) off, which the laser's noise already exceeds. The crowd is
larger and is written under a sequence counter (odd while writing): a reader that saw it change
reads again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from multiprocessing import shared_memory

import numpy as np
from numpy.typing import NDArray

__all__ = ["FleetCrowd", "FleetPoses"]

_FIELDS = 7  # x, y, theta, present (1.0 once written), vx, vy (world, m/s), writes so far
_HEADER = 4  # the crowd's sequence counter, visitors, leg circles, time
_PERSON = 4  # x, y, vx, vy
_CIRCLE = 3  # x, y, radius
#: The most visitors the shared crowd holds (the peak-hour FHW crowd has about 210).
MAX_VISITORS = 1024


@dataclass(frozen=True)
class FleetCrowd:
    """The shared crowd at one instant (world frame): visitors' centres and velocities ``(N, 2)``,
    and the circles the laser sees (legs or bodies, ``(K, 2)`` and ``(K,)``)."""

    time: float
    positions: NDArray[np.float64]
    velocities: NDArray[np.float64]
    centres: NDArray[np.float64]
    radii: NDArray[np.float64]


class FleetPoses:
    """The true poses of ``size`` robots in shared memory; the creator unlinks it on :meth:`close`."""

    def __init__(self, size: int, name: str | None = None) -> None:
        if size < 1:
            raise ValueError("a fleet has at least one robot")
        self.size = size
        floats = size * _FIELDS + _HEADER + MAX_VISITORS * (_PERSON + 2 * _CIRCLE)
        nbytes = floats * 8
        if name is None:
            self._shm = shared_memory.SharedMemory(create=True, size=nbytes)
            self._owner = True
        else:
            self._shm = shared_memory.SharedMemory(name=name)
            self._owner = False
        block: NDArray[np.float64] = np.ndarray((floats,), dtype=np.float64, buffer=self._shm.buf)
        self._poses = block[: size * _FIELDS].reshape(size, _FIELDS)
        start = size * _FIELDS
        self._header = block[start : start + _HEADER]
        start += _HEADER
        self._people = block[start : start + MAX_VISITORS * _PERSON].reshape(MAX_VISITORS, _PERSON)
        start += MAX_VISITORS * _PERSON
        self._circles = block[start:].reshape(2 * MAX_VISITORS, _CIRCLE)
        self._block = block
        if self._owner:
            block[:] = 0.0

    @property
    def name(self) -> str:
        """What another process gives :class:`FleetPoses` to attach to the same poses."""
        return str(self._shm.name)

    def write(
        self, index: int, pose: tuple[float, float, float], velocity: tuple[float, float] = (0.0, 0.0)
    ) -> None:
        """Robot ``index``'s true pose and velocity (world, m/s) now."""
        row = self._poses[index]
        row[:3] = pose
        row[4:6] = velocity
        row[3] = 1.0
        row[6] += 1.0

    def present(self) -> NDArray[np.bool_]:
        """Which robots have written a pose, ``(size,)``."""
        return np.asarray(self._poses[:, 3] == 1.0)

    def poses(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Every robot's pose ``(size, 3)``, velocity ``(size, 2)`` and count of writes ``(size,)``
        (a count that stops growing: a robot that no longer steps)."""
        rows = self._poses.copy()
        return rows[:, :3], rows[:, 4:6], rows[:, 6]

    def others(self, index: int) -> NDArray[np.float64]:
        """The positions ``(M, 2)`` of the other robots that have written a pose."""
        rows = self._poses.copy()
        keep = (rows[:, 3] == 1.0) & (np.arange(self.size) != index)
        out = rows[keep, :2]
        return out[np.isfinite(out).all(axis=1)]

    def write_crowd(
        self,
        time: float,
        positions: NDArray[np.float64],
        velocities: NDArray[np.float64],
        centres: NDArray[np.float64],
        radii: NDArray[np.float64],
    ) -> None:
        """The world's crowd now (at most :data:`MAX_VISITORS` visitors are shared)."""
        n = min(len(positions), MAX_VISITORS)
        k = min(len(radii), 2 * MAX_VISITORS)
        head = self._header
        head[0] += 1.0  # odd: being written
        self._people[:n, :2] = positions[:n]
        self._people[:n, 2:] = velocities[:n]
        self._circles[:k, :2] = centres[:k]
        self._circles[:k, 2] = radii[:k]
        head[1], head[2], head[3] = n, k, time
        head[0] += 1.0

    def read_crowd(self) -> FleetCrowd | None:
        """The crowd the world last wrote (None before its first write)."""
        head = self._header
        for _ in range(100):
            seq = float(head[0])
            if seq == 0.0:
                return None
            if seq % 2.0 == 1.0:
                continue
            n, k, time = int(head[1]), int(head[2]), float(head[3])
            people = self._people[:n].copy()
            circles = self._circles[:k].copy()
            if float(head[0]) == seq:
                return FleetCrowd(time, people[:, :2], people[:, 2:], circles[:, :2], circles[:, 2])
        return None

    def close(self) -> None:
        """Detach (and, for the creator, free the memory)."""
        del self._poses, self._header, self._people, self._circles, self._block
        self._shm.close()
        if self._owner:
            self._shm.unlink()


def nearest(others: NDArray[np.float64], x: float, y: float) -> float:
    """The distance from ``(x, y)`` to the nearest of ``others`` (inf when there is none)."""
    if not len(others):
        return math.inf
    return float(np.min(np.hypot(others[:, 0] - x, others[:, 1] - y)))
