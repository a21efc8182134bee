"""Line maps on disk: GeoJSON (RFC 7946 geometry, local metric coordinates) and SVG.

A line map is a set of wall segments ``(N, 2, 2)`` (metres, the map's frame), optionally its
corners ``(K, 2)`` and the robot's path ``(T, 2)``. The GeoJSON is a ``FeatureCollection`` of
``LineString`` walls (property ``kind: "wall"``, ``observations``: how many scans saw it), ``Point``
corners (``kind: "corner"``) and, when given, the path (``kind: "path"``); the coordinates are
metres in the map's frame, not longitude and latitude (a local "engineering" system, declared
in the collection's ``crs`` member as GeoJSON 2008 did). The SVG draws the same with y up, one
user unit a centimetre. Both are written whole (:mod:`tourbot.io.output`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from tourbot.io.errors import MapFormatError
from tourbot.io.output import write_text_whole

__all__ = ["line_map_geojson", "line_map_svg", "read_line_map", "write_line_map"]


def _segments(segments: ArrayLike) -> np.ndarray:
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    if not np.all(np.isfinite(s)):
        raise ValueError("line map segments must be finite")
    return s


def line_map_geojson(
    segments: ArrayLike,
    corners: ArrayLike | None = None,
    path: ArrayLike | None = None,
    observations: ArrayLike | None = None,
) -> dict[str, Any]:
    """The GeoJSON ``FeatureCollection`` of a line map (see the module's docstring)."""
    segs = _segments(segments)
    obs = None if observations is None else np.asarray(observations, dtype=np.int64)
    features: list[dict[str, Any]] = []
    for k, (a, b) in enumerate(segs):
        props: dict[str, Any] = {"kind": "wall", "length_m": round(float(np.hypot(*(b - a))), 4)}
        if obs is not None:
            props["observations"] = int(obs[k])
        features.append(
            {
                "type": "Feature",
                "geometry": {"type": "LineString", "coordinates": [_xy(a), _xy(b)]},
                "properties": props,
            }
        )
    for c in np.asarray(corners if corners is not None else np.zeros((0, 2)), dtype=np.float64).reshape(
        -1, 2
    ):
        features.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": _xy(c)},
                "properties": {"kind": "corner"},
            }
        )
    if path is not None:
        pts = np.asarray(path, dtype=np.float64).reshape(-1, 2)
        if len(pts) >= 2:
            features.append(
                {
                    "type": "Feature",
                    "geometry": {"type": "LineString", "coordinates": [_xy(p) for p in pts]},
                    "properties": {"kind": "path"},
                }
            )
    return {
        "type": "FeatureCollection",
        "crs": {"type": "name", "properties": {"name": "local metric map frame (m)"}},
        "features": features,
    }


def _xy(p: np.ndarray) -> list[float]:
    return [round(float(p[0]), 4), round(float(p[1]), 4)]


def line_map_svg(
    segments: ArrayLike, corners: ArrayLike | None = None, path: ArrayLike | None = None, margin: float = 1.0
) -> str:
    """An SVG picture of a line map: walls black, corners red, the path blue (y up, 1 unit = 1 cm)."""
    segs = _segments(segments)
    pts = [segs.reshape(-1, 2)]
    if path is not None:
        pts.append(np.asarray(path, dtype=np.float64).reshape(-1, 2))
    allp = np.concatenate([*pts, np.zeros((0, 2))])
    if len(allp) == 0:
        allp = np.zeros((1, 2))
    lo, hi = allp.min(axis=0) - margin, allp.max(axis=0) + margin
    w, h = (hi - lo) * 100.0

    def u(p: np.ndarray) -> str:  # metres to SVG units, y flipped
        return f"{(p[0] - lo[0]) * 100:.1f},{(hi[1] - p[1]) * 100:.1f}"

    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0f}" height="{h:.0f}" '
        f'viewBox="0 0 {w:.1f} {h:.1f}">',
        f'<rect width="{w:.1f}" height="{h:.1f}" fill="white"/>',
    ]
    if path is not None and len(pts[-1]) >= 2:
        out.append(
            '<polyline fill="none" stroke="#3060c0" stroke-width="3" points="'
            + " ".join(u(p) for p in pts[-1])
            + '"/>'
        )
    out.append('<g stroke="black" stroke-width="5" stroke-linecap="round">')
    out += [f'<line x1="{u(a).split(",")[0]}" y1="{u(a).split(",")[1]}" x2="{u(b).split(",")[0]}" '
            f'y2="{u(b).split(",")[1]}"/>' for a, b in segs]  # fmt: skip
    out.append("</g>")
    if corners is not None:
        out.append('<g fill="#c03030">')
        for c in np.asarray(corners, dtype=np.float64).reshape(-1, 2):
            x, y = u(c).split(",")
            out.append(f'<circle cx="{x}" cy="{y}" r="8"/>')
        out.append("</g>")
    out.append("</svg>")
    return "\n".join(out) + "\n"


def write_line_map(
    path: str | Path,
    segments: ArrayLike,
    corners: ArrayLike | None = None,
    trajectory: ArrayLike | None = None,
    observations: ArrayLike | None = None,
) -> None:
    """Write a line map as GeoJSON (``.geojson``, ``.json``) or SVG (``.svg``), by the suffix."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".svg":
        write_text_whole(p, line_map_svg(segments, corners, trajectory))
    elif suffix in (".geojson", ".json"):
        doc = line_map_geojson(segments, corners, trajectory, observations)
        write_text_whole(p, json.dumps(doc, indent=1) + "\n")
    else:
        raise MapFormatError(
            f"unknown line map format {p.suffix or '(none)'!r}; use .geojson or .svg", path=p
        )


def read_line_map(path: str | Path) -> np.ndarray:
    """The wall segments ``(N, 2, 2)`` of a line map GeoJSON written by :func:`write_line_map`."""
    p = Path(path)
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise MapFormatError("no such file", path=p) from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise MapFormatError(f"not a GeoJSON file ({exc})", path=p) from None
    if not isinstance(doc, dict) or doc.get("type") != "FeatureCollection":
        raise MapFormatError("not a GeoJSON FeatureCollection", path=p, field="type")
    out = []
    for k, feat in enumerate(doc.get("features", [])):
        if not isinstance(feat, dict):
            raise MapFormatError("a feature must be an object", path=p, field=f"features[{k}]")
        geom = feat.get("geometry") or {}
        props = feat.get("properties") or {}
        if props.get("kind", "wall") != "wall" or geom.get("type") != "LineString":
            continue
        coords = geom.get("coordinates")
        try:
            xy = np.asarray(coords, dtype=np.float64)
        except (TypeError, ValueError):
            xy = np.zeros((0,))
        if xy.shape != (2, 2) or not np.all(np.isfinite(xy)):
            raise MapFormatError(
                "a wall must be a LineString of two [x, y] points", path=p, field=f"features[{k}]"
            )
        out.append(xy)
    return np.array(out).reshape(-1, 2, 2)
