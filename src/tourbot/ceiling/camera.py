"""Camera projection models: a point in the camera frame to a pixel, and a pixel back to a ray.

Camera frame: the optical axis is +z; +x is the image's +u direction and +y its +v direction
(OpenCV's convention). Three models share one interface (:class:`CameraModel`), so that the one
renderer of ``tourbot.sim.camera`` and the light detector take any of them:

- :class:`PajdlaBakstein`: the paper's fisheye model (Gamallo et al., Sec. III-A, Eqs. 1-2, after
  Bakstein and Pajdla 2002): the image radius against the angle from the optical axis,
  ``r = a tan(theta / b) + c sin(theta / d)``, with the image centre ``(u0, v0)`` and the pixel
  aspect ``beta``.
- :class:`KannalaBrandt`: OpenCV's fisheye model (``cv2.fisheye``),
  ``theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)``.
- :class:`Pinhole`: a flat-retina camera (the forward camera of obstacle detection).

:func:`fit_pajdla_bakstein` fits the paper's model to a Kannala-Brandt calibration (the published
calibrations are OpenCV's), so the two can be compared pixel for pixel.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "CameraModel",
    "KannalaBrandt",
    "PajdlaBakstein",
    "Pinhole",
    "fit_pajdla_bakstein",
]

FloatArray = NDArray[np.float64]

RADIAL_PAJDLA_BAKSTEIN = 0
RADIAL_KANNALA_BRANDT = 1


class CameraModel(Protocol):
    """What the renderer, the detector and the localizer need of a camera's intrinsics."""

    @property
    def max_theta(self) -> float:
        """The largest angle from the optical axis (rad) the model images."""
        ...

    def project(self, points: ArrayLike) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Pixels ``(N, 2)`` of camera-frame points ``(N, 3)`` and which of them are imaged."""
        ...

    def unproject(self, pixels: ArrayLike) -> FloatArray:
        """Unit rays ``(N, 3)`` in the camera frame of pixels ``(N, 2)``."""
        ...

    def radius_of_theta(self, theta: ArrayLike) -> FloatArray:
        """Image radius (pixels, along u) at angle ``theta`` from the optical axis."""
        ...

    def centre(self) -> tuple[float, float]:
        """The image centre (principal point) in pixels."""
        ...


def _angles(points: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Elevation ``theta`` from the optical axis, azimuth ``phi`` (Fig. 6) and the points array."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    rho = np.hypot(p[:, 0], p[:, 1])
    theta = np.arctan2(rho, p[:, 2])
    phi = np.arctan2(p[:, 1], p[:, 0])
    return theta, phi, p


def _rays(theta: FloatArray, phi: FloatArray) -> FloatArray:
    s = np.sin(theta)
    return np.stack([s * np.cos(phi), s * np.sin(phi), np.cos(theta)], axis=-1)


def _invert_monotonic(f_theta: FloatArray, thetas: FloatArray, values: FloatArray) -> FloatArray:
    """theta with f(theta) = value, for a monotonic tabulated f (linear interpolation)."""
    return np.interp(values, f_theta, thetas)


@dataclass(frozen=True)
class PajdlaBakstein:
    """The paper's model, Eqs. 1-2: ``r = a tan(theta/b) + c sin(theta/d)``.

    ``u = u0 + r cos(phi)``, ``v = v0 + beta r sin(phi)``. The paper writes the second line as
    ``beta (v0 + r sin(phi))``; with ``beta`` the pixel aspect ratio that scales only the radial
    term, ``v0`` stays the image centre's row, which is what a calibration reports.
    """

    a: float = 150.0
    b: float = 2.0
    c: float = 40.0
    d: float = 2.0
    u0: float = 320.0
    v0: float = 240.0
    beta: float = 1.0
    fov: float = math.radians(185.0)

    def __post_init__(self) -> None:
        if self.b <= 0 or self.d <= 0 or self.beta <= 0:
            raise ValueError("PajdlaBakstein needs b > 0, d > 0 and beta > 0")
        if not 0 < self.fov < 2 * math.pi:
            raise ValueError("PajdlaBakstein needs 0 < fov < 2 pi")
        t = np.linspace(0.0, self.max_theta, 512)
        if np.any(np.diff(self.radius_of_theta(t)) <= 0) or self.max_theta / self.b >= math.pi / 2:
            raise ValueError("PajdlaBakstein: r(theta) must increase over the field of view")

    @property
    def max_theta(self) -> float:
        return self.fov / 2

    def centre(self) -> tuple[float, float]:
        return self.u0, self.v0

    def radial(self) -> tuple[int, FloatArray, float]:
        """For compiled kernels: the radial law's code (0: Eq. 1), its parameters and the v/u
        pixel aspect."""
        return RADIAL_PAJDLA_BAKSTEIN, np.array([self.a, self.b, self.c, self.d, 0.0]), self.beta

    def radius_of_theta(self, theta: ArrayLike) -> FloatArray:
        """Eq. 1."""
        t = np.asarray(theta, dtype=np.float64)
        return np.asarray(self.a * np.tan(t / self.b) + self.c * np.sin(t / self.d))

    def project(self, points: ArrayLike) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Eqs. 1-2 for camera-frame points (Sec. III-B, Eq. 4)."""
        theta, phi, _ = _angles(points)
        valid = theta <= self.max_theta
        r = self.radius_of_theta(np.minimum(theta, self.max_theta))
        uv = np.stack([self.u0 + r * np.cos(phi), self.v0 + self.beta * r * np.sin(phi)], axis=-1)
        return uv, valid

    def unproject(self, pixels: ArrayLike) -> FloatArray:
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        du = px[:, 0] - self.u0
        dv = (px[:, 1] - self.v0) / self.beta
        r = np.hypot(du, dv)
        thetas = np.linspace(0.0, self.max_theta, 2048)
        theta = _invert_monotonic(self.radius_of_theta(thetas), thetas, r)
        theta = _newton(self.radius_of_theta, theta, r, self.max_theta)
        return _rays(theta, np.arctan2(dv, du))


