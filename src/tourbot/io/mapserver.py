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
from typing import Any, Literal, get_args

import numpy as np
import yaml
from numpy.typing import NDArray

from tourbot.io.errors import MapFormatError
from tourbot.io.output import check_output, output_file
from tourbot.maps.grid import UNKNOWN, OccupancyGrid

__all__ = ["MAP_MODES", "MapMode", "check_map_output", "read_map", "write_map"]

MapMode = Literal["trinary", "scale", "raw"]
#: The ``mode`` values of a map_server YAML, the first the default.
MAP_MODES: tuple[MapMode, ...] = get_args(MapMode)

#: Grey levels map_saver writes: occupied, free, unknown.
OCCUPIED_PIXEL, FREE_PIXEL, UNKNOWN_PIXEL = 0, 254, 205
#: ``raw`` mode: the pixel of an unknown cell (above 100, the largest occupancy in percent).
RAW_UNKNOWN_PIXEL = 255


def _number(doc: dict[str, Any], key: str, path: Path, default: float | None = None) -> float:
    if key not in doc:
        if default is not None:
            return default
        raise MapFormatError(f"missing key {key!r}", path=path, field=key)
    value = doc[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise MapFormatError(f"{key} must be a number, got {value!r}", path=path, field=key)
    return float(value)


def _load_image(path: Path, yaml_path: Path) -> tuple[NDArray[np.float64], NDArray[np.bool_] | None]:
    """The image's shade per pixel (0-255, colour channels averaged as map_server does) and, when
    it has an alpha channel, which pixels are transparent (not fully opaque)."""
    from PIL import Image, UnidentifiedImageError

    if not path.exists():
        raise MapFormatError(f"the map image {path} does not exist", path=yaml_path, field="image")
    try:
        with Image.open(path) as img:
            img.load()
            transparent = None
            if img.mode in ("LA", "RGBA", "PA") or (img.mode == "P" and "transparency" in img.info):
                alpha = np.asarray(img.convert("RGBA"), dtype=np.uint8)[..., 3]
                transparent = alpha < 255
            if img.mode in ("RGB", "RGBA", "LA", "P", "PA"):
                rgb = np.asarray(img.convert("RGB"), dtype=np.float64)
                return rgb.mean(axis=2), transparent  # map_server averages the colour channels
            if img.mode not in ("L", "I", "I;16", "1"):
                raise MapFormatError(f"unsupported image mode {img.mode}", path=path)
            pixels = np.asarray(img, dtype=np.float64)
            if img.mode in ("I", "I;16") and pixels.max() > 255:
                raise MapFormatError("16-bit map images are not supported", path=path)
            return pixels * (255.0 if img.mode == "1" else 1.0), None
    except (UnidentifiedImageError, OSError, SyntaxError) as exc:
        raise MapFormatError(f"not a readable image ({exc})", path=path) from None


def _occupancy(
    pixels: NDArray[np.float64],
    transparent: NDArray[np.bool_] | None,
    mode: str,
    negate: bool,
    occ_th: float,
    free_th: float,
) -> NDArray[np.float32]:
    """Occupancy per pixel as map_server computes it (Nav2 ``map_io``), -1 where unknown."""
    prob = np.full(pixels.shape, UNKNOWN, dtype=np.float32)
    if mode == "raw":
        known = pixels <= 100
        prob[known] = pixels[known] / 100.0
        return prob
    occ = pixels / 255.0 if negate else (255.0 - pixels) / 255.0
    prob[occ > occ_th] = 1.0
    prob[occ < free_th] = 0.0
    if mode == "scale":
        mid = (occ >= free_th) & (occ <= occ_th)
        prob[mid] = (occ[mid] - free_th) / (occ_th - free_th)
        if transparent is not None:
            prob[transparent] = UNKNOWN
    return prob


def read_map(yaml_path: str | Path) -> OccupancyGrid:
    """Read a map_server map into an :class:`OccupancyGrid` (occupied 1, free 0, unknown -1).

    In ``scale`` mode cells between the thresholds keep an intermediate probability and
    transparent pixels are unknown; in ``raw`` mode the pixel value is the occupancy in percent
    (values above 100 are unknown).
    """
    p = Path(yaml_path)
    if not p.exists():
        raise MapFormatError("no such file", path=p)
    if p.is_dir():
        raise MapFormatError("a folder, not a map YAML file", path=p)
    try:
        doc = yaml.safe_load(p.read_text())
    except UnicodeDecodeError:
        raise MapFormatError(
            "binary data, not a map YAML (give the .yaml file beside the image)", path=p
        ) from None
    except yaml.YAMLError as exc:
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
    pixels, transparent = _load_image(image_path, p)
    pixels = pixels[::-1]  # the image's top row is the map's far (max y) edge

    transparent = None if transparent is None else transparent[::-1]
    prob = _occupancy(pixels, transparent, mode, bool(negate), occ_th, free_th)
    return OccupancyGrid(
        prob=prob,
        resolution=resolution,
        origin=(float(origin[0]), float(origin[1]), float(origin[2])),
        occupied_thresh=occ_th,
        free_thresh=free_th,
    )


def check_map_output(yaml_path: str | Path, option: str = "--output") -> Path:
    """``yaml_path`` as a map to write, checked before any work: a ``.yaml`` name, not a folder."""
    p = check_output(yaml_path, option)
    if p.suffix.lower() not in (".yaml", ".yml"):
        raise MapFormatError("the map file name must end in .yaml (the image is written beside it)", path=p)
    return p


def write_map(grid: OccupancyGrid, yaml_path: str | Path, mode: MapMode = "trinary") -> Path:
    """Write ``grid`` as a map_server map, ``NAME.yaml`` and its image beside it; returns the image.

    ``trinary`` (as map_saver): ``NAME.pgm`` with occupied cells (above ``occupied_thresh``) black,
    free cells (known, below ``free_thresh``) white and the rest grey (unknown); reading it back
    gives 1, 0 and -1. ``raw``: ``NAME.pgm`` of occupancy percents (255 unknown). ``scale``:
    ``NAME.png``, grey with alpha (see the module docstring). Both files are written whole or not
    at all (:mod:`tourbot.io.output`).
    """
    p = check_map_output(yaml_path)
    if mode not in MAP_MODES:
        raise MapFormatError(f"mode must be one of {', '.join(MAP_MODES)}, got {mode!r}", field="mode")
    known = grid.prob >= 0.0
    occ_th, free_th = float(grid.occupied_thresh), float(grid.free_thresh)
    if mode == "scale":
        image = p.with_suffix(".png")
        occ = free_th + np.clip(grid.prob, 0.0, 1.0) * (occ_th - free_th)
        grey = _keep_classes(grid, np.rint(255.0 * (1.0 - occ)), "scale", raise_step=-1)
        grey[~known] = 128
        alpha = np.where(known, 255, 0).astype(np.uint8)
        data = _png_bytes(np.stack([grey, alpha], axis=-1)[::-1])  # grey + alpha: PIL's "LA"
    else:
        image = p.with_suffix(".pgm")
        if mode == "raw":
            pixels = _keep_classes(grid, np.rint(np.clip(grid.prob, 0.0, 1.0) * 100.0), "raw", raise_step=1)
            pixels[~known] = RAW_UNKNOWN_PIXEL
        else:
            pixels = np.full(grid.prob.shape, UNKNOWN_PIXEL, dtype=np.uint8)
            pixels[grid.free()] = FREE_PIXEL
            pixels[grid.occupied()] = OCCUPIED_PIXEL
        rows, cols = grid.shape
        header = f"P5\n# written by tourbot\n{cols} {rows}\n255\n".encode("ascii")
        data = header + np.ascontiguousarray(pixels[::-1]).tobytes()
    doc = {
        "image": image.name,
        "mode": mode,
        "resolution": float(grid.resolution),
        "origin": [float(v) for v in grid.origin],
        "negate": 0,
        "occupied_thresh": float(grid.occupied_thresh),
        "free_thresh": float(grid.free_thresh),
    }
    text = yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)
    with output_file(p) as tmp_yaml, output_file(image) as tmp_image:  # the image is renamed first
        tmp_image.write_bytes(data)
        tmp_yaml.write_text(text)
    return image


def _keep_classes(
    grid: OccupancyGrid, pixels: NDArray[np.float64], mode: str, raise_step: int
) -> NDArray[np.uint8]:
    """``pixels`` nudged by one grey level where rounding would move a known cell across a
    threshold, so that the map read back has exactly the occupied and free cells of ``grid``.

    ``raise_step`` is the change of pixel value that raises the occupancy read back.
    """
    known = grid.prob >= 0.0
    occupied, free = grid.occupied(), grid.free()
    between = known & ~occupied & ~free
    values = pixels.copy()
    for _ in range(2):  # one step always suffices; the second pass only confirms it
        back = _occupancy(values, None, mode, False, grid.occupied_thresh, grid.free_thresh)
        too_low = (occupied & ~(back > grid.occupied_thresh)) | (between & (back < grid.free_thresh))
        too_high = (free & ~(back < grid.free_thresh)) | (between & (back > grid.occupied_thresh))
        values[too_low] += raise_step
        values[too_high] -= raise_step
    return np.clip(values, 0, 255).astype(np.uint8)


def _png_bytes(pixels: NDArray[np.uint8]) -> bytes:
    import io

    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(pixels)).save(buffer, format="PNG", optimize=True)
    return buffer.getvalue()
