"""Ceiling lights in an infrared-filtered fisheye image (Gamallo et al., Sec. III-D).

The paper thresholds the image, dilates it and extracts contours, and for each region keeps its
centroid, its radius from the image centre and its azimuth. Here the same segmentation is done with
OpenCV's threshold and connected components (8-connected), whose centroids are the landmarks:

- a blob that is saturated and large (a light pointing at the camera, Fig. 9(a)) is processed again
  with a higher threshold inside its bounding box (Fig. 9(b)); its brightest core's centroid is kept;
- blobs smaller than ``min_area`` are noise;
- blobs touching the image border, or farther than the camera's ``rim_theta`` from the optical axis,
  are rejected: near the horizon are windows, spotlights and visitors' heads, and a light cut by the
  image border has a biased centroid.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tourbot.ceiling.rig import CeilingCamera

__all__ = ["DetectionConfig", "Detections", "detect_lights", "frame_stability"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class DetectionConfig:
    """Thresholds of the light detector (8-bit intensities, pixels)."""

    threshold: int = 200
    min_area: int = 4
    saturated_level: int = 250
    saturated_area: int = 150
    max_levels: int = 12
    border: int = 1

    def __post_init__(self) -> None:
        if not 0 < self.threshold < 255 or self.min_area < 1 or self.border < 0:
            raise ValueError("DetectionConfig needs 0 < threshold < 255, min_area >= 1, border >= 0")


@dataclass(frozen=True)
class Detections:
    """Detected lights: ``centroids`` ``(N, 2)`` pixels (u, v), their ``areas`` and how many blobs
    were ``rejected`` at the rim or the border."""

    centroids: FloatArray
    areas: NDArray[np.int64]
    rejected: int = 0
    rethresholded: int = 0

    def __len__(self) -> int:
        return len(self.centroids)


def detect_lights(
    image: NDArray[np.uint8], camera: CeilingCamera, config: DetectionConfig | None = None
) -> Detections:
    """The lights of an 8-bit grayscale image (threshold, connected components, centroids)."""
    import cv2

    cfg = config or DetectionConfig()
    camera.check_image(image.shape)
    img = np.ascontiguousarray(image, dtype=np.uint8)
    binary = (img >= cfg.threshold).astype(np.uint8)
    n, labels, stats, cents = cv2.connectedComponentsWithStats(binary, connectivity=8)
    out: list[tuple[float, float]] = []
    areas: list[int] = []
    rejected = 0
    redone = 0
    h, w = img.shape
    for k in range(1, n):
        x, y, bw, bh, area = (int(v) for v in stats[k])
        if area < cfg.min_area:
            continue
        if x < cfg.border or y < cfg.border or x + bw > w - cfg.border or y + bh > h - cfg.border:
            rejected += 1
            continue
        box = img[y : y + bh, x : x + bw]
        mask = labels[y : y + bh, x : x + bw] == k
        cores = [(float(cents[k][0]), float(cents[k][1]), area)]
        if area >= cfg.saturated_area and int(box[mask].max()) >= cfg.saturated_level:
            found = _cores(box, mask, cfg)
            if found:
                cores = [(cx + x, cy + y, a) for cx, cy, a in found]
                redone += 1
        for cu, cv, a in cores:
            out.append((cu, cv))
            areas.append(a)
    cen = np.asarray(out, dtype=np.float64).reshape(-1, 2)
    keep = camera.theta_of_pixels(cen) <= camera.rim_theta if len(cen) else np.zeros(0, dtype=bool)
    return Detections(
        centroids=cen[keep],
        areas=np.asarray(areas, dtype=np.int64)[keep],
        rejected=rejected + int((~keep).sum()),
        rethresholded=redone,
    )


def _cores(
    box: NDArray[np.uint8], mask: NDArray[np.bool_], cfg: DetectionConfig
) -> list[tuple[float, float, int]]:
    """A saturated blob processed again (Fig. 9): the threshold is raised through the blob's own
    intensity levels (at most ``max_levels`` of them) until it splits into cores or shrinks below a
    third of its area; the centroids of those cores. A flat blob (already binary) has no core."""
    import cv2

    total = int(mask.sum())
    values = np.unique(box[mask])
    levels = values[values > cfg.threshold]
    if len(levels) > cfg.max_levels:
        levels = levels[np.linspace(0, len(levels) - 1, cfg.max_levels).round().astype(np.int64)]
    best: list[tuple[float, float, int]] = []
    for level in levels[1:] if len(levels) and levels[0] == values.min() else levels:
        sub = ((box >= level) & mask).astype(np.uint8)
        n, _, stats, cents = cv2.connectedComponentsWithStats(sub, connectivity=8)
        found = [
            (float(cents[k][0]), float(cents[k][1]), int(stats[k][4]))
            for k in range(1, n)
            if stats[k][4] >= cfg.min_area
        ]
        if not found:
            break
        best = found
        if len(found) > 1 or sum(a for *_, a in found) < total / 3:
            break
    return best


def frame_stability(frames: list[Detections], tolerance: float) -> float:
    """The fraction of a frame's detections with a detection of the next frame within
    ``tolerance`` pixels, over consecutive frames with detections in both."""
    found = 0
    total = 0
    for a, b in itertools.pairwise(frames):
        if len(a) == 0 or len(b) == 0:
            continue
        d = np.linalg.norm(a.centroids[:, None, :] - b.centroids[None, :, :], axis=2).min(axis=1)
        found += int((d <= tolerance).sum())
        total += len(a)
    return found / total if total else float("nan")
