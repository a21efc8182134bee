from __future__ import annotations

import numpy as np

from tests.people.scenes import legs_of, scan_with_circles
from tourbot.interfaces import Estimator, PoseBelief
from tourbot.people.estimator import PeopleEstimator
from tourbot.snapshot import PoseEstimate


def test_estimator_publishes_confirmed_people_in_the_world_frame() -> None:
    est = PeopleEstimator(rng=np.random.default_rng(0))
    assert isinstance(est, Estimator)
    robot = np.array([2.0, 1.0, 0.5])
    belief = PoseBelief(PoseEstimate(*robot), robot[None, :], np.ones(1))
    assert est.state().people == ()
    for k in range(15):
        t = 0.1 * k
        x = 4.0 + 0.8 * t
        est.on_scan(scan_with_circles(t, robot, legs_of(x, 3.0, 0.0, 6.0 * t)), belief)
    people = est.state().people
    assert people is not None
    assert len(people) == 1
    assert people[0].confirmed
    assert abs(people[0].x - (4.0 + 0.8 * 1.4)) < 0.15
    assert abs(people[0].y - 3.0) < 0.15


def test_positions_are_the_confirmed_visitors_moved_on_to_the_time_asked() -> None:
    est = PeopleEstimator(rng=np.random.default_rng(0))
    robot = np.array([2.0, 1.0, 0.5])
    belief = PoseBelief(PoseEstimate(*robot), robot[None, :], np.ones(1))
    assert est.positions().shape == (0, 2)
    for k in range(15):
        t = 0.1 * k
        est.on_scan(scan_with_circles(t, robot, legs_of(4.0 + 0.8 * t, 3.0, 0.0, 6.0 * t)), belief)
    (person,) = est.state().people or ()
    now = est.positions()
    np.testing.assert_allclose(now, [[person.x, person.y]])
    # half a second after the last scan (t = 1.4 s): moved on by the track's velocity, about 0.8 m/s in x
    later = est.positions(1.9)
    np.testing.assert_allclose(later, now + 0.5 * np.array([[person.vx, person.vy]]))
    assert abs(later[0, 0] - (4.0 + 0.8 * 1.9)) < 0.2
    np.testing.assert_allclose(est.positions(1.0), now)  # never moved back in time
