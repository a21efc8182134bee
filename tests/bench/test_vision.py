"""The vision benchmark's figures: outline cells found within 10 cm, only of obstacles passed."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tourbot.bench.vision import _outline_found, _truth_masks
from tourbot.site import site_from_dict
from tourbot.vision.occupancy import VisionMap

SITE = {
    "name": "room",
    "map": {"walls": [[[0, 0], [10, 0], [10, 6], [0, 6]]], "resolution": 0.05},
    "invisible_obstacles": [
        {"name": "near", "outline": [[4, 2], [5, 2], [5, 3], [4, 3]], "kind": "glass", "height": [0, 1]},
        {"name": "far", "outline": [[8, 4], [9, 4], [9, 5], [8, 5]], "kind": "glass", "height": [0, 1]},
        {"name": "seen", "outline": [[1, 4], [2, 4], [2, 5], [1, 5]], "height": [0, 0.9]},
    ],
}


def test_outline_share_counts_cells_within_10_cm_of_passed_obstacles_only() -> None:
    site = site_from_dict(SITE, base_dir=Path("."))
    path = np.array([[x, 1.0] for x in np.arange(0.5, 6.0, 0.1)])  # 1 m from "near", 3 m from "far"
    # the near square's south and west edges found (half its outline)
    south = np.array([[x, 2.0] for x in np.arange(4.0, 5.01, 0.05)])
    west = np.array([[4.0, y] for y in np.arange(2.0, 3.01, 0.05)])
    found = _outline_found(site, path, np.vstack([south, west]), laser_height=0.4)
    assert set(found) == {"near"}  # "far" not passed within 2 m, "seen" seen by the laser
    assert 0.45 < found["near"] < 0.6
    assert _outline_found(site, path, np.zeros((0, 2)), 0.4) == {"near": 0.0}


def test_truth_masks_cover_walls_and_obstacles() -> None:
    site = site_from_dict(SITE, base_dir=Path("."))
    frame = VisionMap(site.grid).frame
    near_real, hand = _truth_masks(site, frame)
    cell = frame.world_to_cell(np.array([[4.5, 2.5], [3.0, 3.0], [0.05, 3.0]]))
    assert hand[cell[0, 0], cell[0, 1]]
    assert not near_real[cell[1, 0], cell[1, 1]]
    assert near_real[cell[2, 0], cell[2, 1]]  # beside the wall
