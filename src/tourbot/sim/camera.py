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

:class:`ForwardCameraSim` renders what the robot's forward grey camera sees in the site's 2.5D world
(:class:`Scene`, ray cast per pixel behind the patches): the map's walls as vertical textured
planes, a textured floor and ceiling, the site's obstacles with their height ranges (low benches
under the laser plane, cabinets and fire extinguishers over it, tables on thin legs, glass cases:
see-through panes with a faint pattern of their own over what is behind them, on an opaque base
rail and under an opaque lid if the site gives them), and the visitors as textured bodies; the
exposure varies a little from frame to frame and sensor noise is added (no motion blur).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.ceiling.camera import CameraModel
from tourbot.ceiling.rig import CeilingCamera, rotation_rp
from tourbot.errors import TourbotError
from tourbot.maps.grid import OccupancyGrid
from tourbot.site.model import Site

if TYPE_CHECKING:
    from tourbot.vision.camera import ForwardCamera

__all__ = [
    "FIXTURES",
    "Body",
    "CameraFrame",
    "CameraSimConfig",
    "CeilingCameraSim",
    "FixtureType",
    "ForwardCameraConfig",
    "ForwardCameraSim",
    "Patch",
    "Prism",
    "RenderConfig",
    "Scene",
    "SimCamera",
    "Surface",
    "WorldCamera",
    "camera_in_world",
    "make_texture",
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
    scene: Scene | None = None,
) -> NDArray[np.uint8]:
    """An 8-bit image of ``patches`` seen by a camera (``model``) at ``position`` whose axes in the
    world are the columns of ``rotation``; with a 2.5D ``scene`` (floor, walls, solids, visitors)
    behind the patches, ray cast per pixel with a depth test."""
    import cv2

    cfg = config or RenderConfig()
    if scene is None:
        canvas = np.full((height, width), cfg.ambient, dtype=np.float32)
    else:
        rays = _pixel_rays(model, width, height)  # type: ignore[arg-type]
        canvas = scene.draw((rays @ rotation.T).astype(np.float32), position) + cfg.ambient
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
def _pixel_rays(model: CameraModel, width: int, height: int) -> NDArray[np.float32]:
    """Unit ray directions ``(height, width, 3)`` of the pixel centres, camera frame."""
    vv, uu = np.mgrid[0:height, 0:width]
    d = model.unproject(np.stack([uu.ravel(), vv.ravel()], axis=-1).astype(np.float64))
    return d.reshape(height, width, 3).astype(np.float32)


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


# -- the 2.5D world of the forward camera ---------------------------------------------------------


def make_texture(rng: np.random.Generator, size: int = 512) -> NDArray[np.float32]:
    """A tileable grey texture ``(size, size)`` of zero mean and unit spread: noise at three scales
    (a few texels, tens, a hundred), like stone, wood grain, carpet and posters."""
    from scipy import ndimage

    out = np.zeros((size, size), dtype=np.float32)
    for sigma, weight in ((0.8, 0.8), (2.5, 0.8), (8.0, 0.8), (24.0, 1.0)):
        noise = rng.standard_normal((size, size)).astype(np.float32)
        blurred = ndimage.gaussian_filter(noise, sigma, mode="wrap")
        out += weight * blurred / max(float(blurred.std()), 1e-6)
    return (out - out.mean()) / max(float(out.std()), 1e-6)


@dataclass(frozen=True)
class Surface:
    """How a surface looks: mean ``albedo`` (counts), ``contrast`` (counts of texture spread), the
    texture's ``texel`` (m) and ``shift`` (m, so that two objects do not share one pattern)."""

    albedo: float
    contrast: float
    texel: float = 0.01
    shift: float = 0.0


@dataclass(frozen=True)
class Prism:
    """A vertical convex prism: ``footprint`` ``(K, 2)`` (world, counter-clockwise), from ``z[0]``
    to ``z[1]``; ``alpha`` below 1 is glass (that much of its own look over what lies behind)."""

    footprint: FloatArray
    z: tuple[float, float]
    surface: Surface
    alpha: float = 1.0


