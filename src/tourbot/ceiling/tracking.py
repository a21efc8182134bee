"""Tracking the pose between images with the odometry motion model (the paper's future work,
Sec. VI: "adding the robot action model used in the probabilistic algorithms").

Between images the pose and its covariance are carried by the odometry (the motion model of
``tourbot.localization.motion_model``, Probabilistic Robotics Table 5.6, linearised). At each image
the lights are associated from the predicted pose and the pose is refined on their pixel errors
(:meth:`CeilingLocalizer.refine`); that measurement and its covariance (``pixel_std`` squared times
the inverse of the Gauss-Newton information) are fused with the prediction in a Kalman update.

An image that the predicted pose does not explain (a measurement beyond the chi-square gate
``gate`` of the prediction, 99.9 % for three degrees of freedom; fewer than ``min_matched`` lights or than
``min_fraction`` of the detections associated, or a merit above ``max_merit`` pixels) and every
``check_every``-th image trigger global localization
(Alg. 3). A global result is taken when it is unambiguous and explains the image better than the
track: a kidnapped robot is found again from the next image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.ceiling.merit import associate
from tourbot.ceiling.minimize import CeilingLocalizer, Localization
from tourbot.geometry import compose, relative, wrap_angle
from tourbot.localization.motion_model import OdometryMotionModel

__all__ = ["CeilingTracker", "TrackState", "TrackerConfig"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class TrackerConfig:
    """Tracking settings; ``motion``: the odometry motion model (its defaults)."""

    motion: OdometryMotionModel = field(default_factory=OdometryMotionModel)
    pixel_std: float = 1.5
    min_matched: int = 3
    min_fraction: float = 0.7
    max_merit: float = 6.0
    check_every: int = 5
    better_by: float = 0.5
    gate: float = 16.3

    def __post_init__(self) -> None:
        if self.pixel_std <= 0 or self.min_matched < 2 or self.check_every < 1:
            raise ValueError("TrackerConfig needs pixel_std > 0, min_matched >= 2, check_every >= 1")


@dataclass(frozen=True)
class TrackState:
    """The tracker's estimate after an image: pose, covariance, and how it was obtained
    (``tracked``, ``global``, ``predicted`` or ``lost``), with the global hypotheses if any."""

    time: float
    pose: tuple[float, float, float] | None
    covariance: FloatArray | None
    how: str
    hypotheses: Localization | None = None


class CeilingTracker:
    """Pose tracking from ceiling images and odometry, with global relocalization."""

    def __init__(
        self, localizer: CeilingLocalizer, config: TrackerConfig | None = None, seed: int = 0
    ) -> None:
        self.localizer = localizer
        self.config = config or TrackerConfig()
        self._rng = np.random.default_rng(seed)
        self._pose: FloatArray | None = None
        self._cov = np.zeros((3, 3))
        self._odom: FloatArray | None = None
        self._images = 0
        self.state: TrackState = TrackState(0.0, None, None, "lost")

    @property
    def pose(self) -> FloatArray | None:
        return None if self._pose is None else self._pose.copy()

    def on_odometry(self, odom: ArrayLike) -> None:
        """Carry the pose by the odometry motion since the last reading."""
        o = np.asarray(odom, dtype=np.float64)
        if self._odom is not None and self._pose is not None:
            delta = relative(self._odom, o)
            cov_motion = self.config.motion.covariance(self._odom, o, float(self._pose[2]))
            c, s = math.cos(self._pose[2]), math.sin(self._pose[2])
            jac = np.array(
                [
                    [1.0, 0.0, -s * delta[0] - c * delta[1]],
                    [0.0, 1.0, c * delta[0] - s * delta[1]],
                    [0, 0, 1.0],
                ]
            )
            self._cov = jac @ self._cov @ jac.T + cov_motion
            self._pose = compose(self._pose, delta)
        self._odom = o

    def on_detections(self, time: float, detected: ArrayLike) -> TrackState:
        """Correct the pose with one image's detected lights."""
        cfg = self.config
        det = np.asarray(detected, dtype=np.float64).reshape(-1, 2)
        self._images += 1
        tracked = None
        if self._pose is not None and len(det):
            tracked = self._measure(det, self._pose)
        good = (
            tracked is not None
            and tracked[2] >= max(cfg.min_matched, cfg.min_fraction * len(det))
            and tracked[3] <= cfg.max_merit
            and self._pose is not None
            and self._mahalanobis(tracked[0], tracked[1]) <= cfg.gate
        )
        if not good or self._images % cfg.check_every == 0 or self._pose is None:
            glob = self.localizer.locate(det, self._rng) if len(det) else Localization((), 0, 0)
            best = glob.best
            if best is not None and not glob.ambiguous and best.matched >= cfg.min_matched:
                own = tracked[3] if good and tracked is not None else math.inf
                far = (
                    self._pose is None
                    or math.hypot(best.pose[0] - self._pose[0], best.pose[1] - self._pose[1]) > 0.5
                )
                if not good or (far and best.merit < cfg.better_by * own):
                    z, r, _, _ = self._measure(det, np.array(best.pose))
                    self._pose, self._cov = z, r
                    self.state = TrackState(time, _t(self._pose), self._cov.copy(), "global", glob)
                    return self.state
            if not good:
                how = "predicted" if self._pose is not None else "lost"
                self.state = TrackState(
                    time, None if self._pose is None else _t(self._pose), self._cov.copy(), how, glob
                )
                return self.state
        assert tracked is not None
        assert self._pose is not None
        z, r = tracked[0], tracked[1]
        gain = self._cov @ np.linalg.inv(self._cov + r)
        innov = z - self._pose
        innov[2] = float(wrap_angle(innov[2]))
        self._pose = self._pose + gain @ innov
        self._pose[2] = float(wrap_angle(self._pose[2]))
        self._cov = (np.eye(3) - gain) @ self._cov
        self.state = TrackState(time, _t(self._pose), self._cov.copy(), "tracked")
        return self.state

    def _mahalanobis(self, z: FloatArray, r: FloatArray) -> float:
        """The squared Mahalanobis distance of a measurement from the prediction."""
        assert self._pose is not None
        innov = z - self._pose
        innov[2] = float(wrap_angle(innov[2]))
        return float(innov @ np.linalg.solve(self._cov + r, innov))

    def _measure(self, det: FloatArray, start: FloatArray) -> tuple[FloatArray, FloatArray, int, float]:
        """The refined pose from ``start``, its covariance, N_P and M(P)."""
        x, m = self.localizer.polish(det, start)
        cov = self._covariance(det, x)
        return x[:3], cov, int(m.n[0]), float(m.value[0])

    def _covariance(self, det: FloatArray, x: FloatArray) -> FloatArray:
        loc = self.localizer
        cam = loc.camera
        swing = (float(x[3]), float(x[4]))
        proj, seen = cam.project_lights(x[None, :3], loc.lights, swing)
        match, _ = associate(proj, seen, det, loc.config.threshold)
        j = np.flatnonzero(match[0] >= 0)
        if len(j) < 2:
            return np.diag([1.0, 1.0, 0.3])
        i = match[0, j]
        steps = (1e-3, 1e-3, 1e-4)
        cols = []
        for k in range(3):
            xk = x[:3].copy()
            xk[k] += steps[k]
            pk, _ = cam.project_lights(xk[None], loc.lights[i], swing)
            cols.append((pk[0] - proj[0, i]).reshape(-1) / steps[k])
        jac = np.stack(cols, axis=1)
        info = jac.T @ jac / self.config.pixel_std**2
        # the swing, estimated or not, leaves about 1 cm m^-1 of light height unexplained per degree
        return np.asarray(np.linalg.pinv(info) + np.diag([1e-4, 1e-4, 1e-6]))


def _t(p: FloatArray) -> tuple[float, float, float]:
    return float(p[0]), float(p[1]), float(p[2])
