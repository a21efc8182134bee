"""The simulator's one camera renderer, and the upward infrared camera of Gamallo et al. built on it.

:func:`render` draws a scene of flat patches (world polygons with a brightness: lights, windows,
spotlights, visitors) through any camera model of ``tourbot.ceiling.camera`` (the paper's fisheye,
OpenCV's fisheye, or a pinhole, e.g. a forward camera for obstacle detection) placed anywhere in
the world. Patches are drawn far to near (a visitor in front of a light hides it), their edges
sampled densely so that fisheye images of straight edges curve. An extended light has the same
brightness at any distance (radiance is conserved); it is brighter when it points at the camera.
What passes saturation blooms into its neighbourhood (the paper's Fig. 9(a)). Vignetting darkens the
image towards its rim; sensor noise is added last.

:class:`CeilingCameraSim` renders what the robot's upward camera (behind its infrared pass filter,
Sec. III) sees from a site's 3D ceiling lights at 1 Hz: fixture types with their shapes and sizes
(:data:`FIXTURES`: the Domus hall's A, B and E), camera swing from floor bumps, lights that are off,
spotlights and windows that make spurious blobs, and tall visitors occluding lights near the horizon.
Deterministic for a seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.ceiling.camera import CameraModel
from tourbot.ceiling.rig import CeilingCamera, rotation_rp
from tourbot.errors import TourbotError
from tourbot.site.model import Site

__all__ = [
    "FIXTURES",
    "CameraFrame",
    "CameraSimConfig",
    "CeilingCameraSim",
    "FixtureType",
    "Patch",
    "RenderConfig",
    "SimCamera",
    "camera_in_world",
    "render",
]

FloatArray = NDArray[np.float64]


class CameraSimError(TourbotError):
    """A site the camera cannot be simulated in (no lights, an unknown fixture type)."""


@dataclass(frozen=True)
class Patch:
    """A flat polygon ``points`` ``(K, 3)`` (world, metres) of ``brightness`` (8-bit counts before
    saturation); ``normal`` is the direction it shines to and ``focus`` how directional it is
    (brightness times ``cos(angle)^focus`` towards the camera; 0: the same from everywhere)."""

    points: FloatArray
    brightness: float
    normal: tuple[float, float, float] = (0.0, 0.0, -1.0)
    focus: float = 0.0


@dataclass(frozen=True)
class RenderConfig:
    """Image formation: ``ambient`` (counts of the dark scene), bloom (``bloom_sigma`` pixels,
    ``bloom_gain`` of the light above saturation spread around), ``vignetting`` (fraction of
    brightness lost at the horizon's radius), ``noise_std`` (counts) and ``edge_samples`` per edge."""

    ambient: float = 6.0
    bloom_sigma: float = 4.0
    bloom_gain: float = 1.2
    vignetting: float = 0.35
    noise_std: float = 2.0
    edge_samples: int = 10


def camera_in_world(
    rig: CeilingCamera, pose: ArrayLike, swing: tuple[float, float] = (0.0, 0.0)
) -> tuple[FloatArray, FloatArray]:
    """The camera's rotation (columns: its axes in the world) and position for a robot ``pose``."""
    x, y, th = (float(v) for v in np.asarray(pose, dtype=np.float64))
    rot, t = rig.mount(swing)
    rz = rotation_rp(0.0, 0.0, th)
    return np.asarray(rz @ rot), np.array([x, y, 0.0]) + rz @ t


def render(
    model: CameraModel,
    width: int,
    height: int,
    rotation: FloatArray,
    position: FloatArray,
    patches: list[Patch],
    rng: np.random.Generator,
    config: RenderConfig | None = None,
) -> NDArray[np.uint8]:
    """An 8-bit image of ``patches`` seen by a camera (``model``) at ``position`` whose axes in the
    world are the columns of ``rotation``."""
    import cv2

    cfg = config or RenderConfig()
    canvas = np.full((height, width), cfg.ambient, dtype=np.float32)
    order = sorted(
        range(len(patches)),
        key=lambda k: -float(np.linalg.norm(patches[k].points.mean(axis=0) - position)),
    )
    for k in order:
        patch = patches[k]
        pts = _densify(patch.points, cfg.edge_samples)
        cam = (pts - position) @ rotation
        uv, valid = model.project(cam)
        if not valid.any():
            continue
        bright = patch.brightness
        if patch.focus > 0:
            to_cam = position - patch.points.mean(axis=0)
            cosang = float(np.dot(to_cam, patch.normal) / (np.linalg.norm(to_cam) + 1e-12))
            bright *= max(cosang, 0.0) ** patch.focus
        poly = np.round(uv[valid] * 16).astype(np.int32).reshape(-1, 1, 2)
        cv2.fillPoly(canvas, [poly], color=float(bright), shift=4, lineType=cv2.LINE_AA)
    excess = np.maximum(canvas - 255.0, 0.0)
    if cfg.bloom_gain > 0 and excess.any():
        canvas = canvas + cfg.bloom_gain * cv2.GaussianBlur(excess, (0, 0), cfg.bloom_sigma)
    if cfg.vignetting > 0:
        canvas *= _vignette(model, width, height, cfg.vignetting)  # type: ignore[arg-type]
    if cfg.noise_std > 0:
        canvas += rng.normal(0.0, cfg.noise_std, canvas.shape).astype(np.float32)
    return np.clip(np.round(canvas), 0, 255).astype(np.uint8)


@lru_cache(maxsize=8)
def _vignette(model: CameraModel, width: int, height: int, strength: float) -> NDArray[np.float32]:
    """Brightness factor per pixel: ``1 - strength (r / r_horizon)^2``."""
    cu, cv = model.centre()
    r_h = float(model.radius_of_theta(min(math.pi / 2, model.max_theta)))
    vv, uu = np.mgrid[0:height, 0:width]
    rr = np.hypot(uu - cu, vv - cv) / max(r_h, 1.0)
    return (1.0 - strength * np.clip(rr, 0.0, 1.2) ** 2).astype(np.float32)


def _densify(points: FloatArray, samples: int, step: float = 0.02) -> FloatArray:
    """The outline with ``samples`` points per edge at least, and one every ``step`` metres (a patch
    cut by the edge of the field of view keeps its shape)."""
    nxt = np.roll(points, -1, axis=0)
    out = []
    for a, b in zip(points, nxt, strict=True):
        n = max(samples, math.ceil(float(np.linalg.norm(b - a)) / step))
        s = np.linspace(0.0, 1.0, n, endpoint=False)[:, None]
        out.append(a + s * (b - a))
    return np.concatenate(out)


# -- the upward infrared camera ------------------------------------------------------------------


@dataclass(frozen=True)
class FixtureType:
    """A ceiling fixture: ``shape`` (``disc`` of diameter ``size[0]``, or ``rect`` of ``size``
    metres, long side along x), ``brightness`` (counts) and ``focus`` (see :class:`Patch`)."""

    shape: str
    size: tuple[float, float]
    brightness: float
    focus: float = 0.0


#: The Domus hall's fixtures (the paper's Fig. 3): A and E large hanging lamps high up, B small
#: downlights under the low ceiling of area B that saturate the camera right under them (Fig. 9).
#: ``panel``: the fluorescent panels of a site whose lights have no type (FHW).
FIXTURES: dict[str, FixtureType] = {
    "A": FixtureType("disc", (0.6, 0.6), 420.0, 0.5),
    "E": FixtureType("disc", (0.8, 0.8), 450.0, 0.5),
    "B": FixtureType("disc", (0.15, 0.15), 2500.0, 2.0),
    "panel": FixtureType("rect", (1.2, 0.3), 380.0, 0.5),
}


@dataclass(frozen=True)
class CameraSimConfig:
    """The simulated upward camera: ``rate`` (Hz, 1 in the paper), ``swing_std_deg`` (floor bumps:
    the standard deviation of the base's roll and pitch per frame), ``lights_off`` (fraction of the
    site's lights off, drawn once per seed), ``spotlights`` and ``windows`` (spurious bright patches
    on the walls), ``tall_height`` (visitors' heights are drawn from N(1.72, 0.08) m; those taller
    than the camera occlude lights near the horizon)."""

    rate: float = 1.0
    swing_std_deg: float = 0.0
    lights_off: float = 0.0
    spotlights: int = 0
    windows: int = 0
    occlusion: bool = True
    render: RenderConfig = field(default_factory=RenderConfig)

    def __post_init__(self) -> None:
        if not self.rate > 0 or self.swing_std_deg < 0 or not 0 <= self.lights_off <= 1:
            raise ValueError("CameraSimConfig needs rate > 0, swing_std_deg >= 0, 0 <= lights_off <= 1")


@dataclass(frozen=True)
class CameraFrame:
    """One image with its time; the swing and the lights that were on are truth (metrics only)."""

    time: float
    image: NDArray[np.uint8]
    swing: tuple[float, float]


@runtime_checkable
class SimCamera(Protocol):
    """A simulated camera on the robot, polled by the simulator at each step.

    ``name`` becomes the :class:`~tourbot.records.Image`'s ``camera``; :meth:`due` says whether an
    image is due at a time, :meth:`frame` renders it from the robot's true pose with the visitors.
    """

    name: str

    def due(self, time: float) -> bool: ...

    def frame(self, time: float, pose: ArrayLike, people: ArrayLike | None = None) -> CameraFrame: ...


class CeilingCameraSim:
    """The robot's upward camera over a site, deterministic for a seed."""

    name = "ceiling"

    def __init__(
        self, site: Site, rig: CeilingCamera, config: CameraSimConfig | None = None, *, seed: int = 0
    ) -> None:
        if not site.ceiling_lights:
            raise CameraSimError(f"site {site.name!r} has no ceiling lights (field ceiling_lights)")
        self.site = site
        self.rig = rig
        self.config = cfg = config or CameraSimConfig()
        rng_static, self._rng = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2))
        n = len(site.ceiling_lights)
        off = rng_static.permutation(n)[: round(cfg.lights_off * n)]
        self.on = np.ones(n, dtype=bool)
        self.on[off] = False
        self._lights: list[Patch] = []
        for k, light in enumerate(site.ceiling_lights):
            kind = light.type or "panel"
            if kind not in FIXTURES:
                raise CameraSimError(
                    f"site {site.name!r}: unknown fixture type {kind!r} (field ceiling_lights.{k}.type)"
                )
            if self.on[k]:
                self._lights.append(
                    _fixture_patch(np.asarray(light.position, dtype=np.float64), FIXTURES[kind])
                )
        self._spurious = _spurious(site, cfg, rng_static)
        self._heights = rng_static.normal(1.72, 0.08, 4096)
        self._next = 0.0

    def due(self, time: float) -> bool:
        """Whether an image is due at ``time`` (1 Hz by default)."""
        return time + 1e-9 >= self._next

    def frame(self, time: float, pose: ArrayLike, people: ArrayLike | None = None) -> CameraFrame:
        """The image seen from the robot's true ``pose`` with visitors at ``people`` ``(N, 2)``."""
        cfg = self.config
        self._next = time + 1.0 / cfg.rate
        s = math.radians(cfg.swing_std_deg)
        swing = (float(self._rng.normal(0.0, s)), float(self._rng.normal(0.0, s))) if s > 0 else (0.0, 0.0)
        rot, pos = camera_in_world(self.rig, pose, swing)
        patches = self._lights + self._spurious
        if cfg.occlusion and people is not None:
            patches = patches + _visitors(
                np.asarray(people, dtype=np.float64).reshape(-1, 2), pos, self._heights
            )
        image = render(
            self.rig.model, self.rig.width, self.rig.height, rot, pos, patches, self._rng, cfg.render
        )
        return CameraFrame(time, image, swing)


