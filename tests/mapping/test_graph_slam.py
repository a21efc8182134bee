from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from tests.mapping.conftest import corridor_scan
from tourbot.geometry import compose, relative
from tourbot.mapping.graph_slam import Closure, GraphSlam
from tourbot.mapping.people_filter import PeopleFilteredMapper
from tourbot.metrics.relative import aligned_trajectory_error, relation_error, sample_pairs
from tourbot.records import RobotLog


@pytest.fixture(scope="module")
def intel_start(shared_data: Path) -> tuple[RobotLog, GraphSlam]:
    """Graph SLAM over Intel's first 200 scans (a loop round the first rooms), rebuilt odometry."""
    from tourbot.io.carmen import read_carmen

    path = shared_data / "carmen" / "intel-corrected.log.gz"
    log = read_carmen(path)  # odometry rebuilt from the increments (the reader's default)
    log.scans = log.scans[:200]
    slam = GraphSlam(start=log.reference_poses[0])
    for scan in log.scans:
        slam.add_scan(scan)
    slam.finish()
    return log, slam


def test_loops_close_on_intel_and_every_closure_is_true(intel_start: tuple[RobotLog, GraphSlam]) -> None:
    log, slam = intel_start
    ref = log.reference_poses
    assert len(slam.closures) >= 5
    for c in slam.closures:
        err = relative(relative(ref[c.anchor], ref[c.node]), np.asarray(c.delta))
        assert np.hypot(err[0], err[1]) < 0.3
        assert abs(err[2]) < np.radians(3)
    pairs = sample_pairs(ref)["revisit"]
    graph = relation_error(slam.poses, ref, pairs).trans_mean
    front = relation_error(np.asarray(slam.front.poses), ref, pairs).trans_mean
    assert graph < front + 0.02
    assert len(slam.poses) == 200


def _nearest_before(ref: np.ndarray, node: int, back: int) -> int:
    """The node at least ``back`` scans before ``node`` nearest to it in the reference."""
    d = np.hypot(*(ref[: node - back, :2] - ref[node, :2]).T)
    return int(np.argmin(d))


def test_a_lone_match_waits_for_one_that_agrees(intel_start: tuple[RobotLog, GraphSlam]) -> None:
    log, fixture = intel_start
    slam = copy.deepcopy(fixture)
    slam.closures.clear()  # no accepted closure of this pass to agree with
    slam._pending.clear()
    ref = log.reference_poses
    before = 0
    first, second = 180, 186
    a1, a2 = _nearest_before(ref, first, 60), _nearest_before(ref, second, 60)
    assert not slam.propose_closure(a1, first, relative(ref[a1], ref[first]), 0.9)
    assert len(slam.closures) == before  # waiting
    assert slam.propose_closure(a2, second, relative(ref[a2], ref[second]), 0.9)
    assert {(c.anchor, c.node) for c in slam.closures[before:]} == {(a1, first), (a2, second)}


def test_aliased_matches_that_disagree_are_never_accepted(intel_start: tuple[RobotLog, GraphSlam]) -> None:
    """Corridor aliasing (ACES, FR079): each scan matched a few metres along the corridor, by an
    offset that changes from scan to scan; no two agree, none is accepted."""
    log, fixture = intel_start
    slam = copy.deepcopy(fixture)
    slam.closures.clear()  # none of this pass to contradict: the matches only disagree among themselves
    slam._pending.clear()
    ref = log.reference_poses
    before = 0
    for k, (node, shift) in enumerate(
        zip(range(170, 200, 3), [1.0, 2.5, 4.0, 1.7, 3.2, 0.8, 2.1, 3.9, 1.3, 2.8], strict=True)
    ):
        a = _nearest_before(ref, node, 60)
        delta = compose(relative(ref[a], ref[node]), np.array([shift * (-1) ** k, 0.0, 0.0]))
        assert not slam.propose_closure(a, node, delta, 0.9)
    assert len(slam.closures) == before
    assert slam.rejected == fixture.rejected  # never even tried on the graph
    # with the pass's true closures known, each is refused at once as contradicting them
    slam = copy.deepcopy(fixture)
    node = 190
    a = _nearest_before(ref, node, 60)
    slam.propose_closure(a, node, relative(ref[a], ref[node]), 0.9)
    count = slam.contradicted
    bad = compose(relative(ref[a], ref[node + 3]), np.array([2.0, 0.0, 0.0]))
    assert not slam.propose_closure(a, node + 3, bad, 0.9)
    assert slam.contradicted == count + 1


