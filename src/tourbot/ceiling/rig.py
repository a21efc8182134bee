"""Where the upward camera sits on the robot: its intrinsics, height, tilt, and image size.

The robot frame is x forward, y left, z up, its origin on the floor under the base's centre. The
untilted upward camera's frame is the robot frame lifted by ``mount_height`` (1.8 m over the ground
in the paper, Sec. I): optical axis +z up, image +u along the robot's heading, +v to its left. The
mounting tilt turns it by ``roll`` about x and ``pitch`` about y; a floor bump (``swing``) tilts the
whole robot, so it turns the camera and moves it too.

Landmark projection (Gamallo et al., Sec. III-B, Eq. 3 and Alg. 1): a light's world coordinates
are brought into the camera frame, ``B^C = R_C (B^W - C^W)``, and projected with the camera model
(Eqs. 1-2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.ceiling.camera import CameraModel, KannalaBrandt, PajdlaBakstein
from tourbot.errors import InputError

__all__ = ["CeilingCamera", "load_camera", "rotation_rp"]

FloatArray = NDArray[np.float64]


def rotation_rp(roll: float, pitch: float, yaw: float = 0.0) -> FloatArray:
    """``Rz(yaw) Rx(roll) Ry(pitch)``: a frame turned by these angles, as columns in its parent."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    return np.asarray(rz @ rx @ ry)


