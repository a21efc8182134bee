"""Adapters from the project's localizers to the runtime's ``Localizer`` protocol."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import wrap_angle
from tourbot.interfaces import PoseBelief
from tourbot.records import Image, Odometry, Scan
from tourbot.snapshot import PoseEstimate, SampleSummary

if TYPE_CHECKING:
    from tourbot.ceiling.likelihood import CeilingSensor
    from tourbot.localization.mcl import MonteCarloLocalization

__all__ = ["MCLLocalizer", "UpdatePolicy"]


@dataclass(frozen=True)
class UpdatePolicy:
    """When and with what a scan is integrated.

    ``beam_step``: use every k-th beam (neighbouring beams are strongly correlated, Probabilistic
    Robotics Sec. 6.4; Nav2 AMCL uses 60 beams by default). A scan is integrated once the odometry
    has moved ``min_travel`` metres or turned ``min_turn`` radians since the last integration, or
    ``max_interval`` seconds have passed (Nav2 AMCL's ``update_min_d`` 0.25 m, ``update_min_a``
    0.2 rad; smaller here because people move while the robot stands).
    """

    beam_step: int = 4
    min_travel: float = 0.1
    min_turn: float = 0.1
    max_interval: float = 1.0


class MCLLocalizer:
    """Monte Carlo localization (with the novelty filter by default) as a runtime localizer.

    Each scan is integrated at its own odometry pose (``scan.odom``; the last odometry reading when
    a source gives none), under the :class:`UpdatePolicy`; between integrations the last belief
    stands. ``display_samples`` samples, drawn by weight, go to the snapshot.

    With a ``ceiling`` sensor (:class:`tourbot.ceiling.likelihood.CeilingSensor`) it is an
    ``ImageLocalizer``: each image of the upward camera weighs the samples at the image's own
    odometry pose (``mcl.weigh``) and offers the image's global hypotheses to recovery
    (``mcl.inject``); the next scan's update resamples and reports. Two unambiguous fixes far
    from the estimate restart the track there (``mcl.reset_tracking``).
    """

    def __init__(
        self,
        mcl: MonteCarloLocalization,
        policy: UpdatePolicy | None = None,
        display_samples: int = 100,
        seed: int = 0,
        ceiling: CeilingSensor | None = None,
    ) -> None:
        self.mcl = mcl
        self.ceiling = ceiling
        self.images = 0
        self.resets = 0
        self.policy = policy or UpdatePolicy()
        self.display_samples = display_samples
        self._odom: tuple[float, float, float] | None = None
        self._last: tuple[float, tuple[float, float, float]] | None = None
        self._belief: PoseBelief | None = None
        self._rng = np.random.default_rng(seed)
        self.updates = 0

    def _due(self, t: float, odom: tuple[float, float, float]) -> bool:
        if self._last is None or self._belief is None:
            return True
        t0, o0 = self._last
        p = self.policy
        moved = math.hypot(odom[0] - o0[0], odom[1] - o0[1]) >= p.min_travel
        turned = abs(float(wrap_angle(odom[2] - o0[2]))) >= p.min_turn
        return moved or turned or t - t0 >= p.max_interval

    def _decimate(self, scan: Scan) -> Scan:
        k = self.policy.beam_step
        if k <= 1:
            return scan
        g = scan.geometry
        geometry = replace(g, num_beams=len(range(0, g.num_beams, k)), angle_increment=g.angle_increment * k)
        return replace(scan, ranges=np.ascontiguousarray(scan.ranges[::k]), geometry=geometry)

    @property
    def last_update(self) -> tuple[float, tuple[float, float, float]] | None:
        """``(scan time, odometry pose)`` of the last scan integrated (None before the first)."""
        return self._last

    def on_odometry(self, odom: Odometry) -> None:
        self._odom = odom.pose

    def on_image(self, image: Image) -> PoseBelief | None:
        """An image of the upward camera (others are not for the localizer); the belief stands
        until the next scan."""
        if self.ceiling is None or image.camera != "ceiling" or self._belief is None:
            return None
        odom = image.odom if image.odom is not None else self._odom
        if odom is None:
            return None
        m = self.ceiling.fuse(self.mcl, image.pixels, odom)
        self.images += 1
        self.resets += m.reset is not None  # two unambiguous fixes far from the track: a kidnap
        return None

    def on_scan(self, scan: Scan) -> PoseBelief | None:
        odom = scan.odom if scan.odom is not None else self._odom
        if odom is None:
            return None
        if not self._due(scan.timestamp, odom):
            return self._belief
        self._last = (scan.timestamp, odom)
        self.updates += 1
        est = self.mcl.update(odom, self._decimate(scan))
        samples = np.asarray(self.mcl.samples, dtype=np.float64)
        weights = _normalised(np.asarray(self.mcl.weights, dtype=np.float64))
        # The belief integrated over (Schulz & Burgard, Eq. 8) is the track's: recovery's guesses
        # (fresh samples, up to a fifth and more of the set, anywhere on the map) have not won yet
        # and are no part of it; they stay in the displayed samples.
        fresh = self.mcl.recovery.fresh
        kept = ~fresh if fresh.shape == weights.shape and fresh.any() and not fresh.all() else None
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
            poses=tuple(tuple(p) for p in samples[idx].tolist()),
        )
        if kept is not None:
            samples, weights = samples[kept], _normalised(weights[kept])
        self._belief = PoseBelief(estimate, samples, weights, summary)
        return self._belief


def _normalised(weights: NDArray[np.float64]) -> NDArray[np.float64]:
    total = weights.sum()
    return weights / total if total > 0 else np.full(len(weights), 1.0 / max(len(weights), 1))
