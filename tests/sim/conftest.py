from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from tourbot.site import Site, site_from_dict

# A 20 m x 12 m hall split by a wall with a 2 m opening (and a door in it), a glass case the laser
# cannot see, a bench, three exhibits and a tour.
HALL: dict[str, Any] = {
    "name": "hall",
    "map": {
        "walls": [
            [[0, 0], [20, 0], [20, 12], [0, 12]],
            [[10, 0], [10, 5], [10.05, 5], [10.05, 0]],
            [[10, 7], [10, 12], [10.05, 12], [10.05, 7]],
        ],
        "resolution": 0.05,
    },
    "exhibits": [
        {"name": "a", "position": [2, 2], "viewing_pose": [3.2, 2, math.pi], "dwell": 2},
        {"name": "b", "position": [18, 10], "viewing_pose": [16.8, 10, 0.0], "dwell": 2},
        {"name": "c", "position": [18, 2], "viewing_pose": [16.8, 2.5, 0.0], "dwell": 2},
    ],
    "tours": [{"name": "t", "exhibits": ["a", "b", "c"]}, {"name": "one", "exhibits": ["a"]}],
    "doors": [
        {
            "name": "d",
            "hinge": [10, 5],
            "leaf_length": 0.9,
            "closed_direction": math.pi / 2,
            "opening_angle": math.pi / 2,
            "schedule": {"period": 5},
        }
    ],
    "furniture": [
        {
            "name": "bench",
            "outline": [[-0.8, -0.25], [0.8, -0.25], [0.8, 0.25], [-0.8, 0.25]],
            "poses": [[5, 9, 0], [6, 10, 0.5]],
            "schedule": {"period": 3},
        }
    ],
    "invisible_obstacles": [{"name": "glass", "outline": [[13, 4], [14, 4], [14, 8], [13, 8]]}],
}


@pytest.fixture(scope="session")
def hall() -> Site:
    return site_from_dict(HALL, base_dir=Path("."))