def _fixture_patch(centre: FloatArray, kind: FixtureType) -> Patch:
    if kind.shape == "disc":
        a = np.linspace(0.0, 2 * math.pi, 16, endpoint=False)
        r = kind.size[0] / 2
        pts = np.column_stack([centre[0] + r * np.cos(a), centre[1] + r * np.sin(a), np.full(16, centre[2])])
    else:
        hx, hy = kind.size[0] / 2, kind.size[1] / 2
        pts = centre + np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0]])
    return Patch(pts, kind.brightness, (0.0, 0.0, -1.0), kind.focus)


def _spurious(site: Site, cfg: CameraSimConfig, rng: np.random.Generator) -> list[Patch]:
    """Spotlights (small bright discs on the walls, 2.5-3.5 m up, shining into the room) and
    windows (bright vertical rectangles 1-3 m up) at random places on the site's outline."""
    if cfg.spotlights == 0 and cfg.windows == 0:
        return []
    grid = site.grid
    occ = np.argwhere(grid.occupied())
    if len(occ) == 0:
        return []
    walls = grid.cell_to_world(occ[rng.permutation(len(occ))[: cfg.spotlights + cfg.windows]])
    centre = grid.cell_to_world(np.argwhere(grid.free())).mean(axis=0)
    out: list[Patch] = []
    for k, (x, y) in enumerate(walls):
        inward = centre - np.array([x, y])
        inward /= np.linalg.norm(inward) + 1e-12
        side = np.array([-inward[1], inward[0]])
        if k < cfg.spotlights:
            z = rng.uniform(2.5, 3.5)
            a = np.linspace(0.0, 2 * math.pi, 12, endpoint=False)
            pts = np.column_stack(
                [x + 0.1 * np.cos(a) * side[0], y + 0.1 * np.cos(a) * side[1], z + 0.1 * np.sin(a)]
            )
            out.append(Patch(pts, 500.0, (float(inward[0]), float(inward[1]), 0.0), 2.0))
        else:
            w = rng.uniform(1.0, 2.5) / 2
            p0, p1 = np.array([x, y]) - w * side, np.array([x, y]) + w * side
            pts = np.array(
                [[p0[0], p0[1], 1.0], [p1[0], p1[1], 1.0], [p1[0], p1[1], 3.0], [p0[0], p0[1], 3.0]]
            )
            out.append(Patch(pts, 280.0))
    return out


def _visitors(people: FloatArray, camera: FloatArray, heights: FloatArray) -> list[Patch]:
    """Each visitor as a dark billboard 0.5 m wide facing the camera, from the floor to its height
    (index-wise heights); only those within 12 m and taller than the camera can hide a light."""
    out: list[Patch] = []
    for k, (x, y) in enumerate(people):
        h = float(heights[k % len(heights)])
        d = np.array([x - camera[0], y - camera[1]])
        dist = float(np.linalg.norm(d))
        if h <= camera[2] or dist > 12.0 or dist < 0.3:
            continue
        side = np.array([-d[1], d[0]]) / dist * 0.25
        pts = np.array(
            [
                [x - side[0], y - side[1], 0.0],
                [x + side[0], y + side[1], 0.0],
                [x + side[0], y + side[1], h],
                [x - side[0], y - side[1], h],
            ]
        )
        out.append(Patch(pts, 0.0))
    return out
