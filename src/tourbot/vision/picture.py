"""The picture of Burgard et al.'s Fig. 3: image t-1, image t, and the inconsistencies on image t."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tourbot.vision.detector import Detection, View

__all__ = ["inconsistency_figure"]


def inconsistency_figure(path: str | Path, prev: View, cur: View, det: Detection) -> None:
    """Three panels side by side: ``prev``'s image, ``cur``'s image, and ``cur``'s image with the
    disagreeing pixels tinted red, the masked (moving visitors) blue and the triangulated
    obstacles crossed in green; written whole as PNG."""
    import cv2

    from tourbot.io.images import write_png

    a = cv2.cvtColor(prev.image, cv2.COLOR_GRAY2BGR)
    b = cv2.cvtColor(cur.image, cv2.COLOR_GRAY2BGR)
    c = b.copy().astype(np.float32)
    c[det.inconsistent] = 0.5 * c[det.inconsistent] + np.array([0.0, 0.0, 127.0])
    c[det.masked] = 0.6 * c[det.masked] + np.array([100.0, 0.0, 0.0])
    c = c.astype(np.uint8)
    for u, v in det.pixels:
        cv2.drawMarker(c, (int(u), int(v)), (0, 255, 0), cv2.MARKER_CROSS, 7, 1)
    gap = np.full((a.shape[0], 8, 3), 255, dtype=np.uint8)
    write_png(path, np.hstack([a, gap, b, gap, c]))
