"""The dynamic objects' shapes and their sensor simulation, against the numpy reference."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.maps.grid import MapError
from tourbot.maps.objects import (
    ObjectIndex,
    ObjectShape,
    beam_window,
    distance_to_segments,
    door_shape,
    furniture_shape,
    segment_ranges,
    segment_ranges_reference,
)
from tourbot.site.model import Door, Furniture

SQUARE = [(-0.2, -0.2), (0.2, -0.2), (0.2, 0.2), (-0.2, 0.2)]


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 100_000),
    n=st.integers(1, 4),
    s=st.integers(1, 5),
    b=st.integers(1, 30),
)
def test_kernel_matches_the_reference(seed: int, n: int, s: int, b: int) -> None:
    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-2, 2, n), rng.uniform(-math.pi, math.pi, n)])
    angles = rng.uniform(-math.pi, math.pi, b)
    item = Furniture(
        name="u",
        outline=[
            (0, 0),
            (0.37, 0),
            (0.37, 0.37),
            (0.3, 0.37),
            (0.3, 0.07),
            (0.07, 0.07),
            (0.07, 0.37),
            (0, 0.37),
        ],
        poses=[(0, 0, 0)],
    )
    shape = furniture_shape(item)
    states = np.column_stack(
        [rng.uniform(-2, 2, s), rng.uniform(-2, 2, s), rng.uniform(-math.pi, math.pi, s)]
    )
    base = rng.uniform(0.5, 6.0, (n, b))
    segs = shape.segments(states)
    ref = segment_ranges_reference(poses, angles, segs, base)
    fast = segment_ranges(poses, angles, segs, base)
    assert fast.shape == (n, s, b)
    # float32 output; grazing beams may flip at an edge's end within rounding
    close = np.isclose(fast, ref, rtol=1e-5, atol=1e-5)
    assert close.mean() > 0.999


def test_a_beam_meets_a_closed_door_at_the_leaf() -> None:
    door = door_shape(Door(name="d", hinge=(2.0, -0.5), leaf_length=1.0, closed_direction=math.pi / 2))
    segs = door.segments(np.array([[0.0], [math.pi / 2]]))  # closed across the beam, open along x
    out = segment_ranges(np.zeros((1, 3)), np.array([0.0]), segs, np.full((1, 1), 10.0))
    assert out[0, 0, 0] == pytest.approx(2.0 - 0.025, abs=1e-6)  # the leaf's near face
    assert out[0, 1, 0] == pytest.approx(10.0)  # open: the beam passes by the leaf's end... the base


def test_the_base_range_wins_when_nearer() -> None:
    shape = furniture_shape(Furniture(name="f", outline=SQUARE, poses=[(3.0, 0.0, 0.0)]))
    out = segment_ranges(
        np.zeros((1, 3)), np.array([0.0]), shape.segments(np.array([[3.0, 0.0, 0.0]])), np.array([[1.5]])
    )
    assert out[0, 0, 0] == pytest.approx(1.5)


def test_beam_window_covers_the_beams_that_can_hit() -> None:
    shape = furniture_shape(Furniture(name="f", outline=SQUARE, poses=[(3.0, 0.0, 0.0)]))
    states = np.array([[3.0, 0.0, 0.0], [3.0, 0.3, 0.4]])
    inc = math.radians(1.0)
    window = beam_window(np.zeros((1, 3)), shape.boxes(states), -math.pi, inc, 360)
    angles = -math.pi + inc * np.arange(360)
    full = segment_ranges(np.zeros((1, 3)), angles, shape.segments(states), np.full((1, 360), 20.0))
    hit = np.flatnonzero((full[0] < 20.0).any(axis=0))
    assert set(hit) <= set(window.tolist())
    assert len(window) < 30  # a small part of the scan
    # behind the robot: the window wraps around the scan's ends
    back = beam_window(np.array([[0.0, 0.0, math.pi]]), shape.boxes(states), -math.pi, inc, 360)
    assert 0 in back.tolist() or 359 in back.tolist()


def test_index_finds_only_the_objects_near() -> None:
    shapes = [
        furniture_shape(Furniture(name=f"f{i}", outline=SQUARE, poses=[(4.0 * i, 0.0, 0.0)]), margin=0.1)
        for i in range(50)
    ]
    index = ObjectIndex(shapes, tile=2.0)
    assert index.near(40.0, 0.0, 1.0) == [10]
    assert index.near(42.0, 0.0, 3.0) == [10, 11]
    assert index.near(40.0, 50.0, 3.0) == []


def test_shapes_know_their_symmetry_and_refuse_impossible_outlines() -> None:
    assert furniture_shape(Furniture(name="sq", outline=SQUARE, poses=[(0, 0, 0)])).symmetry == 4
    desk = [(-0.8, -0.4), (0.8, -0.4), (0.8, 0.4), (-0.8, 0.4)]
    assert furniture_shape(Furniture(name="desk", outline=desk, poses=[(0, 0, 0)])).symmetry == 2
    with pytest.raises(MapError, match="crosses itself"):
        furniture_shape(Furniture(name="bow", outline=[(0, 0), (2, 2), (2, 0), (0, 1)], poses=[(0, 0, 0)]))
    with pytest.raises(MapError, match="no area"):
        furniture_shape(Furniture(name="flat", outline=[(0, 0), (1, 0), (2, 0)], poses=[(0, 0, 0)]))
    with pytest.raises(MapError, match="opening_angle"):
        door_shape(Door(name="d", hinge=(0, 0), leaf_length=1.0, closed_direction=0.0, opening_angle=4.0))


def test_distance_to_segments() -> None:
    segs = np.array([[0.0, 0.0, 1.0, 0.0]])
    assert distance_to_segments(0.5, 0.3, segs) == pytest.approx(0.3)
    assert distance_to_segments(2.0, 0.0, segs) == pytest.approx(1.0)
    assert distance_to_segments(0.0, 0.0, np.zeros((0, 4))) == math.inf


def test_door_frames_turn_about_the_hinge() -> None:
    shape = ObjectShape(
        "d",
        "door",
        np.array([[0, -0.01], [1, -0.01], [1, 0.01], [0, 0.01]]),
        hinge=(1.0, 2.0),
        closed_direction=0.0,
        low=0.0,
        high=math.pi / 2,
    )
    poly = shape.polygons(np.array([[math.pi / 2]]))[0]
    np.testing.assert_allclose(poly[1], [1.01, 3.0], atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 100_000), full=st.booleans())
def test_every_beam_that_can_hit_is_in_the_window(seed: int, full: bool) -> None:
    rng = np.random.default_rng(seed)
    shape = furniture_shape(Furniture(name="f", outline=SQUARE, poses=[(0.0, 0.0, 0.0)]))
    states = np.column_stack(
        [rng.uniform(-3, 3, 4), rng.uniform(-3, 3, 4), rng.uniform(-math.pi, math.pi, 4)]
    )
    poses = np.column_stack([rng.uniform(-4, 4, 3), rng.uniform(-4, 4, 3), rng.uniform(-math.pi, math.pi, 3)])
    nb = 360 if full else 181
    inc = math.radians(1.0)
    a0 = -math.pi if full else -math.pi / 2
    window = set(beam_window(poses, shape.boxes(states), a0, inc, nb).tolist())
    angles = a0 + inc * np.arange(nb)
    cast = segment_ranges(poses, angles, shape.segments(states), np.full((3, nb), 50.0))
    hit = np.flatnonzero((cast < 50.0).any(axis=(0, 1)))
    assert set(hit.tolist()) <= window