@dataclass(frozen=True)
class Body:
    """A visitor: a vertical cylinder at ``centre`` of ``radius`` up to ``height``; ``clothes``
    (trousers, shirt) and skin looks from the bottom up."""

    centre: tuple[float, float]
    radius: float
    height: float
    legs: Surface
    shirt: Surface
    skin: Surface


@dataclass
class Scene:
    """A 2.5D world: textured floor (z = 0) and ceiling (z = ``wall_height``), the map's occupied
    cells as vertical textured walls up to ``wall_height`` (found with the project's ray caster,
    one ray per ``azimuth_step`` of azimuth), solids with height ranges and visitors."""

    texture: NDArray[np.float32]
    floor: Surface = Surface(105.0, 40.0, 0.012)
    wall: Surface = Surface(150.0, 45.0, 0.01, 3.0)
    ceiling: Surface = Surface(185.0, 12.0, 0.04)
    wall_height: float = 2.6
    max_range: float = 25.0
    azimuth_step: float = math.radians(0.1)
    prisms: list[Prism] = field(default_factory=list)
    bodies: list[Body] = field(default_factory=list)
    _caster: object | None = None

    def set_walls(self, grid: OccupancyGrid) -> None:
        """The map whose occupied cells stand as walls (call again after a door moves)."""
        from tourbot.maps.raycast import DDACaster

        self._caster = DDACaster(grid, self.max_range)

    def sample(self, surface: Surface, a: NDArray[np.float32], b: NDArray[np.float32]) -> NDArray[np.float32]:
        """The surface's brightness at texture coordinates ``a``, ``b`` (metres)."""
        n = self.texture.shape[0]
        a = np.where(np.isfinite(a), a, 0.0)
        b = np.where(np.isfinite(b), b, 0.0)
        ia = ((a + surface.shift) / surface.texel).astype(np.int64) % n
        ib = ((b + 0.37 * surface.shift) / surface.texel).astype(np.int64) % n
        return np.asarray(surface.albedo + surface.contrast * self.texture[ib, ia], dtype=np.float32)

    def draw(self, rays: NDArray[np.float32], position: FloatArray) -> NDArray[np.float32]:
        """Brightness ``(H, W)`` seen along world ray directions ``rays`` ``(H, W, 3)`` from
        ``position`` (nearest surface first: a depth test per pixel)."""
        ox, oy, oz = (float(v) for v in position)
        dx, dy, dz = rays[..., 0], rays[..., 1], rays[..., 2]
        inf = np.float32(np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            t_floor = np.where(dz < -1e-6, -oz / dz, inf).astype(np.float32)
            t_ceil = np.where(dz > 1e-6, (self.wall_height - oz) / dz, inf).astype(np.float32)
            depth = np.minimum(t_floor, t_ceil)
            img = np.where(
                t_floor <= t_ceil,
                self.sample(self.floor, ox + t_floor * dx, oy + t_floor * dy),
                self.sample(self.ceiling, ox + t_ceil * dx, oy + t_ceil * dy),
            )
        if self._caster is not None:
            self._draw_walls(rays, position, depth, img)
        for prism in self.prisms:
            if prism.alpha >= 1.0:
                self._draw_prism(prism, rays, position, depth, img)
        for body in self.bodies:
            self._draw_body(body, rays, position, depth, img)
        for prism in self.prisms:
            if prism.alpha < 1.0:
                self._draw_prism(prism, rays, position, depth, img)
        return img

    def _draw_walls(
        self,
        rays: NDArray[np.float32],
        position: FloatArray,
        depth: NDArray[np.float32],
        img: NDArray[np.float32],
    ) -> None:
        from tourbot.maps.raycast import RayCaster

        assert isinstance(self._caster, RayCaster)
        n = round(2 * math.pi / self.azimuth_step)
        angles = -math.pi + self.azimuth_step * np.arange(n)
        ranges = self._caster.cast(np.array([[position[0], position[1], 0.0]]), angles)[0]
        az = np.arctan2(rays[..., 1], rays[..., 0])
        k = np.round((az + math.pi) / self.azimuth_step).astype(np.int64) % n
        r = ranges[k]
        h = np.hypot(rays[..., 0], rays[..., 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where((r < self.max_range) & (h > 1e-6), r / h, np.inf).astype(np.float32)
        z = position[2] + t * rays[..., 2]
        hit = (t < depth) & (z >= 0.0) & (z <= self.wall_height)
        if not hit.any():
            return
        wx = position[0] + t[hit] * rays[..., 0][hit]
        wy = position[1] + t[hit] * rays[..., 1][hit]
        img[hit] = 0.5 * (self.sample(self.wall, wx, z[hit]) + self.sample(self.wall, wy + 7.0, z[hit]))
        depth[hit] = t[hit]

    def _window(
        self, lo: FloatArray, hi: FloatArray, rays: NDArray[np.float32], position: FloatArray
    ) -> tuple[slice, slice] | None:
        """The image rows and columns a box ``lo``-``hi`` can cover: every pixel whose ray passes
        within the box's bounding sphere (cheap, conservative)."""
        centre = 0.5 * (lo + hi)
        radius = 0.5 * float(np.linalg.norm(hi - lo))
        to = centre - position
        dist = float(np.linalg.norm(to))
        if dist <= radius:
            return slice(None), slice(None)
        cosang = (rays @ (to / dist).astype(np.float32)) if rays.size else rays[..., 0]
        near = cosang >= math.cos(math.asin(min(1.0, radius / dist)))
        if not near.any():
            return None
        rows, cols = np.flatnonzero(near.any(axis=1)), np.flatnonzero(near.any(axis=0))
        return slice(int(rows[0]), int(rows[-1]) + 1), slice(int(cols[0]), int(cols[-1]) + 1)

    def _draw_prism(
        self,
        prism: Prism,
        rays: NDArray[np.float32],
        position: FloatArray,
        depth: NDArray[np.float32],
        img: NDArray[np.float32],
    ) -> None:
        """Cyrus-Beck clipping of each ray against the prism's planes (sides, bottom, top)."""
        fp = prism.footprint
        lo = np.array([fp[:, 0].min(), fp[:, 1].min(), prism.z[0]])
        hi = np.array([fp[:, 0].max(), fp[:, 1].max(), prism.z[1]])
        win = self._window(lo, hi, rays, position)
        if win is None:
            return
        d = rays[win]
        nxt = np.roll(fp, -1, axis=0)
        edge = nxt - fp
        normals = np.stack([edge[:, 1], -edge[:, 0], np.zeros(len(fp))], axis=1)  # outward for CCW
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        offsets = np.einsum("ij,ij->i", normals[:, :2], fp)
        normals = np.vstack([normals, [[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]]])
        offsets = np.r_[offsets, -prism.z[0], prism.z[1]]
        t_in = np.zeros(d.shape[:2], dtype=np.float32)
        t_out = np.full(d.shape[:2], np.inf, dtype=np.float32)
        face = np.full(d.shape[:2], -1, dtype=np.int64)
        inside = np.ones(d.shape[:2], dtype=bool)
        for k, (nrm, off) in enumerate(zip(normals, offsets, strict=True)):
            num = np.float32(off - float(nrm @ position))
            den = d @ nrm.astype(np.float32)
            with np.errstate(divide="ignore", invalid="ignore"):
                tk = num / den
            entering = den < -1e-9
            exiting = den > 1e-9
            better = entering & (tk > t_in)
            t_in = np.where(better, tk, t_in)
            face = np.where(better, k, face)
            t_out = np.where(exiting & (tk < t_out), tk, t_out)
            inside &= ~((np.abs(den) <= 1e-9) & (num < 0))
        sub_depth = depth[win]
        hit = inside & (face >= 0) & (t_in <= t_out) & (t_in > 0) & (t_in < sub_depth)
        if not hit.any():
            return
        t = t_in[hit]
        p = position[None, :] + t[:, None] * d[hit]
        f = face[hit]
        side = f < len(fp)
        # texture: sides by (x + y, z), top and bottom by (x, y); sides lit from one direction
        a = np.where(side, p[:, 0] + p[:, 1], p[:, 0]).astype(np.float32)
        b = np.where(side, p[:, 2], p[:, 1]).astype(np.float32)
        light = np.array([0.6, 0.8, 0.0])
        shade = np.where(side, 0.8 + 0.2 * (normals[np.minimum(f, len(normals) - 1)] @ light), 1.0)
        shade = np.where(f == len(fp), 0.6, shade)
        look = (self.sample(prism.surface, a, b) * shade).astype(np.float32)
        sub_img = img[win]
        if prism.alpha < 1.0:
            sub_img[hit] = prism.alpha * look + (1.0 - prism.alpha) * sub_img[hit]
        else:
            sub_img[hit] = look
            sub_depth[hit] = t

    def _draw_body(
        self,
        body: Body,
        rays: NDArray[np.float32],
        position: FloatArray,
        depth: NDArray[np.float32],
        img: NDArray[np.float32],
    ) -> None:
        cx, cy = body.centre
        lo = np.array([cx - body.radius, cy - body.radius, 0.0])
        hi = np.array([cx + body.radius, cy + body.radius, body.height])
        win = self._window(lo, hi, rays, position)
        if win is None:
            return
        d = rays[win]
        ox, oy = position[0] - cx, position[1] - cy
        a = d[..., 0] ** 2 + d[..., 1] ** 2
        b = 2.0 * (d[..., 0] * ox + d[..., 1] * oy)
        c = ox * ox + oy * oy - body.radius**2
        disc = b * b - 4.0 * a * c
        ok = (disc >= 0) & (a > 1e-9)
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.where(ok, (-b - np.sqrt(np.maximum(disc, 0.0))) / (2.0 * a), np.inf).astype(np.float32)
        z = position[2] + t * d[..., 2]
        sub_depth = depth[win]
        hit = ok & (t > 0) & (t < sub_depth) & (z >= 0.0) & (z <= body.height)
        if not hit.any():
            return
        th, zh = t[hit], z[hit]
        px = ox + th * d[..., 0][hit]
        py = oy + th * d[..., 1][hit]
        around = (np.arctan2(py, px) * body.radius).astype(np.float32)
        look = np.where(
            zh < 0.85,
            self.sample(body.legs, around, zh),
            np.where(
                zh < body.height - 0.25,
                self.sample(body.shirt, around, zh),
                self.sample(body.skin, around, zh),
            ),
        )
        img[win][hit] = look
        sub_depth[hit] = th


@runtime_checkable
class WorldCamera(Protocol):
    """A simulated camera that draws the world grid (walls, doors, furniture at their states):
    the simulator hands it the grid at the start and whenever doors or furniture change."""

    def set_world(self, grid: OccupancyGrid) -> None: ...


@dataclass(frozen=True)
class ForwardCameraConfig:
    """The simulated forward camera: ``rate`` (Hz), ``exposure_std`` (relative spread of the
    automatic exposure's gain from frame to frame), image formation (:class:`RenderConfig`)."""

    rate: float = 5.0
    exposure_std: float = 0.03
    render: RenderConfig = field(
        default_factory=lambda: RenderConfig(ambient=0.0, bloom_gain=0.0, vignetting=0.15, noise_std=2.0)
    )

    def __post_init__(self) -> None:
        if not self.rate > 0 or self.exposure_std < 0:
            raise ValueError("ForwardCameraConfig needs rate > 0 and exposure_std >= 0")


class ForwardCameraSim:
    """The robot's forward grey camera in the site's 2.5D world, deterministic for a seed.

    Walls are the world grid's occupied cells (:class:`WorldCamera`), the site's invisible
    obstacles are solids with their height ranges (``box``, ``glass``, ``table`` on legs), the
    visitors textured bodies of drawn heights and clothes.
    """

    name = "forward"

    def __init__(
        self,
        site: Site,
        camera: ForwardCamera | None = None,
        config: ForwardCameraConfig | None = None,
        *,
        seed: int = 0,
    ) -> None:
        from tourbot.vision.camera import ForwardCamera

        self.site = site
        self.camera = camera or ForwardCamera()
        self.config = config or ForwardCameraConfig()
        rng_static, self._rng = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2))
        self.scene = Scene(make_texture(rng_static))
        self.scene.prisms = _obstacle_prisms(site, rng_static)
        self.scene.set_walls(site.grid)
        n = 4096
        self._heights = rng_static.normal(1.72, 0.08, n)
        self._clothes = rng_static.uniform(40.0, 200.0, (n, 3))
        self._next = 0.0

    def set_world(self, grid: OccupancyGrid) -> None:
        self.scene.set_walls(grid)

    def due(self, time: float) -> bool:
        return time + 1e-9 >= self._next

    def frame(self, time: float, pose: ArrayLike, people: ArrayLike | None = None) -> CameraFrame:
        """The image seen from the robot's true ``pose`` with visitors at ``people`` ``(N, 2)``."""
        cfg = self.config
        self._next = time + 1.0 / cfg.rate
        cam = self.camera
        rot, pos = cam.in_world(pose)
        pts = np.zeros((0, 2)) if people is None else np.asarray(people, dtype=np.float64).reshape(-1, 2)
        bodies = []
        for k, (x, y) in enumerate(pts):
            if math.hypot(x - pos[0], y - pos[1]) > 12.0:
                continue
            c = self._clothes[k % len(self._clothes)]
            bodies.append(
                Body(
                    (float(x), float(y)),
                    0.22,
                    float(self._heights[k % len(self._heights)]),
                    Surface(float(c[0]), 25.0, 0.02, k * 1.3),
                    Surface(float(c[1]), 35.0, 0.015, k * 2.1),
                    Surface(150.0, 10.0, 0.02, k * 0.7),
                )
            )
        self.scene.bodies = bodies
        canvas_rng = self._rng
        gain = float(canvas_rng.normal(1.0, cfg.exposure_std)) if cfg.exposure_std > 0 else 1.0
        render_cfg = cfg.render
        image = render(cam.model, cam.width, cam.height, rot, pos, [], canvas_rng, render_cfg, self.scene)
        if gain != 1.0:
            image = np.clip(np.round(image.astype(np.float32) * gain), 0, 255).astype(np.uint8)
        return CameraFrame(time, image, (0.0, 0.0))


def _obstacle_prisms(site: Site, rng: np.random.Generator) -> list[Prism]:
    """The site's invisible obstacles as solids: a box, a glass case (its panes, and its base rail
    and lid if it has them), a table (top and four legs)."""
    from tourbot.site.model import TABLE_LEG_RADIUS, TABLE_TOP

    out: list[Prism] = []
    for k, obs in enumerate(site.invisible_obstacles):
        fp = _ccw(np.asarray(obs.outline, dtype=np.float64))
        lo, hi = obs.height
        look = Surface(float(rng.uniform(60.0, 200.0)), float(rng.uniform(30.0, 50.0)), 0.008, 11.0 * (k + 1))
        if obs.kind == "glass":
            # the panes between the opaque base rail and lid (dark lacquered metal, finely grained)
            out.append(
                Prism(
                    fp, (lo + obs.base, hi - obs.lid), Surface(210.0, 40.0, 0.01, 5.0 * (k + 1)), alpha=0.35
                )
            )
            for n, part in enumerate(obs.solid_parts()):
                out.append(Prism(fp, part, Surface(70.0, 35.0, 0.008, 3.0 * (k + 1) + n)))
        elif obs.kind == "table":
            out.append(Prism(fp, (max(lo, hi - TABLE_TOP), hi), look))
            r = TABLE_LEG_RADIUS
            for cx, cy in obs.leg_centres():
                leg = np.array([[cx - r, cy - r], [cx + r, cy - r], [cx + r, cy + r], [cx - r, cy + r]])
                out.append(Prism(leg, (lo, hi - TABLE_TOP), Surface(50.0, 15.0, 0.01)))
        else:
            out.append(Prism(fp, (lo, hi), look))
    return out


def _ccw(points: FloatArray) -> FloatArray:
    x, y = points[:, 0], points[:, 1]
    area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    return points if area >= 0 else points[::-1].copy()