@dataclass(frozen=True)
class KannalaBrandt:
    """OpenCV's fisheye model (``cv2.fisheye``), without skew."""

    fx: float
    fy: float
    cx: float
    cy: float
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    k4: float = 0.0
    fov: float = math.radians(185.0)

    def __post_init__(self) -> None:
        if self.fx <= 0 or self.fy <= 0:
            raise ValueError("KannalaBrandt needs fx > 0 and fy > 0")
        t = np.linspace(0.0, self.max_theta, 512)
        if np.any(np.diff(self._theta_d(t)) <= 0):
            raise ValueError("KannalaBrandt: theta_d(theta) must increase over the field of view")

    @property
    def max_theta(self) -> float:
        return self.fov / 2

    def centre(self) -> tuple[float, float]:
        return self.cx, self.cy

    def radial(self) -> tuple[int, FloatArray, float]:
        """For compiled kernels: the radial law's code (1: Kannala-Brandt), its parameters
        ``(fx, k1..k4)`` and the v/u pixel aspect ``fy / fx``."""
        return (
            RADIAL_KANNALA_BRANDT,
            np.array([self.fx, self.k1, self.k2, self.k3, self.k4]),
            self.fy / self.fx,
        )

    def _theta_d(self, theta: ArrayLike) -> FloatArray:
        t = np.asarray(theta, dtype=np.float64)
        t2 = t * t
        return np.asarray(t * (1 + t2 * (self.k1 + t2 * (self.k2 + t2 * (self.k3 + t2 * self.k4)))))

    def radius_of_theta(self, theta: ArrayLike) -> FloatArray:
        return self.fx * self._theta_d(theta)

    def project(self, points: ArrayLike) -> tuple[FloatArray, NDArray[np.bool_]]:
        theta, phi, _ = _angles(points)
        valid = theta <= self.max_theta
        td = self._theta_d(np.minimum(theta, self.max_theta))
        uv = np.stack([self.cx + self.fx * td * np.cos(phi), self.cy + self.fy * td * np.sin(phi)], axis=-1)
        return uv, valid

    def unproject(self, pixels: ArrayLike) -> FloatArray:
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        x = (px[:, 0] - self.cx) / self.fx
        y = (px[:, 1] - self.cy) / self.fy
        td = np.hypot(x, y)
        thetas = np.linspace(0.0, self.max_theta, 2048)
        theta = _invert_monotonic(self._theta_d(thetas), thetas, td)
        theta = _newton(self._theta_d, theta, td, self.max_theta)
        return _rays(theta, np.arctan2(y, x))

    def opencv(self) -> tuple[FloatArray, FloatArray]:
        """The camera matrix ``K`` and the distortion ``D`` in ``cv2.fisheye``'s layout."""
        k = np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])
        return k, np.array([[self.k1], [self.k2], [self.k3], [self.k4]])


