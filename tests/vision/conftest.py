from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from tourbot.site import Site, site_from_dict

# A 10 m x 6 m room with one table (0.75 m, on legs) and one glass case in the middle.
ROOM: dict[str, Any] = {
    "name": "room",
    "map": {"walls": [[[0, 0], [10, 0], [10, 6], [0, 6]]], "resolution": 0.05},
    "exhibits": [{"name": "a", "position": [9, 3], "viewing_pose": [8, 3, 0.0]}],
    "tours": [{"name": "t", "exhibits": ["a"]}],
    "invisible_obstacles": [
        {
            "name": "table",
            "outline": [[5, 2.2], [6, 2.2], [6, 2.8], [5, 2.8]],
            "height": [0, 0.75],
            "kind": "table",
        },
        {
            "name": "glass",
            "outline": [[5, 4], [5.6, 4], [5.6, 4.6], [5, 4.6]],
            "height": [0, 1.0],
            "kind": "glass",
        },
    ],
}


@pytest.fixture(scope="session")
def room() -> Site:
    return site_from_dict(ROOM, base_dir=Path("."))
