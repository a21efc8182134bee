"""Where the forward camera sits on the robot: a grey pinhole camera looking ahead and down.

The robot frame is x forward, y left, z up, its origin on the floor under the base's centre. The
camera frame is OpenCV's: optical axis +z, image +u to the right (+x), +v down (+y). The camera
stands ``offset`` ahead of the centre at ``mount_height`` and looks ``tilt`` below the horizon, as
the obstacle camera of the TOURBOT robots (Burgard et al., Sec. 3: a camera over the laser that
sees the floor in front of the robot, tables, cabinets and fire extinguishers).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.ceiling.camera import Pinhole

__all__ = ["ForwardCamera"]

FloatArray = NDArray[np.float64]


def _default_model() -> Pinhole:
    return Pinhole(fx=480.0, fy=480.0, cx=319.5, cy=239.5, fov=math.radians(120.0))


@dataclass(frozen=True)
class ForwardCamera:
    """The forward camera: intrinsics (``model``, for ``width`` x ``height`` images) and mount."""

    model: Pinhole = field(default_factory=_default_model)
    width: int = 640
    height: int = 480
    mount_height: float = 1.2
    offset: float = 0.15
    tilt: float = math.radians(25.0)

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0 or not self.mount_height > 0:
            raise ValueError("ForwardCamera needs a positive image size and mount height")
        if not 0 <= self.tilt < math.pi / 2:
            raise ValueError("ForwardCamera needs 0 <= tilt < pi/2")

    def scaled(self, factor: float) -> ForwardCamera:
        """The same camera with images ``factor`` times as wide and high (e.g. 0.5: 320 x 240)."""
        m = self.model
        f = float(factor)
        model = Pinhole(m.fx * f, m.fy * f, (m.cx + 0.5) * f - 0.5, (m.cy + 0.5) * f - 0.5, m.fov)
        return ForwardCamera(
            model, round(self.width * f), round(self.height * f), self.mount_height, self.offset, self.tilt
        )

    @cached_property
    def mount_rotation(self) -> FloatArray:
        """Columns: the camera's axes in the robot frame (right, down, optical axis)."""
        c, s = math.cos(self.tilt), math.sin(self.tilt)
        forward, left, up = np.eye(3)
        z = c * forward - s * up
        y = -c * up - s * forward
        x = -left
        return np.stack([x, y, z], axis=1)

    def in_world(self, pose: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """The camera's rotation (columns: its axes in the world) and position for a robot ``pose``."""
        x, y, th = (float(v) for v in np.asarray(pose, dtype=np.float64))
        c, s = math.cos(th), math.sin(th)
        rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        pos = np.array([x + c * self.offset, y + s * self.offset, self.mount_height])
        return np.asarray(rz @ self.mount_rotation), pos

    @cached_property
    def rays(self) -> FloatArray:
        """Unit ray directions ``(height, width, 3)`` of the pixel centres, camera frame."""
        vv, uu = np.mgrid[0 : self.height, 0 : self.width]
        d = self.model.unproject(np.stack([uu.ravel(), vv.ravel()], axis=-1).astype(np.float64))
        return d.reshape(self.height, self.width, 3)

    def project(self, rotation: FloatArray, position: FloatArray, points: FloatArray) -> FloatArray:
        """Pixel coordinates ``(..., 2)`` of world ``points`` ``(..., 3)``; NaN behind the camera."""
        cam = (points - position) @ rotation
        z = cam[..., 2]
        ok = z > 1e-3
        zs = np.where(ok, z, 1.0)
        m = self.model
        u = np.where(ok, m.cx + m.fx * cam[..., 0] / zs, np.nan)
        v = np.where(ok, m.cy + m.fy * cam[..., 1] / zs, np.nan)
        return np.stack([u, v], axis=-1)
