"""The object-based world model of an exhibition site, read from one YAML file.

A site is the static map (a ROS map_server occupancy grid and/or wall polygons), the exhibits
(name, position, viewing pose, short text), tours (ordered exhibits), doors (hinge, leaf length,
opening angle), movable furniture (outline and pose), obstacles the laser cannot see (glass cases,
low tables: outline and height range) and ceiling lights (3D positions): the object-based model of
Schulz and Burgard (2001, Sec. 3) and the exhibit/tour database of Burgard et al. (tele-presence).

Units: metres and radians, world frame of the map. Paths in the file are relative to the file.
A wrong file raises :class:`SiteError` naming the file and the field (``exhibits[3].viewing_pose``).
"""

from __future__ import annotations

import math
from functools import cached_property
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from tourbot.errors import InputError
from tourbot.maps.grid import OccupancyGrid

__all__ = [
    "CeilingLight",
    "Door",
    "Exhibit",
    "Furniture",
    "InvisibleObstacle",
    "MapSpec",
    "Schedule",
    "Site",
    "SiteError",
    "Tour",
    "load_site",
    "segment_walls",
    "walls_grid",
]

Point = tuple[float, float]
Pose = tuple[float, float, float]
Polygon = Annotated[list[Point], Field(min_length=3)]


class SiteError(InputError):
    """A site file that is missing, malformed or inconsistent; names the file and the field."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class MapSpec(_Model):
    """The static map: a ROS map_server YAML (``grid``) and/or wall polygons (``walls``).

    With walls only, the grid is rasterised at ``resolution`` over the walls' bounding box plus
    ``margin``; with both, the walls are drawn into the loaded grid.
    """

    grid: str | None = None
    walls: list[Polygon] = []
    resolution: float = Field(default=0.05, gt=0)
    margin: float = Field(default=1.0, ge=0)

    @model_validator(mode="after")
    def _needs_something(self) -> MapSpec:
        if self.grid is None and not self.walls:
            raise ValueError("a map needs a grid file, wall polygons, or both")
        return self


class Exhibit(_Model):
    """A thing to show: where it stands, where the robot stops to present it, what it says."""

    name: str = Field(min_length=1)
    position: Point
    viewing_pose: Pose
    text: str = ""
    dwell: float = Field(default=10.0, ge=0, description="seconds the robot stays to present it")


class Tour(_Model):
    """An ordered list of exhibit names."""

    name: str = Field(min_length=1)
    exhibits: list[str] = Field(min_length=1)
    description: str = ""


class Schedule(_Model):
    """When a door or a piece of furniture changes.

    ``period``: seconds between changes; ``random``: draw the change times from an exponential
    distribution of that mean instead of a fixed period (seeded by the simulator).
    """

    period: float = Field(default=60.0, gt=0)
    random: bool = False
    start_open: bool = True


class Door(_Model):
    """A door leaf of ``leaf_length`` turning about ``hinge``.

    ``closed_direction`` is the direction (rad, world) of the leaf when closed and
    ``opening_angle`` the signed angle it turns through to be fully open.
    """

    name: str = Field(min_length=1)
    hinge: Point
    leaf_length: float = Field(gt=0)
    closed_direction: float
    opening_angle: float = math.pi / 2
    thickness: float = Field(default=0.05, gt=0)
    schedule: Schedule = Schedule()

    def leaf(self, open_fraction: float) -> tuple[Point, Point]:
        """The leaf's two end points at ``open_fraction`` in [0, 1]."""
        a = self.closed_direction + open_fraction * self.opening_angle
        x0, y0 = self.hinge
        return (x0, y0), (x0 + self.leaf_length * math.cos(a), y0 + self.leaf_length * math.sin(a))


class Furniture(_Model):
    """A movable object: ``outline`` in its own frame, and the poses it is moved between."""

    name: str = Field(min_length=1)
    outline: Polygon
    poses: list[Pose] = Field(min_length=1)
    schedule: Schedule = Schedule(period=120.0)

    def polygon(self, pose: Pose) -> list[Point]:
        """The outline placed at ``pose`` (world)."""
        c, s = math.cos(pose[2]), math.sin(pose[2])
        return [(pose[0] + c * x - s * y, pose[1] + s * x + c * y) for x, y in self.outline]


