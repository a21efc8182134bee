"""What a localizer answers after each update: plain data shared by MCL and grid Markov localization.

An estimator keeps its belief (samples or a grid) to itself; what the rest of the system reads
(the navigator, the recorder, the web page, the benchmarks) is this snapshot.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["LocalizationEstimate"]


@dataclass(frozen=True)
class LocalizationEstimate:
    """The pose estimate after one update of a localizer.

    - ``pose``: ``(3,)`` world pose ``(x, y, theta)``; for MCL the weighted mean of the best
      cluster of samples, for the grid the mean of the most probable mode.
    - ``covariance``: ``(3, 3)`` covariance of that estimate (x, y, theta; theta differences
      wrapped).
    - ``used_beams``: ``(B,)`` bool, the beams integrated in this update (after the max-range check
      and the entropy or novelty filter of Fox et al. 1998, Eq. 3-6); all False when the sensor
      update was skipped.
    - ``n_samples``: the number of hypotheses held (samples for MCL, non-negligible cells for grid).
    - ``updated``: whether the scan was integrated (a localizer may skip scans taken while the robot
      stands still).
    - ``update_seconds``: wall-clock time of this update.
    - ``info``: small, method-specific figures (e.g. injected samples, effective sample size).
    """

    timestamp: float
    pose: NDArray[np.float64]
    covariance: NDArray[np.float64]
    used_beams: NDArray[np.bool_]
    n_samples: int
    updated: bool = True
    update_seconds: float = 0.0
    info: dict[str, float] = field(default_factory=dict)

    @property
    def n_used_beams(self) -> int:
        """How many beams were integrated."""
        return int(np.count_nonzero(self.used_beams))

    @property
    def position_std(self) -> float:
        """Square root of the trace of the position covariance, metres (a one-number spread)."""
        return float(np.sqrt(max(self.covariance[0, 0] + self.covariance[1, 1], 0.0)))
