"""The ceiling camera as a sensor of Monte Carlo localization (the paper's future work, Sec. VI:
fusion with the laser and odometry).

:class:`CeilingLikelihood` satisfies the MCL seam's ``PoseLikelihood`` protocol
(``log_likelihood(poses (N, 3)) -> (N,)`` for the latest measurement it holds): the log likelihood
of a pose is Alg. 2's accumulated error read as a Laplace law on the pixel distances,
``log p(image | P) = -epsilon_P / scale``: an associated light costs its pixel error, a detection
left unexplained costs the association threshold (a robust, bounded penalty for visitors' heads,
windows and spotlights). :func:`recovery_poses` turns the global hypotheses of an image into the
candidate poses offered to MCL's recovery (``mcl.inject``).

:class:`CeilingSensor` is the whole sensor for one image: the lights detected (Sec. III), the
likelihood MCL weighs its samples with at the image's time (``mcl.weigh``), and the poses of the
image's global hypotheses (Alg. 3) spread a little and offered to MCL's recovery. When two
images in a row each give one unambiguous pose, consistent with each other through the odometry,
and both lie farther than ``reset_distance`` from the robot's estimate, the sensor says so
(:attr:`CeilingMeasurement.reset`): the track is wrong (a kidnap) and restarts there. A kidnapped
robot among visitors, whose laser sees mostly people, then finds itself again from the ceiling;
where the ceiling is symmetric (a regular grid of lights) no image is unambiguous, the hypotheses
are offered to recovery and the laser must pick.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.ceiling.detection import DetectionConfig, detect_lights
from tourbot.ceiling.merit import merit_fast
from tourbot.ceiling.minimize import CeilingLocalizer, Localization, LocalizerConfig
from tourbot.ceiling.rig import CeilingCamera
from tourbot.geometry import compose, relative, wrap_angle
from tourbot.maps.grid import OccupancyGrid

__all__ = ["CeilingLikelihood", "CeilingMeasurement", "CeilingSensor", "FusionConfig", "recovery_poses"]

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


@dataclass(frozen=True)
class FusionConfig:
    """The ceiling camera inside MCL.

    ``threshold``/``scale``: the likelihood's association threshold and Laplace scale (pixels);
    ``min_lights``: an image with fewer detected lights gives no global hypotheses (one or two
    lights fit too many poses); ``offered``/``spread``: how many poses are offered to recovery
    around each hypothesis, and their standard deviations (m, m, rad).
    """

    threshold: float = 25.0
    scale: float = 5.0
    min_lights: int = 3
    offered: int = 10
    spread: tuple[float, float, float] = (0.1, 0.1, 0.05)
    reset_distance: float = 1.0
    agreement: float = 0.3
    detection: DetectionConfig = field(default_factory=DetectionConfig)
    localizer: LocalizerConfig = field(default_factory=LocalizerConfig)

    def __post_init__(self) -> None:
        if self.min_lights < 1 or self.offered < 0 or min(self.spread) < 0:
            raise ValueError("FusionConfig needs min_lights >= 1, offered >= 0 and spreads >= 0")


@dataclass(frozen=True)
class CeilingMeasurement:
    """One image as MCL's sensor: the detected lights, the likelihood of poses, the hypotheses of
    the image alone and the poses offered to recovery, and the seconds it took."""

    detections: FloatArray
    likelihood: CeilingLikelihood
    hypotheses: Localization | None
    offered: FloatArray
    seconds: float
    reset: FloatArray | None = None


class FusedFilter(Protocol):
    """What :meth:`CeilingSensor.fuse` needs of Monte Carlo localization (its seams)."""

    @property
    def last_estimate(self) -> Any: ...

    def weigh(self, odom_pose: ArrayLike, likelihood: CeilingLikelihood) -> None: ...

    def inject(self, poses: ArrayLike) -> None: ...

    def reset_tracking(self, pose: ArrayLike, cov: ArrayLike | None = None) -> None: ...


class CeilingSensor:
    """The upward camera over a site's ceiling lights, as a second sensor of MCL."""

    def __init__(
        self,
        camera: CeilingCamera,
        lights: ArrayLike,
        free_space: OccupancyGrid,
        config: FusionConfig | None = None,
        seed: int = 0,
    ) -> None:
        self.camera = camera
        self.config = cfg = config or FusionConfig()
        self.lights = np.asarray(lights, dtype=np.float64).reshape(-1, 3)
        self.localizer = CeilingLocalizer(camera, self.lights, free_space, cfg.localizer)
        self._rng = np.random.default_rng([seed, 16])
        self._fix: tuple[FloatArray, FloatArray] | None = None  # the last disagreeing fix, its odometry

    def measure(
        self, pixels: NDArray[np.uint8], estimate: ArrayLike | None = None, odom: ArrayLike | None = None
    ) -> CeilingMeasurement:
        """Detect the lights of one image; its likelihood, the poses it offers to recovery, and
        whether the robot's ``estimate`` (at odometry pose ``odom``) must restart (module docstring)."""
        t0 = time.perf_counter()
        cfg = self.config
        det = detect_lights(pixels, self.camera, cfg.detection).centroids
        likelihood = CeilingLikelihood(self.camera, self.lights, cfg.threshold, cfg.scale)
        likelihood.set_detections(det)
        hypotheses: Localization | None = None
        offered = np.zeros((0, 3))
        if len(det) >= cfg.min_lights:
            hypotheses = self.localizer.locate(det, self._rng)
            centres = recovery_poses(hypotheses)
            if len(centres) and cfg.offered:
                noise = self._rng.normal(0.0, cfg.spread, (len(centres), cfg.offered, 3))
                offered = (centres[:, None, :] + noise).reshape(-1, 3)
                offered[:, 2] = wrap_angle(offered[:, 2])
        reset = self._reset(hypotheses, estimate, odom)
        return CeilingMeasurement(det, likelihood, hypotheses, offered, time.perf_counter() - t0, reset)

    def fuse(self, mcl: FusedFilter, pixels: NDArray[np.uint8], odom: ArrayLike) -> CeilingMeasurement:
        """One image into ``mcl`` at odometry pose ``odom``: restart the track at the camera's fix
        when it was kidnapped, else weigh the samples and offer the image's hypotheses."""
        est = mcl.last_estimate
        m = self.measure(pixels, None if est is None else est.pose, odom)
        if m.reset is not None:
            mcl.reset_tracking(m.reset)
            return m
        mcl.weigh(odom, m.likelihood)
        if len(m.offered):
            mcl.inject(m.offered)
        return m

    def _reset(
        self, hyp: Localization | None, estimate: ArrayLike | None, odom: ArrayLike | None
    ) -> FloatArray | None:
        cfg = self.config
        if hyp is None or hyp.best is None or hyp.ambiguous or estimate is None or odom is None:
            self._fix = None
            return None
        fix = np.asarray(hyp.best.pose, dtype=np.float64)
        est = np.asarray(estimate, dtype=np.float64).reshape(3)
        o = np.asarray(odom, dtype=np.float64).reshape(3)
        if np.hypot(*(fix[:2] - est[:2])) <= cfg.reset_distance:
            self._fix = None
            return None
        previous, self._fix = self._fix, (fix, o)
        if previous is None:
            return None
        carried = compose(previous[0], relative(previous[1], o))  # the last fix moved by the odometry
        if np.hypot(*(carried[:2] - fix[:2])) > cfg.agreement:
            return None
        self._fix = None
        return fix
