"""Expected ranges from the free space of a map, cast once and looked up per scan.

Both grid Markov localization (Fox, Burgard, Thrun & Cremers 1998, Sec. 2.3: the expected distance
``o_l`` of each beam is precomputed for every cell of the grid, the paper's "look-up table") and the
reset search of Monte Carlo localization score poses under the beam model (Probabilistic Robotics
Table 6.1) from ray-cast expected ranges. :class:`ExpectedRangeTable` holds ``bins[p, j]``, the range
in units of ``range_bin`` seen from position ``p`` along direction ``j * angle_step`` (relative to
the heading of the pose it was cast from), capped at ``max_range``. A heading of ``k`` steps turns a
scan's beams into columns of the table, so scoring a scan at every position and heading is one
look-up per beam: ``sum_b log p(z_b | o_(p, k + d_b))`` (:func:`best_headings`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import wrap_angle
from tourbot.localization.errors import LocalizationError
from tourbot.maps.beam_model import BeamModel
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.raycast import RangeCaster

__all__ = ["ExpectedRangeTable", "best_headings", "best_headings_reference"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
Progress = Callable[[int, int], None]


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
class ExpectedRangeTable:
    """Expected ranges ``bins`` ``(P, D)`` (uint16, in units of ``range_bin``, capped at
    ``max_range``) along ``D`` directions ``j * angle_step``; ``positions`` ``(P, 2)``, when known,
    are the world positions they were cast from (directions then in the world frame)."""

    bins: NDArray[np.uint16]
    angle_step: float
    range_bin: float
    max_range: float
    positions: FloatArray | None = None

    @property
    def n_bins(self) -> int:
        return round(self.max_range / self.range_bin) + 1

    @property
    def n_angles(self) -> int:
        return int(self.bins.shape[1])

    @classmethod
    def cast(
        cls,
        poses: FloatArray,
        angles: FloatArray,
        caster: RangeCaster,
        max_range: float,
        range_bin: float,
        progress: Progress | None = None,
        chunk: int = 2048,
    ) -> ExpectedRangeTable:
        """Cast ``angles`` (uniform over the circle, relative to each pose's heading) from every
        pose ``(P, 3)``, in chunks of ``chunk`` poses (``progress(done, total)`` after each)."""
        if max_range / range_bin + 1 >= np.iinfo(np.uint16).max:
            raise LocalizationError(f"max_range {max_range} m needs too many bins of {range_bin} m")
        n = poses.shape[0]
        out = np.empty((n, angles.size), dtype=np.uint16)
        top = round(max_range / range_bin)
        for start in range(0, n, chunk):
            stop = min(start + chunk, n)
            ranges = np.asarray(caster.cast(poses[start:stop], angles), dtype=np.float64)
            out[start:stop] = np.clip(np.round(ranges / range_bin), 0, top).astype(np.uint16)
            if progress is not None:
                progress(stop, n)
        step = 2.0 * math.pi / max(1, angles.size)
        return cls(out, step, float(range_bin), float(max_range), np.ascontiguousarray(poses[:, :2]))

    @classmethod
    def on_lattice(
        cls,
        grid: OccupancyGrid,
        caster: RangeCaster,
        spacing: float,
        directions: int,
        range_bin: float = 0.05,
    ) -> ExpectedRangeTable:
        """Cast ``directions`` world-frame beams from the centre of every free cell of a lattice of
        ``spacing`` metres (every ``round(spacing / resolution)``-th cell in both axes)."""
        step = max(1, round(spacing / grid.resolution))
        rows, cols = np.nonzero(grid.free()[::step, ::step])
        cells = np.column_stack([rows * step, cols * step])
        local = (cells[:, ::-1] + 0.5) * grid.resolution
        centres = grid.grid_to_world(np.column_stack([local, np.zeros(cells.shape[0]) - grid.origin[2]]))
        poses = np.column_stack([centres[:, :2], np.zeros(cells.shape[0])])
        angles = 2.0 * math.pi * np.arange(directions) / directions
        return cls.cast(
            poses, angles, caster, float(caster.max_range), range_bin, chunk=max(1, poses.shape[0])
        )

    def screen(
        self, measured: FloatArray, angles: FloatArray, model: BeamModel, n: int
    ) -> tuple[FloatArray, FloatArray]:
        """The ``n`` best laser poses ``(n, 3)`` (positions, each at its best heading) for the
        readings ``measured`` taken at laser-frame ``angles``, by the beam model ``model``, and
        their log-likelihoods. A beam's angle is rounded to the table's directions."""
        if self.positions is None:
            raise LocalizationError("this expected-range table does not know its positions")
        n_dir = self.n_angles
        step = 2.0 * math.pi / n_dir
        offsets = np.round(np.asarray(angles, dtype=np.float64) / step).astype(np.int64) % n_dir
        expected = np.arange(self.n_bins, dtype=np.float64) * self.range_bin
        z = np.asarray(measured, dtype=np.float64)
        p = model.probabilities(np.broadcast_to(expected[:, None], (self.n_bins, z.size)), z, self.max_range)
        loglik = np.ascontiguousarray(np.log(np.maximum(p, 1e-300)).T)  # (B, n_bins)
        score, heading = best_headings(self.bins, offsets, loglik)
        n = min(n, score.size)
        if n <= 0:
            return np.zeros((0, 3)), np.zeros(0)
        top = np.argpartition(-score, n - 1)[:n] if n < score.size else np.arange(score.size)
        top = top[np.argsort(-score[top], kind="stable")]
        poses = np.column_stack([self.positions[top], wrap_angle(heading[top] * step)])
        return poses, score[top]

    def save(self, path: Path) -> None:
        """Write the table to ``path`` (``.npz``), atomically (a temporary file renamed)."""
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        with tmp.open("wb") as fh:
            np.savez(
                fh,
                bins=self.bins,
                meta=np.array([self.angle_step, self.range_bin, self.max_range], dtype=np.float64),
            )
        tmp.replace(path)

    @classmethod
    def load(cls, path: Path) -> ExpectedRangeTable:
        """Read a table written by :meth:`save`; :class:`LocalizationError` if it is not one."""
        try:
            with np.load(path) as data:
                bins = np.asarray(data["bins"])
                meta = np.asarray(data["meta"], dtype=np.float64)
        except (OSError, ValueError, KeyError) as exc:
            raise LocalizationError(f"{path}: not an expected-range table ({exc})") from exc
        if bins.dtype != np.uint16 or bins.ndim != 2 or meta.shape != (3,):
            raise LocalizationError(f"{path}: not an expected-range table (bins {bins.dtype} {bins.shape})")
        return cls(bins, float(meta[0]), float(meta[1]), float(meta[2]))
