from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.navigation.avoidance import DWAConfig, DynamicWindow, arc_clearance, arc_clearance_reference


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 20), p=st.integers(0, 30))
def test_arc_clearance_matches_reference(seed: int, n: int, p: int) -> None:
    rng = np.random.default_rng(seed)
    v = rng.uniform(0.0, 0.8, n)
    w = rng.uniform(-1.5, 1.5, n)
    w[rng.random(n) < 0.3] = 0.0
    pts = rng.uniform(-3.0, 3.0, (p, 2))
    c1, a1 = arc_clearance(v, w, pts, 2.0, 10)
    c2, a2 = arc_clearance_reference(v, w, pts, 2.0, 10)
    np.testing.assert_allclose(c1, c2, rtol=1e-9)
    np.testing.assert_allclose(a1, a2, rtol=1e-9)


def _window() -> DynamicWindow:
    return DynamicWindow(
        DWAConfig(), radius=0.3, max_speed=0.6, max_turn_rate=1.2, max_accel=0.6, max_turn_accel=2.0
    )


def test_free_space_drives_to_the_carrot() -> None:
    v, w, moving = _window().choose(0.5, 0.0, (1.0, 0.0), np.zeros((0, 2)))
    assert moving
    assert v > 0.4
    assert abs(w) < 0.2


def test_a_person_ahead_is_avoided_not_hit() -> None:
    legs = np.array([[0.8, 0.05], [0.8, -0.05]])
    v, w, moving = _window().choose(0.5, 0.0, (2.0, 0.0), legs)
    assert moving
    assert abs(w) > 0.1  # swerves
    c, _ = arc_clearance(np.array([v]), np.array([w]), legs, 2.0, 10)
    assert c[0] > 0.3


def test_surrounded_robot_is_blocked() -> None:
    ang = np.linspace(-np.pi, np.pi, 24, endpoint=False)
    ring = 0.45 * np.stack([np.cos(ang), np.sin(ang)], axis=-1)
    v, _, moving = _window().choose(0.0, 0.0, (2.0, 0.0), ring)
    assert not moving
    assert v == 0.0


def _wall(y: float) -> np.ndarray:
    """A wall along the robot's heading, ``y`` m to its side, 5 cm between points."""
    x = np.arange(-2.0, 3.0, 0.05)
    return np.stack([x, np.full_like(x, y)], axis=-1)


def test_a_robot_inside_its_margin_drives_along_the_wall() -> None:
    # 0.37 m from a wall: inside radius 0.3 + margin 0.08. The robot used to stop for good there
    # (every arc, the spin on the spot too, counted as too close): seen at a corridor's corner.
    v, w, moving = _window().choose(0.0, 0.0, (2.0, 0.0), _wall(-0.37))
    assert moving
    assert v > 0.0
    c, _ = arc_clearance(np.array([v]), np.array([w]), _wall(-0.37), 2.0, 8)
    assert c[0] >= 0.37 - DWAConfig().squeeze - 1e-9  # comes no closer than it stood


def test_a_robot_inside_its_margin_does_not_turn_into_the_wall() -> None:
    # the carrot behind the wall: no arc toward it is admissible, the robot stays where it is
    v, w, moving = _window().choose(0.0, 0.0, (0.5, -2.0), _wall(-0.37))
    if moving:
        c, _ = arc_clearance(np.array([v]), np.array([w]), _wall(-0.37), 2.0, 8)
        assert c[0] >= 0.37 - DWAConfig().squeeze - 1e-9
    far = _window().choose(0.0, 0.0, (0.5, -2.0), _wall(-0.60))
    assert far[2]  # with room beside it, it moves
