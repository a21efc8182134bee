"""Pedestrian trajectories of the ETH and UCY recordings: ``frame  person_id  x  y`` per line.

The format of the crowd-prediction benchmarks (BIWI ETH and Hotel, Pellegrini et al. 2009; UCY
Zara and Students, Lerner et al. 2007), as redistributed by Trajectron++: whitespace-separated
columns, positions in metres on the ground plane, a frame every 0.4 s with frame numbers stepping
by 10. :class:`Trajectories` is also what the simulated crowd is sampled into for comparison
(:mod:`tourbot.sim.crowd_stats`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tourbot.errors import InputError

__all__ = ["FRAME_PERIOD", "PedestrianFormatError", "Trajectories", "read_pedestrians"]

#: Seconds between two frames of the ETH/UCY recordings (2.5 Hz).
FRAME_PERIOD = 0.4
#: Frame numbers step by this much between consecutive frames.
FRAME_STEP = 10


class PedestrianFormatError(InputError):
    """A pedestrian-trajectory file that cannot be read."""


@dataclass(frozen=True)
class Trajectories:
    """Positions of people over frames: sample ``k`` is person ``ids[k]`` at frame ``frames[k]``
    (integers, one frame = ``period`` seconds) at ``xy[k]`` metres; sorted by person, then frame."""

    frames: NDArray[np.int64]
    ids: NDArray[np.int64]
    xy: NDArray[np.float64]
    period: float = FRAME_PERIOD
    name: str = ""

    def __post_init__(self) -> None:
        order = np.lexsort((self.frames, self.ids))
        object.__setattr__(self, "frames", np.asarray(self.frames, dtype=np.int64)[order])
        object.__setattr__(self, "ids", np.asarray(self.ids, dtype=np.int64)[order])
        object.__setattr__(self, "xy", np.asarray(self.xy, dtype=np.float64).reshape(-1, 2)[order])

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def people(self) -> int:
        return len(np.unique(self.ids))

    @property
    def duration(self) -> float:
        return float(self.frames.max() - self.frames.min() + 1) * self.period if len(self) else 0.0


def read_pedestrians(path: str | Path) -> Trajectories:
    """Read an ETH/UCY file; one-line :class:`PedestrianFormatError` naming the line on bad input."""
    p = Path(path)
    if not p.is_file():
        raise PedestrianFormatError("no such file", path=p)
    rows: list[tuple[int, int, float, float]] = []
    with p.open(encoding="utf-8") as f:
        for n, line in enumerate(f, start=1):
            fields = line.split()
            if not fields or fields[0].startswith("#"):
                continue
            if len(fields) != 4:
                raise PedestrianFormatError(
                    f"expected 4 columns (frame person_id x y), got {len(fields)}", path=p, line=n
                )
            try:
                values = [float(v) for v in fields]
            except ValueError:
                raise PedestrianFormatError(f"not a number in {line.strip()!r}", path=p, line=n) from None
            frame, pid, x, y = values
            if not all(math.isfinite(v) for v in values):
                raise PedestrianFormatError("a value is not finite", path=p, line=n)
            if frame != round(frame) or round(frame) % FRAME_STEP:
                raise PedestrianFormatError(
                    f"frame {frame:g} is not a multiple of {FRAME_STEP}", path=p, line=n, field="frame"
                )
            if pid != round(pid):
                raise PedestrianFormatError(f"person id {pid:g} is not an integer", path=p, line=n)
            rows.append((round(frame) // FRAME_STEP, round(pid), x, y))
    if not rows:
        raise PedestrianFormatError("no trajectories in the file", path=p)
    a = np.array(rows, dtype=np.float64)
    ids, frames = a[:, 1].astype(np.int64), a[:, 0].astype(np.int64)
    key = ids * (int(frames.max()) + 1) + frames
    if len(np.unique(key)) != len(key):
        raise PedestrianFormatError("a person appears twice in one frame", path=p)
    return Trajectories(frames=frames, ids=ids, xy=a[:, 2:4], name=p.stem)