@dataclass(frozen=True)
class Pinhole:
    """A flat-retina camera: ``u = cx + fx x/z``, ``v = cy + fy y/z``; images points in front only."""

    fx: float
    fy: float
    cx: float
    cy: float
    fov: float = math.radians(120.0)

    def __post_init__(self) -> None:
        if self.fx <= 0 or self.fy <= 0 or not 0 < self.fov < math.pi:
            raise ValueError("Pinhole needs fx > 0, fy > 0 and 0 < fov < pi")

    @property
    def max_theta(self) -> float:
        return self.fov / 2

    def centre(self) -> tuple[float, float]:
        return self.cx, self.cy

    def radius_of_theta(self, theta: ArrayLike) -> FloatArray:
        return np.asarray(self.fx * np.tan(np.asarray(theta, dtype=np.float64)))

    def project(self, points: ArrayLike) -> tuple[FloatArray, NDArray[np.bool_]]:
        theta, _, p = _angles(points)
        valid = theta <= self.max_theta
        z = np.where(p[:, 2] > 1e-9, p[:, 2], 1e-9)
        uv = np.stack([self.cx + self.fx * p[:, 0] / z, self.cy + self.fy * p[:, 1] / z], axis=-1)
        return uv, valid

    def unproject(self, pixels: ArrayLike) -> FloatArray:
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        d = np.stack(
            [(px[:, 0] - self.cx) / self.fx, (px[:, 1] - self.cy) / self.fy, np.ones(len(px))], axis=-1
        )
        return np.asarray(d / np.linalg.norm(d, axis=1, keepdims=True))


def _newton(
    f: Callable[[FloatArray], FloatArray], theta: FloatArray, target: FloatArray, max_theta: float
) -> FloatArray:
    """Two Newton steps on ``f(theta) = target`` from the tabulated guess (numeric derivative)."""
    h = 1e-6
    t = theta.copy()
    for _ in range(2):
        val = f(t)
        der = (f(t + h) - f(t - h)) / (2 * h)
        t = np.clip(t - (val - target) / np.where(np.abs(der) > 1e-12, der, 1e-12), 0.0, max_theta)
    return t


def fit_pajdla_bakstein(kb: KannalaBrandt, samples: int = 200) -> PajdlaBakstein:
    """The paper's model fitted to a Kannala-Brandt calibration (least squares on r(theta)).

    Same centre and field of view; ``beta = fy / fx``; ``a, b, c, d`` minimize the radial difference
    over ``theta`` in ``[0, max_theta]``.
    """
    from scipy.optimize import least_squares

    theta = np.linspace(0.0, kb.max_theta, samples)
    r = kb.radius_of_theta(theta)
    b_min = kb.max_theta / (math.pi / 2) * 1.02

    def residual(x: FloatArray) -> FloatArray:
        a, b, c, d = x
        return np.asarray(a * np.tan(theta / b) + c * np.sin(theta / d) - r)

    x0 = np.array([kb.fx, max(3.0, b_min * 1.5), 0.0, 1.0])
    fit = least_squares(residual, x0, bounds=([-np.inf, b_min, -np.inf, 0.2], [np.inf, 50.0, np.inf, 50.0]))
    a, b, c, d = (float(v) for v in fit.x)
    return PajdlaBakstein(a=a, b=b, c=c, d=d, u0=kb.cx, v0=kb.cy, beta=kb.fy / kb.fx, fov=kb.fov)