@dataclass(frozen=True)
class CeilingCamera:
    """The upward fisheye camera of the robot: a typed part of the robot's configuration.

    ``rim_theta``: detections farther than this from the robot's vertical are rejected (near the
    horizon: windows, spotlights, visitors' heads); ``width``/``height``: the image size the
    calibration belongs to.
    """

    model: PajdlaBakstein | KannalaBrandt = field(default_factory=PajdlaBakstein)
    width: int = 640
    height: int = 480
    mount_height: float = 1.8
    offset: tuple[float, float] = (0.0, 0.0)
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0
    rim_theta: float = math.radians(75.0)

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0 or self.mount_height <= 0:
            raise ValueError("CeilingCamera needs a positive image size and mount height")
        if not 0 < self.rim_theta <= self.model.max_theta:
            raise ValueError("CeilingCamera needs 0 < rim_theta <= the model's max_theta")

    # -- geometry ---------------------------------------------------------------------------------

    def mount(self, swing: tuple[float, float] = (0.0, 0.0)) -> tuple[FloatArray, FloatArray]:
        """The camera's rotation (columns: camera axes in the robot frame) and position in the robot
        frame, with the base tilted by ``swing`` = (roll, pitch) about its footprint's centre."""
        r_mount = rotation_rp(self.roll, self.pitch, self.yaw)
        t = np.array([self.offset[0], self.offset[1], self.mount_height])
        if swing == (0.0, 0.0):
            return r_mount, t
        r_swing = rotation_rp(swing[0], swing[1])
        return np.asarray(r_swing @ r_mount), np.asarray(r_swing @ t)

    def to_camera(
        self, poses: ArrayLike, points: ArrayLike, swing: tuple[float, float] = (0.0, 0.0)
    ) -> FloatArray:
        """World points ``(M, 3)`` in the camera frame of each robot pose ``(N, 3)``: ``(N, M, 3)``
        (Eq. 3: ``B^C = R_C (B^W - C^W)``)."""
        ps = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        rot, t = self.mount(swing)
        c, s = np.cos(ps[:, 2]), np.sin(ps[:, 2])
        dx = pts[None, :, 0] - ps[:, None, 0]
        dy = pts[None, :, 1] - ps[:, None, 1]
        robot = np.stack([c[:, None] * dx + s[:, None] * dy, -s[:, None] * dx + c[:, None] * dy], axis=-1)
        robot = np.concatenate([robot, np.broadcast_to(pts[None, :, 2:3], (len(ps), len(pts), 1))], axis=-1)
        return np.asarray((robot - t) @ rot)

    def project_lights(
        self, poses: ArrayLike, lights: ArrayLike, swing: tuple[float, float] = (0.0, 0.0)
    ) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Map(P) of Alg. 1 for each pose: pixels ``(N, M, 2)`` and which are seen (inside the rim,
        inside the image)."""
        cam = self.to_camera(poses, lights, swing)
        n, m = cam.shape[:2]
        uv, valid = self.model.project(cam.reshape(-1, 3))
        up = (cam.reshape(-1, 3) @ self.mount()[0].T)[:, 2]
        theta = np.arccos(np.clip(up / np.linalg.norm(cam.reshape(-1, 3), axis=1), -1.0, 1.0))
        seen = valid & (theta <= self.rim_theta) & self.inside(uv)
        return uv.reshape(n, m, 2), seen.reshape(n, m)

    def inside(self, uv: ArrayLike) -> NDArray[np.bool_]:
        p = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        return np.asarray(
            (p[:, 0] >= 0) & (p[:, 0] <= self.width - 1) & (p[:, 1] >= 0) & (p[:, 1] <= self.height - 1)
        )

    def theta_of_pixels(self, uv: ArrayLike) -> FloatArray:
        """Angle (rad) of the pixels' rays from the robot's vertical (the mounting tilt removed)."""
        rays = self.model.unproject(uv) @ self.mount()[0].T
        return np.asarray(np.arccos(np.clip(rays[:, 2], -1.0, 1.0)))

    # -- checks -----------------------------------------------------------------------------------

    def check_image(self, shape: tuple[int, ...], path: str | Path | None = None) -> None:
        """An image that does not fit this calibration is one clear error naming file and field."""
        if len(shape) != 2:
            raise InputError(
                f"expected a grayscale image, got shape {shape}", path=path, field="image.channels"
            )
        h, w = shape
        if (w, h) != (self.width, self.height):
            raise InputError(
                f"image is {w}x{h} pixels, the camera calibration is for {self.width}x{self.height}",
                path=path,
                field="image.size",
            )


def _fits_image(model: CameraModel, width: int, height: int) -> str | None:
    """Why a calibration cannot belong to an image of this size, or None."""
    cu, cv = model.centre()
    if not (0 <= cu < width and 0 <= cv < height):
        return f"image centre ({cu:.1f}, {cv:.1f}) is outside the {width}x{height} image"
    r90 = float(model.radius_of_theta(min(math.pi / 2, model.max_theta)))
    if r90 < 0.1 * min(width, height) or r90 > 4 * max(width, height):
        return f"the horizon's image radius {r90:.0f} px does not fit a {width}x{height} image"
    return None


def load_camera(path: str | Path) -> CeilingCamera:
    """A camera calibration from a YAML file; errors name the file and the field.

    Keys: ``model`` (``pajdla-bakstein``: a, b, c, d, u0, v0, beta; ``kannala-brandt``: fx, fy, cx,
    cy, k1-k4), ``fov_deg``, ``width``, ``height``, ``mount_height``, ``roll_deg``, ``pitch_deg``,
    ``yaw_deg``, ``rim_deg``.
    """
    import yaml

    p = Path(path)
    try:
        data = yaml.safe_load(p.read_text())
    except OSError as exc:
        raise InputError(f"cannot read the camera file: {exc.strerror or exc}", path=p) from exc
    except yaml.YAMLError as exc:
        raise InputError(f"not valid YAML: {exc}", path=p) from exc
    if not isinstance(data, dict):
        raise InputError("a camera file must be a mapping", path=p)
    return camera_from_dict(data, path=p)


def camera_from_dict(data: dict[str, Any], path: str | Path | None = None) -> CeilingCamera:
    known = {
        "model",
        "fov_deg",
        "width",
        "height",
        "mount_height",
        "roll_deg",
        "pitch_deg",
        "yaw_deg",
        "rim_deg",
    }
    for key in data:
        if key not in known and key not in _PB_KEYS + _KB_KEYS:
            raise InputError("unknown key", path=path, field=str(key))
    kind = data.get("model", "pajdla-bakstein")
    try:
        fov = math.radians(float(data.get("fov_deg", 185.0)))
        if kind == "pajdla-bakstein":
            model: PajdlaBakstein | KannalaBrandt = PajdlaBakstein(
                **{k: float(data[k]) for k in _PB_KEYS if k in data}, fov=fov
            )
        elif kind == "kannala-brandt":
            missing = [k for k in ("fx", "fy", "cx", "cy") if k not in data]
            if missing:
                raise InputError("missing", path=path, field=missing[0])
            model = KannalaBrandt(**{k: float(data[k]) for k in _KB_KEYS if k in data}, fov=fov)
        else:
            raise InputError(
                f"unknown model {kind!r} (pajdla-bakstein, kannala-brandt)", path=path, field="model"
            )
        width, height = int(data.get("width", 640)), int(data.get("height", 480))
        why = _fits_image(model, width, height)
        if why is not None:
            raise InputError(why, path=path, field="model")
        return CeilingCamera(
            model=model,
            width=width,
            height=height,
            mount_height=float(data.get("mount_height", 1.8)),
            roll=math.radians(float(data.get("roll_deg", 0.0))),
            pitch=math.radians(float(data.get("pitch_deg", 0.0))),
            yaw=math.radians(float(data.get("yaw_deg", 0.0))),
            rim_theta=math.radians(float(data.get("rim_deg", 75.0))),
        )
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), path=path, field="model") from exc


_PB_KEYS = ("a", "b", "c", "d", "u0", "v0", "beta")
_KB_KEYS = ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")


#: The published calibration of the camera of the real frames (``../shared/data/README.md``):
#: OpenCV fisheye, 640 x 480, tilted about 22 degrees from vertical.
CYCLOID_CAMERA = CeilingCamera(
    model=KannalaBrandt(fx=193.2595, fy=192.6833, cx=347.8275, cy=245.5299, k1=0.0092507),
    width=640,
    height=480,
    pitch=math.radians(22.0),
)
