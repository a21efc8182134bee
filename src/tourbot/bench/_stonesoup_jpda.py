"""The peer of the people tracker in ``tourbot bench tracking``: Stone Soup's JPDA tracker.

Stone Soup (dstl, PyPI ``stonesoup``) is what people reach for today for JPDA: Kalman filters with a
constant-velocity model, JPDA over :class:`~stonesoup.hypothesiser.probability.PDAHypothesiser`
hypotheses (gated at ``prob_gate``), computed by default with
:class:`~stonesoup.dataassociator.probability.JPDAwithEHM2`: Stone Soup's own exact JPDA that splits
the tracks into clusters sharing gated detections and computes each cluster's marginal association
probabilities with efficient hypothesis management (Horridge and Maskell 2006), the same
probabilities as the plain :class:`~stonesoup.dataassociator.probability.JPDA`, which enumerates
every joint event of all tracks at once and needs seconds per scan with 20 people; the Gaussian
mixture of each track's hypotheses reduced to one Gaussian by ``MultiTargetMixtureTracker``, tracks
started by ``MultiMeasurementInitiator`` (GNN over candidate tracks) and ended after missed updates.
It is fed exactly the person features tourbot's tracker sees, in the world frame, so the comparison
is of the trackers alone. Benchmark-only: Stone Soup is imported here and nowhere else.
"""

from __future__ import annotations

import datetime
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["StoneSoupConfig", "StoneSoupJPDA"]


@dataclass(frozen=True, slots=True)
class StoneSoupConfig:
    """The peer's parameters, matched to :class:`~tourbot.people.sjpdaf.SJPDAFConfig`'s where they
    mean the same thing (P_D, clutter density, measurement noise, misses before deletion)."""

    accel_noise: float = 1.0  # ConstantVelocity noise_diff_coeff (m^2/s^3)
    measurement_std: float = 0.1
    detection_probability: float = 0.9
    clutter_density: float = 0.02
    gate_probability: float = 0.99
    init_points: int = 3
    max_misses: int = 10
    velocity_std: float = 0.5
    associator: str = "ehm2"  # "ehm2" (exact, clustered: JPDAwithEHM2) or "jpda" (plain JPDA)


class StoneSoupJPDA:
    """Stone Soup's JPDA multi-target tracker behind a ``update(time, points)`` call."""

    def __init__(self, config: StoneSoupConfig | None = None) -> None:
        from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
        from stonesoup.dataassociator.probability import JPDA, JPDAwithEHM2
        from stonesoup.deleter.time import UpdateTimeStepsDeleter
        from stonesoup.hypothesiser.distance import DistanceHypothesiser
        from stonesoup.hypothesiser.probability import PDAHypothesiser
        from stonesoup.initiator.simple import MultiMeasurementInitiator
        from stonesoup.measures import Mahalanobis
        from stonesoup.models.measurement.linear import LinearGaussian
        from stonesoup.models.transition.linear import (
            CombinedLinearGaussianTransitionModel,
            ConstantVelocity,
        )
        from stonesoup.predictor.kalman import KalmanPredictor
        from stonesoup.tracker.simple import MultiTargetMixtureTracker
        from stonesoup.types.state import GaussianState
        from stonesoup.updater.kalman import KalmanUpdater

        cfg = config or StoneSoupConfig()
        self.config = cfg
        transition = CombinedLinearGaussianTransitionModel(
            [ConstantVelocity(cfg.accel_noise), ConstantVelocity(cfg.accel_noise)]
        )
        self.measurement_model = LinearGaussian(
            ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2) * cfg.measurement_std**2
        )
        predictor = KalmanPredictor(transition)
        updater = KalmanUpdater(self.measurement_model)
        hypothesiser = PDAHypothesiser(
            predictor=predictor,
            updater=updater,
            clutter_spatial_density=cfg.clutter_density,
            prob_detect=cfg.detection_probability,
            prob_gate=cfg.gate_probability,
        )
        v2 = cfg.velocity_std**2
        initiator = MultiMeasurementInitiator(
            prior_state=GaussianState(np.zeros((4, 1)), np.diag([0.0, v2, 0.0, v2])),
            measurement_model=self.measurement_model,
            deleter=UpdateTimeStepsDeleter(2),
            data_associator=GNNWith2DAssignment(
                DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=3.0)
            ),
            updater=updater,
            min_points=cfg.init_points,
        )
        self._tracker = MultiTargetMixtureTracker(
            initiator=initiator,
            deleter=UpdateTimeStepsDeleter(cfg.max_misses),
            detector=None,
            data_associator=(JPDA if cfg.associator == "jpda" else JPDAwithEHM2)(hypothesiser=hypothesiser),
            updater=updater,
        )
        self._ids: dict[str, int] = {}
        self._epoch = datetime.datetime(2000, 1, 1, tzinfo=datetime.UTC)

    def update(self, t: float, points: NDArray[np.float64]) -> list[tuple[int, float, float]]:
        """Feed the features ``(M, 2)`` of the scan at time ``t``; the tracks ``(id, x, y)``."""
        from stonesoup.types.detection import Detection

        time = self._epoch + datetime.timedelta(seconds=float(t))
        detections = {
            Detection(np.array([[x], [y]]), timestamp=time, measurement_model=self.measurement_model)
            for x, y in np.asarray(points, dtype=np.float64).reshape(-1, 2)
        }
        _, tracks = self._tracker.update_tracker(time, detections)
        out = []
        for track in tracks:
            tid = self._ids.setdefault(str(track.id), len(self._ids) + 1)
            sv: Any = track.state_vector
            out.append((tid, float(sv[0, 0]), float(sv[2, 0])))
        return out
