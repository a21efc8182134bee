from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.people.scenes import legs_of, scan_with_circles
from tourbot.people.legs import (
    LegConfig,
    LegFeatures,
    detect_legs,
    group_legs,
    leg_segments,
    leg_segments_reference,
)


def test_two_legs_become_one_person_feature() -> None:
    scan = scan_with_circles(0.0, (0.0, 0.0, 0.0), legs_of(3.0, 1.0, 0.0, 0.0))
    legs = detect_legs(scan)
    assert len(legs) == 2
    assert np.all(legs.probability > 0.5)
    persons = group_legs(legs)
    assert len(persons) == 1
    assert persons.members.tolist() == [[0, 1]] or persons.members.tolist() == [[1, 0]]
    # The feature lies between the legs, a little in front of their centres (the visible surface).
    assert np.linalg.norm(persons.points[0] - [3.0, 1.0]) < 0.08


def test_walls_and_wide_objects_are_not_legs() -> None:
    # A 1 m wide box in front of the wall: a local minimum, but far too wide for a leg.
    circles = [(2.0, y, 0.06) for y in np.arange(-0.5, 0.5, 0.05)]
    legs = detect_legs(scan_with_circles(0.0, (0.0, 0.0, 0.0), circles))
    assert len(legs) == 0


def test_far_legs_are_ignored() -> None:
    scan = scan_with_circles(0.0, (0.0, 0.0, 0.0), legs_of(9.0, 0.0, 0.0, 0.0), wall=12.0)
    assert len(detect_legs(scan, LegConfig(max_range=8.0))) == 0


def test_no_returns_no_legs() -> None:
    scan = scan_with_circles(0.0, (0.0, 0.0, 0.0), [])
    scan = type(scan)(0.0, np.full(scan.ranges.shape, np.inf), scan.geometry)
    assert len(detect_legs(scan)) == 0


def test_legs_of_different_people_are_not_paired() -> None:
    legs = LegFeatures(np.array([[1.0, 0.0], [1.0, 0.2], [3.0, 0.0]]), np.full(3, 0.1), np.full(3, 0.9))
    persons = group_legs(legs)
    assert len(persons) == 2
    assert sorted((persons.members >= 0).sum(axis=1).tolist()) == [1, 2]
    np.testing.assert_allclose(persons.probability[0], 1.0 - 0.1 * 0.1)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**16), beams=st.integers(2, 200), holes=st.floats(0.0, 0.5))
def test_kernel_matches_reference(seed: int, beams: int, holes: float) -> None:
    rng = np.random.default_rng(seed)
    # Piecewise-constant ranges with small noise: segments of many widths, some leg-like.
    r = np.repeat(rng.uniform(0.5, 10.0, beams // 3 + 1), 3)[:beams] + rng.normal(0.0, 0.01, beams)
    valid = rng.uniform(size=beams) >= holes
    angles = np.linspace(-np.pi / 2, np.pi / 2, beams)
    cfg = LegConfig()
    for a, b in zip(
        leg_segments(r, angles, valid, cfg), leg_segments_reference(r, angles, valid, cfg), strict=True
    ):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)


def test_a_leg_partly_behind_the_other_is_still_a_leg() -> None:
    # Seen from the origin the near leg hides part of the far one: the far leg's segment has a
    # nearer neighbour on one side (an occluder, not a surface it belongs to) and the wall behind.
    scan = scan_with_circles(0.0, (0.0, 0.0, 0.0), [(2.0, 0.0, 0.06), (2.25, 0.08, 0.06)])
    legs = detect_legs(scan)
    assert len(legs) == 2
    assert np.all(legs.probability > 0.5)


def test_a_bump_on_a_wall_is_not_a_leg() -> None:
    # A 10 cm bump 5 cm proud of a wall: narrow, but no jump to either side.
    circles = [(3.0, y, 0.06) for y in np.arange(-2.0, 2.0, 0.02)] + [(2.95, 0.0, 0.06)]
    legs = detect_legs(scan_with_circles(0.0, (0.0, 0.0, 0.0), circles))
    assert len(legs) == 0
