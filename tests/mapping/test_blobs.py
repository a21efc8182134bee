from __future__ import annotations

import math

import numpy as np

from tourbot.mapping.blobs import BlobParams, person_blobs
from tourbot.records import LaserGeometry, Scan

GEOM = LaserGeometry(181, -math.pi / 2, math.radians(1), 30.0)


def _wall(distance: float) -> np.ndarray:
    """Ranges to a wall ``distance`` ahead, no return where it is out of reach."""
    with np.errstate(divide="ignore"):
        r = distance / np.cos(GEOM.angles)
    return np.where((r > 0) & (r < GEOM.max_range), r, GEOM.max_range)


def test_a_far_visitor_in_front_of_a_wall_is_a_blob() -> None:
    r = _wall(12.0)
    r[90:92] = 9.0  # two beams on a person 9 m ahead, 3 m in front of the wall
    blob = person_blobs(Scan(0.0, r, GEOM))
    assert blob[90]
    assert blob[91]
    assert blob.sum() == 2  # the wall is no blob


def test_near_wide_and_flat_things_are_no_blobs() -> None:
    r = _wall(12.0)
    r[40:42] = 2.0  # near: the leg detector's business
    r[120:128] = 9.0  # 1.1 m wide: an exhibit, not a person
    r[150:152] -= 0.1  # 10 cm in front of the wall: no contrast
    assert not person_blobs(Scan(0.0, r, GEOM)).any()
    assert person_blobs(Scan(0.0, r, GEOM), BlobParams(min_range=1.0))[40]


def test_a_blob_at_the_edge_of_the_field_of_view_is_not_judged() -> None:
    r = _wall(5.0)
    r[:3] = 6.0  # the first beams: one side unseen
    assert not person_blobs(Scan(0.0, r, GEOM))[:3].any()
