"""ROS map_server maps: a YAML file and an image (PGM, PNG...) beside it.

The YAML gives ``image``, ``resolution`` (m/pixel), ``origin`` ``[x, y, yaw]`` (the pose of the
lower-left pixel), ``occupied_thresh``, ``free_thresh``, ``negate`` and optionally ``mode``
(``trinary``, the default, ``scale`` or ``raw``). A pixel of value ``v`` has occupancy
``(255 - v) / 255`` (``v / 255`` when ``negate``); in ``trinary`` mode it is occupied above
``occupied_thresh``, free below ``free_thresh`` and unknown between. The image's first row is the
top of the map (largest y), the grid's first row the bottom.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from tourbot.io.errors import MapFormatError
from tourbot.maps.grid import UNKNOWN, OccupancyGrid

__all__ = ["read_map", "write_map"]

#: Grey levels map_saver writes: occupied, free, unknown.
OCCUPIED_PIXEL, FREE_PIXEL, UNKNOWN_PIXEL = 0, 254, 205


def _number(doc: dict[str, Any], key: str, path: Path, default: float | None = None) -> float:
    if key not in doc:
        if default is not None:
            return default
        raise MapFormatError(f"missing key {key!r}", path=path, field=key)
    value = doc[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise MapFormatError(f"{key} must be a number, got {value!r}", path=path, field=key)
    return float(value)


def _load_image(path: Path, yaml_path: Path) -> NDArray[np.float64]:
    from PIL import Image, UnidentifiedImageError

    if not path.exists():
        raise MapFormatError(f"the map image {path} does not exist", path=yaml_path, field="image")
    try:
        with Image.open(path) as img:
            img.load()
            if img.mode in ("RGB", "RGBA", "LA", "P"):
                rgb = np.asarray(img.convert("RGB"), dtype=np.float64)
                return rgb.mean(axis=2)  # map_server averages the colour channels
            if img.mode not in ("L", "I", "I;16", "1"):
                raise MapFormatError(f"unsupported image mode {img.mode}", path=path)
            pixels = np.asarray(img, dtype=np.float64)
            if img.mode in ("I", "I;16") and pixels.max() > 255:
                raise MapFormatError("16-bit map images are not supported", path=path)
            return pixels * (255.0 if img.mode == "1" else 1.0)
    except (UnidentifiedImageError, OSError, SyntaxError) as exc:
        raise MapFormatError(f"not a readable image ({exc})", path=path) from None


def read_map(yaml_path: str | Path) -> OccupancyGrid:
    """Read a map_server map into an :class:`OccupancyGrid` (occupied 1, free 0, unknown -1).

    In ``scale`` mode cells between the thresholds keep an intermediate probability; in ``raw``
    mode the pixel value is the occupancy in percent (values above 100 are unknown).
    """
    p = Path(yaml_path)
    if not p.exists():
        raise MapFormatError("no such file", path=p)
    if p.is_dir():
        raise MapFormatError("a folder, not a map YAML file", path=p)
    try:
        doc = yaml.safe_load(p.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise MapFormatError(f"not valid YAML ({str(exc).splitlines()[0]})", path=p) from None
    if not isinstance(doc, dict):
        raise MapFormatError("a map YAML must be a mapping of keys to values", path=p)
    if "image" not in doc or not isinstance(doc["image"], str):
        raise MapFormatError("missing key 'image' (the image file name)", path=p, field="image")
    resolution = _number(doc, "resolution", p)
    if resolution <= 0:
        raise MapFormatError(f"resolution must be positive, got {resolution}", path=p, field="resolution")
    origin = doc.get("origin")
    if (
        not isinstance(origin, list)
        or len(origin) != 3
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in origin)
    ):
        raise MapFormatError(f"origin must be [x, y, yaw], got {origin!r}", path=p, field="origin")
    occ_th = _number(doc, "occupied_thresh", p, 0.65)
    free_th = _number(doc, "free_thresh", p, 0.196)
    if not 0.0 <= free_th < occ_th <= 1.0:
        raise MapFormatError(
            f"need 0 <= free_thresh < occupied_thresh <= 1, got {free_th} and {occ_th}",
            path=p,
            field="free_thresh",
        )
    negate = doc.get("negate", 0)
    if negate not in (0, 1, True, False):
        raise MapFormatError(f"negate must be 0 or 1, got {negate!r}", path=p, field="negate")
    mode = doc.get("mode", "trinary")
    if mode not in ("trinary", "scale", "raw"):
        raise MapFormatError(f"mode must be trinary, scale or raw, got {mode!r}", path=p, field="mode")
    image_path = Path(doc["image"])
    if not image_path.is_absolute():
        image_path = p.parent / image_path
    pixels = _load_image(image_path, p)[::-1]  # the image's top row is the map's far (max y) edge

    prob = np.full(pixels.shape, UNKNOWN, dtype=np.float32)
    if mode == "raw":
        known = pixels <= 100
        prob[known] = pixels[known] / 100.0
    else:
        occ = pixels / 255.0 if negate else (255.0 - pixels) / 255.0
        prob[occ > occ_th] = 1.0
        prob[occ < free_th] = 0.0
        if mode == "scale":
            mid = (occ >= free_th) & (occ <= occ_th)
            prob[mid] = (occ[mid] - free_th) / (occ_th - free_th)
    return OccupancyGrid(
        prob=prob,
        resolution=resolution,
        origin=(float(origin[0]), float(origin[1]), float(origin[2])),
        occupied_thresh=occ_th,
        free_thresh=free_th,
    )


def write_map(grid: OccupancyGrid, yaml_path: str | Path) -> Path:
    """Write ``grid`` as map_saver does: ``NAME.yaml`` and ``NAME.pgm`` (trinary; returns the PGM).

    Occupied cells (above ``occupied_thresh``) are black, free cells (known, below ``free_thresh``)
    white, the rest grey (unknown); reading the map back gives 1, 0 and -1.
    """
    p = Path(yaml_path)
    if p.suffix.lower() not in (".yaml", ".yml"):
        raise MapFormatError("the map file name must end in .yaml", path=p)
    p.parent.mkdir(parents=True, exist_ok=True)
    pgm = p.with_suffix(".pgm")
    pixels = np.full(grid.prob.shape, UNKNOWN_PIXEL, dtype=np.uint8)
    pixels[grid.free()] = FREE_PIXEL
    pixels[grid.occupied()] = OCCUPIED_PIXEL
    rows, cols = grid.shape
    with pgm.open("wb") as f:
        f.write(f"P5\n# written by tourbot\n{cols} {rows}\n255\n".encode("ascii"))
        f.write(np.ascontiguousarray(pixels[::-1]).tobytes())
    doc = {
        "image": pgm.name,
        "mode": "trinary",
        "resolution": float(grid.resolution),
        "origin": [float(v) for v in grid.origin],
        "negate": 0,
        "occupied_thresh": float(grid.occupied_thresh),
        "free_thresh": float(grid.free_thresh),
    }
    p.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))
    return pgm
