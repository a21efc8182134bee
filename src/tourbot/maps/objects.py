"""The dynamic objects of the object-based world model, and their sensor simulation.

Schulz and Burgard (2001), Sec. 3: the robot's world model is a boundary representation of the
building in which some objects (doors, movable furniture) have a *state*. Here each such object
is an :class:`ObjectShape`: an outline polygon in its own frame and a map from its state to the
pose of that frame in the world,

- a door: the state is the opening angle ``a`` of its leaf (rad, 0 closed); the leaf's frame sits
  at the hinge, pointing along ``closed_direction + a``; its outline is the leaf's rectangle;
- a piece of furniture (a desk, a bench, the paper's U-shaped object): the state is its pose
  ``(x, y, theta)``; the outline is its footprint.

The sensor simulation (the paper's ray tracing, ``\\hat d_i(s, l)`` of Eq. 10) is the nearest of the
static map's cast (:mod:`tourbot.maps.raycast`, the one caster) and the exact intersection of the
beam with the outlines' edges: :func:`segment_ranges` (numba) batched over robot pose samples x
object state samples x beams, with the plain numpy reference :func:`segment_ranges_reference`.

Two savings of the paper's Sec. 3 are here too: :func:`beam_window`, the consecutive beams that
hit the object's bounding box in at least one sample state (the others only give a constant factor
of Eq. 10), and :class:`ObjectIndex`, a spatial tiling of the objects' reachable boxes so that only
objects near the robot are looked at (Samet's spatial tiling, the paper's [23]).

The simulator draws its doors and furniture with the same shapes and the same kernel
(:mod:`tourbot.sim.objects`), so what the robot expects is what the simulated laser sees.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.geometry import wrap_angle
from tourbot.maps.grid import MapError


class Door(Protocol):
    """What a door's shape needs of the site's door (:class:`tourbot.site.model.Door`)."""

    @property
    def name(self) -> str: ...
    @property
    def hinge(self) -> tuple[float, float]: ...
    @property
    def leaf_length(self) -> float: ...
    @property
    def thickness(self) -> float: ...
    @property
    def closed_direction(self) -> float: ...
    @property
    def opening_angle(self) -> float: ...


class Furniture(Protocol):
    """What a piece of furniture's shape needs of the site's (:class:`tourbot.site.model.Furniture`)."""

    @property
    def name(self) -> str: ...
    @property
    def outline(self) -> Sequence[tuple[float, float]]: ...
    @property
    def poses(self) -> Sequence[tuple[float, float, float]]: ...


__all__ = [
    "ObjectIndex",
    "ObjectShape",
    "beam_window",
    "distance_to_segments",
    "door_shape",
    "furniture_shape",
    "nearest_edge",
    "segment_ranges",
    "segment_ranges_reference",
    "segments_of",
    "shapes_of_site",
]

FloatArray = NDArray[np.float64]
Float32Array = NDArray[np.float32]


@dataclass(frozen=True)
class ObjectShape:
    """One dynamic object: ``outline`` ``(E, 2)`` in its frame and how its state places the frame.

    ``kind`` is ``"door"`` (state ``(a,)``: frame at ``hinge`` with heading
    ``closed_direction + a``, ``a`` between ``low`` and ``high``) or ``"furniture"`` (state
    ``(x, y, theta)``: the frame's pose). ``reach`` is the world box ``(xmin, ymin, xmax, ymax)``
    the outline can occupy over the whole state range (what the spatial index files it under).
    ``symmetry``: the outline is unchanged by turns of ``2 pi / symmetry`` about its frame's
    origin (a rectangle centred on it: 2), so headings are only defined modulo that.
    """

    name: str
    kind: str
    outline: FloatArray
    hinge: tuple[float, float] = (0.0, 0.0)
    closed_direction: float = 0.0
    low: float = 0.0
    high: float = 0.0
    nominal: tuple[float, ...] = ()
    reach: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    symmetry: int = 1

    @property
    def dim(self) -> int:
        return 1 if self.kind == "door" else 3

    @property
    def radius(self) -> float:
        """Distance from the frame's origin to the farthest outline vertex."""
        return float(np.hypot(self.outline[:, 0], self.outline[:, 1]).max())

    def frames(self, states: ArrayLike) -> FloatArray:
        """World poses ``(S, 3)`` of the object's frame in ``states`` ``(S, dim)``."""
        s = np.asarray(states, dtype=np.float64).reshape(-1, self.dim)
        if self.kind == "door":
            out = np.empty((s.shape[0], 3))
            out[:, 0], out[:, 1] = self.hinge
            out[:, 2] = wrap_angle(self.closed_direction + s[:, 0])
            return out
        return s.copy()

    def polygons(self, states: ArrayLike) -> FloatArray:
        """World outlines ``(S, E, 2)`` in ``states`` ``(S, dim)``."""
        f = self.frames(states)
        c, sn = np.cos(f[:, 2])[:, None], np.sin(f[:, 2])[:, None]
        ox, oy = self.outline[None, :, 0], self.outline[None, :, 1]
        return np.stack([f[:, 0:1] + c * ox - sn * oy, f[:, 1:2] + sn * ox + c * oy], axis=-1)

    def segments(self, states: ArrayLike) -> FloatArray:
        """The outlines' edges ``(S, E, 4)`` as ``(x0, y0, x1, y1)``."""
        return segments_of(self.polygons(states))

    def error(self, estimate: Sequence[float], truth: Sequence[float]) -> tuple[float, float]:
        """Position (m; 0 for a door) and angle (rad) error of an estimate against the truth, the
        heading taken modulo the outline's symmetry."""
        if self.kind == "door":
            return 0.0, abs(float(estimate[0]) - float(truth[0]))
        period = 2 * math.pi / self.symmetry
        d = math.hypot(estimate[0] - truth[0], estimate[1] - truth[1])
        return d, abs(math.remainder(estimate[2] - truth[2], period))

    def boxes(self, states: ArrayLike) -> FloatArray:
        """Bounding boxes ``(S, 4)`` ``(xmin, ymin, xmax, ymax)`` of the outlines in ``states``."""
        poly = self.polygons(states)
        return np.concatenate([poly.min(axis=1), poly.max(axis=1)], axis=-1)


def distance_to_segments(x: float, y: float, segs: FloatArray) -> float:
    """Distance from the point ``(x, y)`` to the nearest of the edges ``segs`` ``(..., 4)`` (inf if none)."""
    s = np.asarray(segs, dtype=np.float64).reshape(-1, 4)
    if not len(s):
        return math.inf
    ex, ey = s[:, 2] - s[:, 0], s[:, 3] - s[:, 1]
    length2 = np.maximum(ex * ex + ey * ey, 1e-18)
    u = np.clip(((x - s[:, 0]) * ex + (y - s[:, 1]) * ey) / length2, 0.0, 1.0)
    return float(np.hypot(s[:, 0] + u * ex - x, s[:, 1] + u * ey - y).min())


def segments_of(polygons: FloatArray) -> FloatArray:
    """Closed polygons ``(S, E, 2)`` -> their edges ``(S, E, 4)``."""
    nxt = np.roll(polygons, -1, axis=1)
    return np.ascontiguousarray(np.concatenate([polygons, nxt], axis=-1))


def _symmetry(outline: FloatArray) -> int:
    """Largest ``k`` in 1..4 such that a turn by ``2 pi / k`` maps the outline's vertices onto themselves."""
    for k in (4, 2):
        a = 2 * math.pi / k
        c, s = math.cos(a), math.sin(a)
        turned = outline @ np.array([[c, s], [-s, c]])
        d = np.hypot(turned[:, None, 0] - outline[None, :, 0], turned[:, None, 1] - outline[None, :, 1])
        if d.min(axis=1).max() < 1e-6:
            return k
    return 1


def _validate_outline(name: str, outline: FloatArray) -> None:
    """A simple polygon of positive area, else :class:`MapError` naming the object."""
    n = outline.shape[0]
    if n < 3 or not np.isfinite(outline).all():
        raise MapError(f"object {name!r}: an outline needs at least 3 finite vertices")
    x, y = outline[:, 0], outline[:, 1]
    area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    if abs(area) < 1e-6:
        raise MapError(f"object {name!r}: the outline has no area")
    segs = segments_of(outline[None])[0]
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue  # neighbours through the closing edge
            if _segments_cross(segs[i], segs[j]):
                raise MapError(f"object {name!r}: the outline crosses itself (edges {i} and {j})")


def _segments_cross(a: FloatArray, b: FloatArray) -> bool:
    def orient(px: float, py: float, qx: float, qy: float, rx: float, ry: float) -> float:
        return (qx - px) * (ry - py) - (qy - py) * (rx - px)

    d1 = orient(b[0], b[1], b[2], b[3], a[0], a[1])
    d2 = orient(b[0], b[1], b[2], b[3], a[2], a[3])
    d3 = orient(a[0], a[1], a[2], a[3], b[0], b[1])
    d4 = orient(a[0], a[1], a[2], a[3], b[2], b[3])
    return d1 * d2 < 0 and d3 * d4 < 0


def door_shape(door: Door) -> ObjectShape:
    """A site door as a shape: the leaf, a rectangle ``leaf_length x thickness`` from the hinge."""
    if not 0 < abs(door.opening_angle) <= math.pi:
        raise MapError(f"door {door.name!r}: opening_angle must be non-zero and at most pi in size")
    h = door.thickness / 2
    outline = np.array([[0.0, -h], [door.leaf_length, -h], [door.leaf_length, h], [0.0, h]])
    lo, hi = sorted((0.0, float(door.opening_angle)))
    r = door.leaf_length + h
    x, y = door.hinge
    return ObjectShape(
        name=door.name,
        kind="door",
        outline=outline,
        hinge=(float(x), float(y)),
        closed_direction=float(door.closed_direction),
        low=lo,
        high=hi,
        nominal=(0.0,),
        reach=(x - r, y - r, x + r, y + r),
    )


def furniture_shape(item: Furniture, margin: float = 0.5) -> ObjectShape:
    """A site piece of furniture as a shape; it may stand within ``margin`` of any of its poses."""
    outline = np.asarray(item.outline, dtype=np.float64)
    _validate_outline(item.name, outline)
    poses = np.asarray(item.poses, dtype=np.float64)
    r = float(np.hypot(outline[:, 0], outline[:, 1]).max()) + margin
    return ObjectShape(
        name=item.name,
        kind="furniture",
        outline=outline,
        nominal=tuple(float(v) for v in poses[0]),
        reach=(
            float(poses[:, 0].min() - r),
            float(poses[:, 1].min() - r),
            float(poses[:, 0].max() + r),
            float(poses[:, 1].max() + r),
        ),
        symmetry=_symmetry(outline),
    )


def shapes_of_site(
    doors: Sequence[Door], furniture: Sequence[Furniture], margin: float = 0.5
) -> list[ObjectShape]:
    """Every dynamic object of a site, doors first, in the site's order."""
    return [door_shape(d) for d in doors] + [furniture_shape(f, margin) for f in furniture]


# --------------------------------------------------------------------------------------------
# The beams against the outlines' edges
# --------------------------------------------------------------------------------------------


def _check(poses: ArrayLike, angles: ArrayLike, segs: ArrayLike, base: ArrayLike) -> tuple[FloatArray, ...]:
    p = np.ascontiguousarray(np.asarray(poses, dtype=np.float64))
    a = np.ascontiguousarray(np.asarray(angles, dtype=np.float64).ravel())
    s = np.ascontiguousarray(np.asarray(segs, dtype=np.float64))
    b = np.ascontiguousarray(np.asarray(base, dtype=np.float64))
    if p.ndim != 2 or p.shape[1] != 3:
        raise MapError(f"laser poses must be (N, 3), got {p.shape}")
    if s.ndim != 3 or s.shape[2] != 4:
        raise MapError(f"segments must be (S, M, 4), got {s.shape}")
    if b.shape != (p.shape[0], a.shape[0]):
        raise MapError(f"base ranges must be (N, B) = {(p.shape[0], a.shape[0])}, got {b.shape}")
    return p, a, s, b


def segment_ranges_reference(
    poses: ArrayLike, angles: ArrayLike, segs: ArrayLike, base: ArrayLike
) -> FloatArray:
    """Plain numpy form of :func:`segment_ranges`: ranges ``(N, S, B)``.

    ``poses`` ``(N, 3)`` laser poses, ``angles`` ``(B,)`` beam angles in the laser frame, ``segs``
    ``(S, M, 4)`` the edges of each object state, ``base`` ``(N, B)`` the static map's ranges.
    Each beam ``o + t d`` (``t >= 0``) meets an edge ``p + u (q - p)`` (``0 <= u <= 1``) where
    ``t = (p - o) x e / (d x e)`` and ``u = (p - o) x d / (d x e)``; the range is the smallest such
    ``t``, or ``base`` when that is nearer.
    """
    p, a, s, b = _check(poses, angles, segs, base)
    th = p[:, 2:3] + a[None, :]  # (N, B)
    dx, dy = np.cos(th)[:, None, :, None], np.sin(th)[:, None, :, None]  # (N, 1, B, 1)
    px = s[None, :, None, :, 0] - p[:, 0, None, None, None]  # (N, S, 1, M)
    py = s[None, :, None, :, 1] - p[:, 1, None, None, None]
    ex = (s[:, :, 2] - s[:, :, 0])[None, :, None, :]
    ey = (s[:, :, 3] - s[:, :, 1])[None, :, None, :]
    den = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (px * ey - py * ex) / den
        u = (px * dy - py * dx) / den
    ok = (den != 0.0) & (t >= 0.0) & (u >= 0.0) & (u <= 1.0)
    t = np.where(ok, t, np.inf)
    near = t.min(axis=3) if t.shape[3] else np.full(t.shape[:3], np.inf)
    return np.asarray(np.minimum(near, b[:, None, :]), dtype=np.float64)


@numba.njit(cache=True, inline="always")
def nearest_edge(segs: FloatArray, k: int, x: float, y: float, dx: float, dy: float, best: float) -> float:
    """The distance along the unit direction ``(dx, dy)`` from ``(x, y)`` to the nearest of the
    edges ``segs[k]`` (rows ``x0, y0, x1, y1``), or ``best`` when none is nearer: one beam against
    one object state, the inner loop of both numba kernels of the objects' sensor model."""
    for m in range(segs.shape[1]):
        ex = segs[k, m, 2] - segs[k, m, 0]
        ey = segs[k, m, 3] - segs[k, m, 1]
        den = dx * ey - dy * ex
        if den == 0.0:
            continue
        px = segs[k, m, 0] - x
        py = segs[k, m, 1] - y
        t = (px * ey - py * ex) / den
        if t < 0.0 or t >= best:
            continue
        u = (px * dy - py * dx) / den
        if 0.0 <= u <= 1.0:
            best = t
    return best


@numba.njit(cache=True)
def _segment_ranges(
    x: FloatArray,
    y: FloatArray,
    theta: FloatArray,
    angles: FloatArray,
    segs: FloatArray,
    base: FloatArray,
    out: Float32Array,
) -> None:
    n, nb = base.shape
    ns = segs.shape[0]
    for i in range(n):
        for b in range(nb):
            a = theta[i] + angles[b]
            dx = math.cos(a)
            dy = math.sin(a)
            for k in range(ns):
                out[i, k, b] = nearest_edge(segs, k, x[i], y[i], dx, dy, base[i, b])


def segment_ranges(poses: ArrayLike, angles: ArrayLike, segs: ArrayLike, base: ArrayLike) -> Float32Array:
    """Expected ranges ``(N, S, B)`` (float32): ``base`` lowered to the edges of each state.

    The numba kernel of :func:`segment_ranges_reference` (same arguments, same result).
    """
    p, a, s, b = _check(poses, angles, segs, base)
    out = np.empty((p.shape[0], s.shape[0], a.shape[0]), dtype=np.float32)
    if out.size:
        _segment_ranges(
            np.ascontiguousarray(p[:, 0]),
            np.ascontiguousarray(p[:, 1]),
            np.ascontiguousarray(p[:, 2]),
            a,
            s,
            b,
            out,
        )
    return out


def beam_window(
    poses: ArrayLike, boxes: ArrayLike, angle_min: float, increment: float, num_beams: int
) -> NDArray[np.int64]:
    """The consecutive beams that hit at least one of ``boxes`` ``(S, 4)`` from some laser pose.

    Schulz and Burgard (2001), Sec. 3: beams that hit the object in no sample state only give a
    constant factor of Eq. 10, and the beams that may hit it are approximated by the consecutive
    beams meeting its bounding box in at least one sample state. Here the box is the union of the
    samples' boxes, the beams those whose direction lies within the box's angular extent seen from
    any of the laser ``poses`` ``(N, 3)``. Indices into the scan, in beam order (wrapping around a
    full-circle scan); all beams when a laser is inside the box.
    """
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    bx = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    x0, y0 = bx[:, 0].min(), bx[:, 1].min()
    x1, y1 = bx[:, 2].max(), bx[:, 3].max()
    full = abs(num_beams * increment - 2 * math.pi) < 1e-6
    if np.any((p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1)):
        return np.arange(num_beams, dtype=np.int64)
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    centre = np.arctan2(cy - p[:, 1], cx - p[:, 0]) - p[:, 2]  # (N,) in each laser's frame
    ang = np.arctan2(corners[None, :, 1] - p[:, 1, None], corners[None, :, 0] - p[:, 0, None]) - p[:, 2, None]
    rel = wrap_angle(ang - centre[:, None])  # seen from outside the box spans < pi: no wrap inside it
    lo, hi = rel.min(axis=1), rel.max(axis=1)  # (N,)
    beams = angle_min + increment * np.arange(num_beams)
    off = wrap_angle(beams[None, :] - centre[:, None])  # (N, B)
    hit = ((off >= lo[:, None] - 1e-9) & (off <= hi[:, None] + 1e-9)).any(axis=0)
    inside = np.flatnonzero(hit)
    if full and inside.size and inside[0] == 0 and inside[-1] == num_beams - 1:
        # the window wraps around the scan's ends: start it after the gap
        gap = int(np.argmax(np.diff(inside))) + 1 if inside.size < num_beams else 0
        inside = np.roll(inside, -gap)
    return inside.astype(np.int64)


class ObjectIndex:
    """Spatial tiling (Samet 1990, the paper's [23]) of the objects' reachable boxes.

    Each object is filed under every ``tile`` x ``tile`` square its :attr:`ObjectShape.reach` box
    touches; :meth:`near` answers which objects may lie within ``radius`` of a point by looking at
    the tiles of that disc's box only, so many objects in a big building stay cheap.
    """

    def __init__(self, shapes: Sequence[ObjectShape], tile: float = 2.0) -> None:
        if not tile > 0:
            raise MapError(f"tile must be positive, got {tile}")
        self.shapes = list(shapes)
        self.tile = float(tile)
        self._tiles: dict[tuple[int, int], list[int]] = defaultdict(list)
        for i, s in enumerate(self.shapes):
            for key in self._keys(*s.reach):
                self._tiles[key].append(i)

    def _keys(self, x0: float, y0: float, x1: float, y1: float) -> list[tuple[int, int]]:
        t = self.tile
        return [
            (i, j)
            for i in range(math.floor(x0 / t), math.floor(x1 / t) + 1)
            for j in range(math.floor(y0 / t), math.floor(y1 / t) + 1)
        ]

    def near(self, x: float, y: float, radius: float) -> list[int]:
        """Indices of the objects whose reachable box comes within ``radius`` of ``(x, y)``."""
        found: set[int] = set()
        for key in self._keys(x - radius, y - radius, x + radius, y + radius):
            found.update(self._tiles.get(key, ()))
        out = []
        for i in sorted(found):
            bx0, by0, bx1, by1 = self.shapes[i].reach
            dx = max(bx0 - x, 0.0, x - bx1)
            dy = max(by0 - y, 0.0, y - by1)
            if dx * dx + dy * dy <= radius * radius:
                out.append(i)
        return out
