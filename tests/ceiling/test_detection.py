"""Light detection on the real fisheye frames of ``../shared/data/ceiling`` and on rendered images."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tourbot.ceiling.detection import DetectionConfig, detect_lights, frame_stability
from tourbot.ceiling.rig import CYCLOID_CAMERA, CeilingCamera
from tourbot.io.images import read_raw_frames

#: The real frames are thresholded by the recording software; what the issue calls their rim blobs
#: are the fragments beyond 70 degrees from the vertical (the camera leans 22 degrees forward).
REAL = replace(CYCLOID_CAMERA, rim_theta=math.radians(70.0))
REAL_DETECTION = DetectionConfig(threshold=128, min_area=12)


@pytest.fixture(scope="module")
def frames(shared_data: Path) -> np.ndarray:
    return read_raw_frames(shared_data / "ceiling" / "cycloid-ceiling-frames.raw.gz", 640, 480)


def test_real_frames_are_read(frames: np.ndarray) -> None:
    assert frames.shape == (200, 480, 640)


def test_real_detections_are_stable_and_rim_blobs_rejected(frames: np.ndarray) -> None:
    kept = [detect_lights(f, REAL, REAL_DETECTION) for f in frames[:100]]
    counts = np.array([len(d) for d in kept])
    assert counts.min() >= 5  # a grid of lights is always in view
    assert all(d.rejected > 0 for d in kept[:20])  # the rim fragments are there and refused
    for d in kept:
        assert (REAL.theta_of_pixels(d.centroids) <= REAL.rim_theta + 1e-9).all()
    # what is kept is found again in the next frame more often than the rim blobs would be
    everything = replace(REAL, rim_theta=REAL.model.max_theta)
    loose = [detect_lights(f, everything, REAL_DETECTION) for f in frames[:100]]
    s_kept = frame_stability(kept, 10.0)
    s_all = frame_stability(loose, 10.0)
    assert s_kept > 0.75
    assert s_kept > s_all


def test_saturated_blob_is_rethresholded_into_its_cores() -> None:
    cam = CeilingCamera()
    img = np.full((480, 640), 5, dtype=np.uint8)
    img[200:260, 280:360] = 220  # the bloom of two lights pointing at the camera
    img[220:232, 290:302] = 255
    img[225:237, 330:342] = 255
    d = detect_lights(img, cam)
    assert d.rethresholded == 1
    assert len(d) == 2
    assert sorted(d.centroids[:, 0].round().tolist()) == [296.0, 336.0]


def test_small_and_border_blobs_are_not_lights() -> None:
    cam = CeilingCamera()
    img = np.zeros((480, 640), dtype=np.uint8)
    img[100, 100] = 255  # one hot pixel
    img[0:10, 300:310] = 255  # cut by the border
    img[240:246, 320:326] = 255
    d = detect_lights(img, cam)
    assert len(d) == 1
    assert d.rejected == 1
    assert d.centroids[0] == pytest.approx([322.5, 242.5])
