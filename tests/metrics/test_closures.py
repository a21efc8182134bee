from __future__ import annotations

import numpy as np
import pytest

from tourbot.geometry import compose, invert, relative, transform_points
from tourbot.metrics.closures import audit_closures, off_reference, overlap


def _room() -> np.ndarray:
    """The walls of a 6 x 4 m room with a 2 m partition, sampled every 2 cm (world frame)."""
    t = np.arange(0.0, 1.0, 0.02 / 6.0)
    walls = [((0, 0), (6, 0)), ((6, 0), (6, 4)), ((6, 4), (0, 4)), ((0, 4), (0, 0)), ((3, 0), (3, 2))]
    return np.concatenate([np.c_[a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])] for a, b in walls])


def _seen_from(pose: np.ndarray, world: np.ndarray) -> np.ndarray:
    return transform_points(invert(pose), world)


TRUE = np.array([[1.5, 1.0, 0.2], [4.5, 2.5, 2.0]])


def test_a_closure_within_the_tolerance_is_not_off_the_reference() -> None:
    delta = relative(TRUE[0], TRUE[1]) + np.array([0.2, -0.1, np.radians(2.0)])
    far = relative(TRUE[0], TRUE[1]) + np.array([0.0, 0.0, np.radians(4.0)])
    assert off_reference([(0, 1, delta), (0, 1, far)], TRUE).tolist() == [False, True]


def test_overlap_is_full_at_the_true_relative_pose_and_drops_when_turned() -> None:
    world = _room()
    a, b = _seen_from(TRUE[0], world), _seen_from(TRUE[1], world)
    true = relative(TRUE[0], TRUE[1])
    assert overlap(a, b, true) == pytest.approx(1.0)
    assert overlap(a, b, compose(true, np.array([0.0, 0.0, np.radians(3.5)]))) < 0.5
    assert overlap(a, np.zeros((0, 2)), true) == 0.0


def test_the_scans_side_with_a_right_closure_against_a_wrong_reference() -> None:
    world = _room()
    points = [_seen_from(TRUE[0], world), _seen_from(TRUE[1], world)]
    wrong_ref = TRUE.copy()
    wrong_ref[1] = compose(TRUE[1], np.array([0.05, 0.0, np.radians(3.5)]))
    right = relative(TRUE[0], TRUE[1])
    audit = audit_closures([(0, 1, right)], wrong_ref, points)
    assert (audit.accepted, audit.off_reference, audit.scans_side_with_closure) == (1, 1, 1)
    # the other way round: the reference right, the closure 3.5 degrees off
    wrong = compose(right, np.array([0.05, 0.0, np.radians(3.5)]))
    audit = audit_closures([(0, 1, wrong)], TRUE, points)
    assert (audit.accepted, audit.off_reference, audit.scans_side_with_closure) == (1, 1, 0)