#: A table's top is this thick (m); its legs stand this far inside the outline's corners and are
#: this thick (the laser sees them as four thin posts).
TABLE_TOP = 0.04
TABLE_LEG_INSET = 0.05
TABLE_LEG_RADIUS = 0.025


class InvisibleObstacle(_Model):
    """An obstacle off the laser plane: world outline (convex), height range and ``kind``.

    ``kind`` says what it is made of: ``box`` (solid from ``height[0]`` to ``height[1]``: a low bench
    or platform below the laser plane, a wall cabinet or fire extinguisher above it), ``glass`` (a
    glass case: the laser passes through its panes, the camera sees through them) or ``table`` (a
    top :data:`TABLE_TOP` thick at ``height[1]`` on four thin legs). A glass case may stand on an
    opaque base rail (plinth) ``base`` metres high and carry an opaque top frame (lid) ``lid``
    metres thick, both on its whole outline; the panes fill the rest (0 and 0: a frameless case of
    glued panes). What a laser at a given height sees of it is derived from these heights
    (:meth:`laser_outline`, :meth:`laser_legs`), never drawn twice.
    """

    name: str = Field(min_length=1)
    outline: Polygon
    height: tuple[float, float] = (0.0, 0.3)
    kind: Literal["box", "glass", "table"] = "box"
    base: float = Field(default=0.0, ge=0.0)
    lid: float = Field(default=0.0, ge=0.0)

    @field_validator("height")
    @classmethod
    def _ordered(cls, v: tuple[float, float]) -> tuple[float, float]:
        if v[0] > v[1]:
            raise ValueError("height must be (low, high) with low <= high")
        return v

    @model_validator(mode="after")
    def _parts(self) -> InvisibleObstacle:
        if (self.base or self.lid) and self.kind != "glass":
            raise ValueError("base and lid are the parts of a glass case (kind: glass)")
        if self.base + self.lid > self.height[1] - self.height[0]:
            raise ValueError("base + lid must fit within the height range")
        return self

    def solid_parts(self) -> list[tuple[float, float]]:
        """The height ranges of the opaque parts: the whole box, or a glass case's base rail and lid
        (a table's top and legs are :data:`TABLE_TOP` and :meth:`leg_centres`)."""
        lo, hi = self.height
        if self.kind == "box":
            return [(lo, hi)]
        if self.kind != "glass":
            return []
        return [p for p in ((lo, lo + self.base), (hi - self.lid, hi)) if p[1] > p[0]]

    def laser_outline(self, laser_height: float) -> bool:
        """Whether a laser at ``laser_height`` sees the outline: an opaque part (a box, a glass
        case's base rail or lid) spans its plane."""
        return any(lo <= laser_height <= hi for lo, hi in self.solid_parts())

    def laser_legs(self, laser_height: float) -> list[Point]:
        """Centres of the table legs a laser at ``laser_height`` sees (none for boxes and glass)."""
        if self.kind != "table" or not self.height[0] <= laser_height <= self.height[1] - TABLE_TOP:
            return []
        return self.leg_centres()

    def leg_centres(self) -> list[Point]:
        """A table's legs: one in each corner, :data:`TABLE_LEG_INSET` from both edges."""
        pts = np.asarray(self.outline, dtype=np.float64)
        out = []
        for k, p in enumerate(pts):
            a = pts[k - 1] - p
            b = pts[(k + 1) % len(pts)] - p
            a /= max(float(np.hypot(*a)), 1e-12)
            b /= max(float(np.hypot(*b)), 1e-12)
            bis = a + b
            half = 0.5 * math.acos(float(np.clip(a @ b, -1.0, 1.0)))
            q = p + bis / max(float(np.hypot(*bis)), 1e-12) * TABLE_LEG_INSET / max(math.sin(half), 1e-6)
            out.append((float(q[0]), float(q[1])))
        return out


