"""The object state estimator on a door seen from a robot in a room (the simulator's geometry)."""

from __future__ import annotations

import math

import numpy as np

from tests.objects.conftest import make_scan
from tourbot.maps.objects import door_shape, segment_ranges
from tourbot.maps.raycast import DDACaster
from tourbot.objects.estimator import ObjectEstimatorConfig, ObjectStateEstimator, Observation
from tourbot.site.model import Site


def _run(
    room: Site,
    angle: float,
    steps: int = 20,
    blockers: np.ndarray | None = None,
    seed: int = 0,
    start: float = 0.0,
    est: ObjectStateEstimator | None = None,
    t0: float = 0.0,
) -> ObjectStateEstimator:
    shape = door_shape(room.doors[0])
    rng = np.random.default_rng(seed)
    if est is None:
        est = ObjectStateEstimator([shape], DDACaster(room.grid, 10.0), seed=seed)
    for k in range(steps):
        pose = (2.0 + 0.05 * k + start, 2.0, 1.2)
        scan = make_scan(room, [shape], [np.array([angle])], pose, t0 + 0.2 * k, rng, blockers)
        samples = np.asarray(pose)[None] + rng.normal(0, [0.01, 0.01, 0.002], (50, 3))
        est.update(scan, samples, np.full(50, 1 / 50))
    return est


def test_a_door_is_found_at_its_angle(room: Site) -> None:
    for angle in (0.0, math.radians(35.0), math.radians(80.0)):
        est = _run(room, angle).estimates()[0]
        assert est.quality.status == Observation.OBSERVED
        assert abs(est.state[0] - angle) < math.radians(2.0), (angle, est)


def test_a_door_changed_while_away_is_found_again(room: Site) -> None:
    est = _run(room, 0.0)
    assert abs(est.estimates()[0].state[0]) < math.radians(2.0)
    # ten minutes later the door is open: the jump prior spreads the samples over the range again
    est = _run(room, math.radians(70.0), est=est, t0=600.0)
    assert abs(est.estimates()[0].state[0] - math.radians(70.0)) < math.radians(3.0)


def test_a_door_behind_a_crowd_is_reported_occluded_not_found(room: Site) -> None:
    # a wall of visitors between the robot and the doorway, 1 m in front of it
    blockers = np.array([[[2.2, 3.0, 4.4, 3.0]]])
    est = _run(room, math.radians(45.0), blockers=blockers).estimates()[0]
    assert est.quality.poor
    assert est.quality.status == Observation.OCCLUDED


def test_the_estimate_integrates_over_the_pose_samples(room: Site) -> None:
    """With the belief spread over the pose, the door's estimate is less certain (Eq. 8)."""
    shape = door_shape(room.doors[0])
    caster = DDACaster(room.grid, 10.0)
    rng = np.random.default_rng(1)
    pose = (2.5, 2.0, 1.2)
    scan = make_scan(room, [shape], [np.array([math.radians(40.0)])], pose, 0.0, rng)
    spreads = []
    for std in (0.005, 0.15):
        est = ObjectStateEstimator([shape], caster, ObjectEstimatorConfig(pose_samples=50), seed=3)
        samples = np.asarray(pose)[None] + np.random.default_rng(2).normal(0, [std, std, std / 3], (200, 3))
        est.update(scan, samples, np.full(200, 1 / 200))
        spreads.append(est.estimates()[0].std[0])
    assert spreads[1] > spreads[0]


def test_only_objects_within_reach_are_updated(room: Site) -> None:
    shape = door_shape(room.doors[0])
    est = ObjectStateEstimator([shape], DDACaster(room.grid, 10.0), ObjectEstimatorConfig(max_distance=1.0))
    rng = np.random.default_rng(0)
    scan = make_scan(room, [shape], [np.array([0.3])], (1.0, 1.0, 0.0), 0.0, rng)
    assert est.update(scan, np.array([[1.0, 1.0, 0.0]]), np.ones(1)) == []
    assert est.estimates()[0].quality.status == Observation.UNSEEN


def test_scan_helper_sees_the_leaf(room: Site) -> None:
    shape = door_shape(room.doors[0])
    base = np.full((1, 1), 10.0)
    r = segment_ranges(
        np.array([[3.45, 2.0, math.pi / 2]]), np.array([0.0]), shape.segments(np.zeros((1, 1))), base
    )
    assert abs(float(r[0, 0, 0]) - (3.975 - 0.02 - 2.0)) < 1e-4


def test_a_desk_seen_on_one_face_only_is_not_pinned_down() -> None:
    from tourbot.maps.objects import furniture_shape
    from tourbot.objects.estimator import ObjectBelief
    from tourbot.site.model import Furniture

    desk = furniture_shape(
        Furniture(
            name="desk",
            outline=[(-0.7, -0.35), (0.7, -0.35), (0.7, 0.35), (-0.7, 0.35)],
            poses=[(0.0, 2.0, 0.0)],
        )
    )
    belief = ObjectBelief(desk, ObjectEstimatorConfig(), np.random.default_rng(0))
    state = np.array([0.0, 2.0, 0.0])
    angles = np.radians(np.arange(-90.0, 90.5, 1.0))

    def readings(laser: np.ndarray) -> np.ndarray:
        base = np.full((1, angles.size), 8.0)
        return segment_ranges(laser[None], angles, desk.segments(state[None]), base)[0, 0].astype(np.float64)

    front = np.array([0.0, 0.0, math.pi / 2])  # straight in front: only the south face
    z = readings(front)
    assert not belief._constrained(front, angles, z, state, np.full(angles.size, 8.0))
    corner = np.array([1.6, 0.6, 2.0])  # from the side: the south and the east face
    z = readings(corner)
    assert belief._constrained(corner, angles, z, state, np.full(angles.size, 8.0))


def test_a_converged_door_in_plain_view_stays_observed(room: Site) -> None:
    """Once the samples agree (no jump drawn: none of them tells a beam apart from the others), the
    beams on the leaf still discriminate its range: the estimate stays observed, not few-beams."""
    from dataclasses import replace

    est = _run(room, math.radians(35.0))
    assert est.estimates()[0].quality.status == Observation.OBSERVED
    belief = est.beliefs[0]
    belief.config = replace(belief.config, jump_min=0.0)  # no jump in the next prediction
    belief.samples = np.full_like(belief.samples, math.radians(35.0))
    est = _run(room, math.radians(35.0), steps=1, est=est, t0=3.85, start=1.0)  # the next scan, 50 ms on
    e = est.estimates()[0]
    assert e.quality.status == Observation.OBSERVED, e.quality
    assert e.quality.beams >= 5
    assert abs(e.state[0] - math.radians(35.0)) < math.radians(1.0)
