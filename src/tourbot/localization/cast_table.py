"""A table of expected ranges on a lattice of the free space, to screen reset candidates.

The reset search of Monte Carlo localization (``MonteCarloLocalization._scan_drawn_poses``)
screens uniform candidates by the likelihood field of the scan's longest returns: cheap, but blind
where the map's walls around the robot are short and the crowd hides the rest (a nook), since
the field scores an endpoint and many places have some wall at a metre. The beam model with ray
cast expected ranges (Fox et al. 1998 Sec. 2.3, Probabilistic Robotics Table 6.1) tells them
apart, but ray casting every candidate is too slow. This table casts once per map: the expected
range ``o_l`` of ``directions`` beams (uniform over the circle) from every laser position of a
lattice with ``spacing`` over the free space. A heading of the lattice turns a scan's beams into
directions of the table, so scoring a scan at every lattice position and heading is a look-up
per beam: ``sum_b log p(z_b | o_(p, k + d_b))`` with ``d_b`` the beam's angle in table steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import wrap_angle
from tourbot.maps.beam_model import BeamModel
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.raycast import RayCaster

__all__ = ["CastTable", "best_headings", "best_headings_reference"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: expected ranges are stored in steps of this many metres (the beam model's sigma_hit is 0.2 m)
_STEP = 0.05


@numba.njit(cache=True, fastmath=True)
def _best_headings_kernel(
    table: NDArray[np.uint16],
    offsets: IntArray,
    loglik: NDArray[np.float32],
    score: FloatArray,
    heading: IntArray,
) -> None:
    n_pos, n_dir = table.shape
    n_beams = offsets.shape[0]
    acc = np.empty(n_dir, dtype=np.float32)
    row = np.empty(2 * n_dir, dtype=np.int64)
    for p in range(n_pos):
        for d in range(n_dir):
            row[d] = table[p, d]
            row[d + n_dir] = table[p, d]
            acc[d] = 0.0
        for b in range(n_beams):
            o = offsets[b]
            lb = loglik[b]
            for k in range(n_dir):
                acc[k] += lb[row[k + o]]
        best = acc[0]
        arg = 0
        for k in range(1, n_dir):
            if acc[k] > best:
                best = acc[k]
                arg = k
        score[p] = best
        heading[p] = arg


def best_headings(
    table: NDArray[np.uint16], offsets: IntArray, loglik: FloatArray
) -> tuple[FloatArray, IntArray]:
    """Per lattice position ``p`` (row of ``table``, expected ranges in 5 cm steps per direction), the
    best heading step ``k`` and its score ``sum_b loglik[b, table[p, (k + offsets[b]) % D]]``
    (``loglik[b, c]``: the log-likelihood of beam ``b``'s reading when ``c`` steps are expected;
    the first heading of the highest score wins a tie)."""
    n_pos = table.shape[0]
    score = np.empty(n_pos, dtype=np.float64)
    heading = np.empty(n_pos, dtype=np.int64)
    if n_pos and table.shape[1]:
        _best_headings_kernel(
            np.ascontiguousarray(table),
            np.ascontiguousarray(np.asarray(offsets, dtype=np.int64) % table.shape[1]),
            np.ascontiguousarray(loglik, dtype=np.float32),
            score,
            heading,
        )
    return score, heading


def best_headings_reference(
    table: NDArray[np.uint16], offsets: IntArray, loglik: FloatArray
) -> tuple[FloatArray, IntArray]:
    """:func:`best_headings` in plain numpy (the kernel's reference)."""
    n_dir = table.shape[1]
    cols = (np.arange(n_dir)[:, None] + np.asarray(offsets, dtype=np.int64)[None, :]) % n_dir  # (D, B)
    vals = table[:, cols].astype(np.int64)  # (P, D, B)
    scores = loglik[np.arange(cols.shape[1])[None, None, :], vals].sum(axis=2)  # (P, D)
    heading = np.argmax(scores, axis=1)
    return scores[np.arange(table.shape[0]), heading], heading.astype(np.int64)


@dataclass(frozen=True)
class CastTable:
    """Expected ranges ``ranges_q`` ``(P, D)`` (uint16, in 5 cm steps, capped at ``max_range``) of ``D``
    directions ``2 pi d / D`` (world frame) from laser ``positions`` ``(P, 2)``."""

    positions: FloatArray
    ranges_q: NDArray[np.uint16]
    max_range: float

    @property
    def directions(self) -> int:
        return int(self.ranges_q.shape[1])

    @classmethod
    def build(cls, grid: OccupancyGrid, caster: RayCaster, spacing: float, directions: int) -> CastTable:
        """Cast ``directions`` beams from the centre of every free cell of a lattice of ``spacing``
        metres (every ``round(spacing / resolution)``-th cell in both axes)."""
        step = max(1, round(spacing / grid.resolution))
        free = grid.free()
        rows, cols = np.nonzero(free[::step, ::step])
        cells = np.column_stack([rows * step, cols * step])
        local = (cells[:, ::-1] + 0.5) * grid.resolution
        centres = grid.grid_to_world(np.column_stack([local, np.zeros(cells.shape[0]) - grid.origin[2]]))
        poses = np.column_stack([centres[:, :2], np.zeros(cells.shape[0])])
        angles = 2.0 * math.pi * np.arange(directions) / directions
        ranges = caster.cast(poses, angles) if poses.shape[0] else np.zeros((0, directions), np.float32)
        q = np.minimum(
            np.round(np.asarray(ranges, dtype=np.float64) / _STEP), round(caster.max_range / _STEP)
        )
        return cls(np.ascontiguousarray(poses[:, :2]), q.astype(np.uint16), float(caster.max_range))

    def screen(
        self, measured: FloatArray, angles: FloatArray, model: BeamModel, n: int
    ) -> tuple[FloatArray, FloatArray]:
        """The ``n`` best laser poses ``(n, 3)`` (lattice positions, each at its best heading) for
        the readings ``measured`` taken at laser-frame ``angles``, by the beam model ``model``,
        and their log-likelihoods. A beam's angle is rounded to the table's directions."""
        n_dir = self.directions
        step = 2.0 * math.pi / n_dir
        offsets = np.round(np.asarray(angles, dtype=np.float64) / step).astype(np.int64) % n_dir
        n_q = round(self.max_range / _STEP) + 1
        expected = np.arange(n_q, dtype=np.float64) * _STEP
        z = np.asarray(measured, dtype=np.float64)
        p = model.probabilities(np.broadcast_to(expected[:, None], (n_q, z.size)), z, self.max_range)
        loglik = np.ascontiguousarray(np.log(np.maximum(p, 1e-300)).T)  # (B, n_q)
        score, heading = best_headings(self.ranges_q, offsets, loglik)
        n = min(n, score.size)
        if n <= 0:
            return np.zeros((0, 3)), np.zeros(0)
        top = np.argpartition(-score, n - 1)[:n] if n < score.size else np.arange(score.size)
        top = top[np.argsort(-score[top], kind="stable")]
        poses = np.column_stack([self.positions[top], wrap_angle(heading[top] * step)])
        return poses, score[top]