class CeilingLight(_Model):
    """A ceiling light at ``position`` (x, y, z) in metres; ``type`` names its fixture (the shape and
    size the camera simulator draws, e.g. the Domus hall's types A, B and E)."""

    position: tuple[float, float, float]
    name: str = ""
    type: str = ""


class Site(_Model):
    """A whole exhibition site; ``base_dir`` is the folder its relative paths start from."""

    name: str = Field(min_length=1)
    description: str = ""
    map: MapSpec
    exhibits: list[Exhibit] = []
    tours: list[Tour] = []
    doors: list[Door] = []
    furniture: list[Furniture] = []
    invisible_obstacles: list[InvisibleObstacle] = []
    ceiling_lights: list[CeilingLight] = []
    approximate: list[str] = Field(default=[], description="fields drawn approximately (e.g. map.walls)")
    base_dir: Path = Field(default=Path("."), exclude=True)

    model_config = ConfigDict(extra="forbid", frozen=True, arbitrary_types_allowed=True)

    @model_validator(mode="after")
    def _consistent(self) -> Site:
        _unique("exhibits", [e.name for e in self.exhibits])
        _unique("tours", [t.name for t in self.tours])
        _unique("doors", [d.name for d in self.doors])
        _unique("furniture", [f.name for f in self.furniture])
        known = {e.name for e in self.exhibits}
        for i, tour in enumerate(self.tours):
            for j, name in enumerate(tour.exhibits):
                if name not in known:
                    raise _FieldError(f"tours.{i}.exhibits.{j}", f"unknown exhibit {name!r}")
        return self

    def exhibit(self, name: str) -> Exhibit:
        for e in self.exhibits:
            if e.name == name:
                return e
        raise SiteError(f"no exhibit named {name!r} in site {self.name!r}", field="exhibits")

    def tour(self, name: str) -> Tour:
        for t in self.tours:
            if t.name == name:
                return t
        names = ", ".join(t.name for t in self.tours) or "none"
        raise SiteError(f"no tour named {name!r} in site {self.name!r} (tours: {names})", field="tours")

    @cached_property
    def grid(self) -> OccupancyGrid:
        """The static occupancy grid: the map file with the walls drawn in (cached)."""
        return _static_grid(self)

    def invisible_mask(self, grid: OccupancyGrid | None = None) -> np.ndarray:
        """Cells of ``grid`` (default: the static grid) covered by invisible obstacles: the
        hand-drawn second map of the site (every such obstacle, whatever the laser sees of it)."""
        g = grid or self.grid
        return rasterize_polygons(g, [o.outline for o in self.invisible_obstacles])

    def laser_missed(self, laser_height: float) -> list[InvisibleObstacle]:
        """The invisible obstacles whose outline a laser at ``laser_height`` does not see."""
        return [o for o in self.invisible_obstacles if not o.laser_outline(laser_height)]


class _FieldError(ValueError):
    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field


def _unique(section: str, names: list[str]) -> None:
    seen: set[str] = set()
    for i, n in enumerate(names):
        if n in seen:
            raise _FieldError(f"{section}.{i}.name", f"duplicate name {n!r}")
        seen.add(n)


def load_site(path: str | Path) -> Site:
    """Read and validate a site file; errors name the file and the field."""
    p = Path(path)
    if p.is_dir():
        p = p / "site.yaml"
    try:
        text = p.read_text()
    except OSError as exc:
        raise SiteError(f"cannot read the site file: {exc.strerror or exc}", path=p) from exc
    except UnicodeDecodeError as exc:
        raise SiteError(
            f"not a text (UTF-8) YAML file: bad byte 0x{exc.object[exc.start]:02x} at offset {exc.start}",
            path=p,
        ) from exc
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = None if mark is None else mark.line + 1
        raise SiteError(f"not valid YAML: {getattr(exc, 'problem', exc)}", path=p, line=line) from exc
    if not isinstance(data, dict):
        raise SiteError("a site file must be a mapping with at least 'name' and 'map'", path=p)
    return site_from_dict(data, base_dir=p.parent, path=p)


