"""The ceiling camera as a sensor of Monte Carlo localization (the paper's future work, Sec. VI:
fusion with the laser and odometry).

:class:`CeilingLikelihood` satisfies the MCL seam's ``PoseLikelihood`` protocol
(``log_likelihood(poses (N, 3)) -> (N,)`` for the latest measurement it holds): the log likelihood
of a pose is Alg. 2's accumulated error read as a Laplace law on the pixel distances,
``log p(image | P) = -epsilon_P / scale``: an associated light costs its pixel error, a detection
left unexplained costs the association threshold (a robust, bounded penalty for visitors' heads,
windows and spotlights). :func:`recovery_poses` turns the global hypotheses of an image into the
candidate poses offered to MCL's recovery (``mcl.inject``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.ceiling.merit import merit_fast
from tourbot.ceiling.minimize import Localization
from tourbot.ceiling.rig import CeilingCamera

__all__ = ["CeilingLikelihood", "recovery_poses"]

FloatArray = NDArray[np.float64]


class CeilingLikelihood:
    """``log_likelihood`` of robot poses for the latest image's detected lights."""

    def __init__(
        self, camera: CeilingCamera, lights: ArrayLike, threshold: float = 25.0, scale: float = 5.0
    ) -> None:
        if threshold <= 0 or scale <= 0:
            raise ValueError("CeilingLikelihood needs threshold > 0 and scale > 0")
        self.camera = camera
        self.lights = np.asarray(lights, dtype=np.float64).reshape(-1, 3)
        self.threshold = threshold
        self.scale = scale
        self._det = np.zeros((0, 2))

    def set_detections(self, detected: ArrayLike) -> None:
        """The measurement the next calls weigh poses with (an image's detected lights)."""
        self._det = np.asarray(detected, dtype=np.float64).reshape(-1, 2)

    def log_likelihood(self, poses: ArrayLike) -> FloatArray:
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        if len(self._det) == 0:
            return np.zeros(len(p))
        _, error, _ = merit_fast(self.camera, self.lights, self._det, p, self.threshold)
        return np.asarray(-error / self.scale)


def recovery_poses(result: Localization) -> FloatArray:
    """The hypotheses of one image as candidate poses ``(M, 3)`` for MCL's ``inject``."""
    return np.array([h.pose for h in result.hypotheses], dtype=np.float64).reshape(-1, 3)