def test_a_false_group_is_rejected_or_survived(intel_start: tuple[RobotLog, GraphSlam]) -> None:
    """A twin place: two matches that agree with each other and are both 5 m off. The graph's
    consistency check refuses them; forced in with the robust kernel, the map survives."""
    log, fixture = intel_start
    slam = copy.deepcopy(fixture)
    ref = log.reference_poses
    before = aligned_trajectory_error(slam.poses, ref).rmse
    shift = np.array([5.0, 0.0, 0.0])
    group = [
        Closure(10, node, tuple(compose(relative(ref[10], ref[node]), shift)), 0.9) for node in (150, 153)
    ]
    assert slam._agree(group[0], group[1])  # they agree with each other
    assert not slam.add_closures(group)
    assert aligned_trajectory_error(slam.poses, ref).rmse == pytest.approx(before, abs=1e-6)
    info = np.diag([100.0, 100.0, 2500.0])
    for c in group:
        slam.graph.add_edge(c.anchor, c.node, np.asarray(c.delta), info, robust=True)
    assert aligned_trajectory_error(slam.graph.optimize(), ref).rmse < before + 0.05


def test_poorly_fitted_scans_stay_out_of_the_submaps(intel_start: tuple[RobotLog, GraphSlam]) -> None:
    """A scan the front end fitted poorly may sit askew (FHW scans 57-60: 7-25 deg off); matches to
    its walls, or edges from its pose, were false closures."""
    _, fixture = intel_start
    slam = copy.deepcopy(fixture)
    full = slam._build_submap(0, 29)
    slam._quality[5:20] = [slam.params.submap_quality + 1.0] * 15
    part = slam._build_submap(0, 29)
    assert 0 < int((part.grid.grid == 1.0).sum()) < int((full.grid.grid == 1.0).sum())


def test_the_people_filter_stays_in_the_pipeline(hall_log: RobotLog) -> None:
    people = PeopleFilteredMapper.create(start=hall_log.reference_poses[0], seed=0)
    slam = GraphSlam(people=people)
    for scan in hall_log.scans:
        slam.add_scan(scan)
    poses = slam.finish()
    assert len(poses) == len(hall_log)
    assert len(people.left_out) == len(hall_log)
    assert slam.grid().occupied().sum() > 100
    odom = aligned_trajectory_error(hall_log.odom_poses, hall_log.reference_poses).rmse
    assert aligned_trajectory_error(poses, hall_log.reference_poses).rmse < odom


def test_online_poses_are_available_while_mapping(real_log: Callable[[str], RobotLog]) -> None:
    log = real_log("aces")
    slam = GraphSlam()
    for k, scan in enumerate(log.scans[:20]):
        pose = slam.add_scan(scan)
        assert pose.shape == (3,)
        assert len(slam.poses) == k + 1


@pytest.mark.parametrize("heading", [0.0, np.pi / 2])
def test_a_corridor_edge_is_loose_along_the_corridor(heading: float) -> None:
    """The scan-matching edge carries the match's covariance in the edge's own frame: in a
    featureless corridor, long along the robot's heading whichever way the corridor runs."""
    slam = GraphSlam(start=np.array([0.0, 0.0, heading]))
    slam.add_scan(corridor_scan((0.0, 0.0, heading)))
    slam.add_scan(corridor_scan((0.45 * np.cos(heading), 0.45 * np.sin(heading), heading)))
    (edge,) = slam.graph.edges
    values, vectors = np.linalg.eigh(np.linalg.inv(edge.information)[:2, :2])
    assert abs(vectors[0, 1]) > 0.99  # the longest axis is the edge frame's x: along the corridor
    assert np.sqrt(values[1] / values[0]) > 4.0


def test_a_step_that_jumps_away_from_the_odometry_is_no_edge(real_log: Callable[[str], RobotLog]) -> None:
    """ACES scan 243: back in a corridor it mapped long before, the front end snaps the scan
    onto that drifted old map, 0.97 m short of where the reference and the odometry (0.09 m off)
    put it. The graph's edge there is the odometry's: such a step is an implicit loop closure,
    not a motion, and as a scan-matching edge it held the graph 1 m short."""
    log = real_log("aces")
    ref = log.reference_poses
    slam = GraphSlam(start=ref[0])
    for scan in log.scans[:244]:
        slam.add_scan(scan)
    front = np.asarray(slam.front.poses)
    truth = relative(ref[242], ref[243])
    assert np.hypot(*(relative(front[242], front[243]) - truth)[:2]) > 0.5
    (edge,) = [e for e in slam.graph.edges if (e.i, e.j) == (242, 243)]
    odo = relative(log.odom_poses[242], log.odom_poses[243])
    assert np.allclose(edge.delta, odo)
    assert np.hypot(*(odo - truth)[:2]) < 0.15
    # the steps that agree with the odometry stay scan-matching edges
    assert 0 < slam.jumps <= 10