def site_from_dict(data: dict[str, Any], *, base_dir: Path, path: Path | None = None) -> Site:
    """Validate a site given as plain data (``path`` only for the error messages)."""
    try:
        return Site.model_validate({**data, "base_dir": base_dir})
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = ".".join(str(x) for x in err["loc"])
        ctx_err = (err.get("ctx") or {}).get("error")
        if isinstance(ctx_err, _FieldError):
            loc = ctx_err.field
        msg = err["msg"].removeprefix("Value error, ")
        more = f" (and {len(exc.errors()) - 1} more)" if len(exc.errors()) > 1 else ""
        raise SiteError(msg + more, path=path, field=loc or None) from exc


def _static_grid(site: Site) -> OccupancyGrid:
    spec = site.map
    if spec.grid is None:
        return walls_grid(spec.walls, spec.resolution, spec.margin)
    from tourbot.io.mapserver import read_map

    grid = read_map(site.base_dir / spec.grid)
    return _draw_walls(grid, spec.walls) if spec.walls else grid


def walls_grid(walls: list[list[Point]], resolution: float = 0.05, margin: float = 1.0) -> OccupancyGrid:
    """The occupancy grid of wall polygons alone, as a site without a grid file has it: free over
    the walls' bounding box plus ``margin``, the walls' outlines occupied."""
    pts = np.array([p for poly in walls for p in poly], dtype=np.float64).reshape(-1, 2)
    if len(pts) == 0:
        raise ValueError("no walls to draw")
    lo = pts.min(axis=0) - margin
    hi = pts.max(axis=0) + margin
    cols = max(1, math.ceil((hi[0] - lo[0]) / resolution))
    rows = max(1, math.ceil((hi[1] - lo[1]) / resolution))
    grid = OccupancyGrid(
        np.zeros((rows, cols), dtype=np.float32), resolution, (float(lo[0]), float(lo[1]), 0.0)
    )
    return _draw_walls(grid, walls)


def segment_walls(segments: np.ndarray) -> list[list[Point]]:
    """Wall segments ``(N, 2, 2)`` (a line map) as the site's wall polygons: each the closed
    polyline ``a, b, a`` whose outline is the segment."""
    return [
        [(round(float(a[0]), 3), round(float(a[1]), 3)), (round(float(b[0]), 3), round(float(b[1]), 3)),
         (round(float(a[0]), 3), round(float(a[1]), 3))]
        for a, b in np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    ]  # fmt: skip


def _draw_walls(grid: OccupancyGrid, walls: list[list[Point]]) -> OccupancyGrid:
    mask = rasterize_polygons(grid, walls, outline_only=True)
    prob = grid.prob.copy()
    prob[mask] = 1.0
    return OccupancyGrid(prob, grid.resolution, grid.origin, grid.occupied_thresh, grid.free_thresh)


def rasterize_polygons(
    grid: OccupancyGrid, polygons: list[list[Point]], *, outline_only: bool = False
) -> np.ndarray:
    """Boolean mask of the cells of ``grid`` covered by ``polygons`` (world points).

    ``outline_only`` draws only the edges, one cell thick (walls given as closed polylines).
    """
    import cv2

    mask = np.zeros(grid.shape, dtype=np.uint8)
    for poly in polygons:
        rc = _world_to_fcells(grid, np.asarray(poly, dtype=np.float64))
        pts = np.round(rc[:, ::-1] * 16).astype(np.int32).reshape(-1, 1, 2)  # (col, row), 4 fraction bits
        if outline_only:
            cv2.polylines(mask, [pts], isClosed=True, color=1, thickness=1, shift=4)
        else:
            cv2.fillPoly(mask, [pts], color=1, shift=4)
            cv2.polylines(mask, [pts], isClosed=True, color=1, thickness=1, shift=4)
    return mask.astype(bool)


def _world_to_fcells(grid: OccupancyGrid, pts: np.ndarray) -> np.ndarray:
    """Continuous (row, col) coordinates of world points, cell centres at half-integers minus 0.5."""
    from tourbot.geometry import invert, transform_points

    local = transform_points(invert(grid.origin), pts) / grid.resolution - 0.5
    return np.stack([local[:, 1], local[:, 0]], axis=-1)
