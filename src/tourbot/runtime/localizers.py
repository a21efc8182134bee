"""Adapters from the project's localizers to the runtime's ``Localizer`` protocol."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from tourbot.records import Odometry, Scan
from tourbot.runtime.interfaces import PoseBelief
from tourbot.runtime.snapshot import PoseEstimate, SampleSummary

if TYPE_CHECKING:
    from tourbot.localization.mcl import MonteCarloLocalization

__all__ = ["MCLLocalizer"]


class MCLLocalizer:
    """Monte Carlo localization (with the novelty filter by default) as a runtime localizer.

    Each scan is integrated at its own odometry pose (``scan.odom``; the last odometry reading when
    a source gives none). ``display_samples`` samples, drawn by weight, go to the snapshot.
    """

    def __init__(self, mcl: MonteCarloLocalization, display_samples: int = 200, seed: int = 0) -> None:
        self.mcl = mcl
        self.display_samples = display_samples
        self._odom: tuple[float, float, float] | None = None
        self._rng = np.random.default_rng(seed)

    def on_odometry(self, odom: Odometry) -> None:
        self._odom = odom.pose

    def on_scan(self, scan: Scan) -> PoseBelief | None:
        odom = scan.odom if scan.odom is not None else self._odom
        if odom is None:
            return None
        est = self.mcl.update(odom, scan)
        samples = np.asarray(self.mcl.samples, dtype=np.float64)
        weights = np.asarray(self.mcl.weights, dtype=np.float64)
        total = weights.sum()
        weights = weights / total if total > 0 else np.full(len(weights), 1.0 / max(len(weights), 1))
        cov = np.asarray(est.covariance, dtype=np.float64)
        estimate = PoseEstimate(
            float(est.pose[0]),
            float(est.pose[1]),
            float(est.pose[2]),
            (
                (float(cov[0, 0]), float(cov[0, 1]), float(cov[0, 2])),
                (float(cov[1, 0]), float(cov[1, 1]), float(cov[1, 2])),
                (float(cov[2, 0]), float(cov[2, 1]), float(cov[2, 2])),
            ),
        )
        k = min(self.display_samples, len(samples))
        idx = self._rng.choice(len(samples), size=k, p=weights) if k else np.zeros(0, dtype=np.int64)
        summary = SampleSummary(
            count=len(samples),
            n_effective=float(1.0 / np.sum(weights**2)) if len(weights) else 0.0,
            poses=tuple((float(x), float(y), float(t)) for x, y, t in samples[idx]),
        )
        return PoseBelief(estimate, samples, weights, summary)
