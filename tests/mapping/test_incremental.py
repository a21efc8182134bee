from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.mapping.conftest import corridor_scan
from tourbot.mapping.incremental import (
    IncrementalMapper,
    MapperParams,
    MappingError,
    _apply_counts,
    _apply_counts_reference,
    _counted_cells,
    _counted_cells_reference,
    _stamp_cells,
    _stamp_cells_reference,
)
from tourbot.maps.grid import OccupancyGrid
from tourbot.metrics import relative_pose_error
from tourbot.records import LaserGeometry, RobotLog, Scan


def test_scan_matching_beats_odometry_on_a_synthetic_hall(hall: OccupancyGrid, hall_log: RobotLog) -> None:
    mapper = IncrementalMapper(start=hall_log.reference_poses[0])
    for scan in hall_log.scans:
        mapper.add_scan(scan)
    ref = hall_log.reference_poses
    slam = relative_pose_error(np.asarray(mapper.poses), ref)
    odom = relative_pose_error(hall_log.odom_poses, ref)
    assert slam.trans_mean < 0.5 * odom.trans_mean
    assert slam.rot_mean < 0.5 * odom.rot_mean
    # the map holds the hall's walls where they are
    grid = mapper.grid()
    walls = hall.cell_to_world(np.argwhere(hall.occupied()))
    cells = grid.world_to_cell(walls)
    seen = grid.inside(cells)
    hit = grid.occupied()[cells[seen, 0], cells[seen, 1]]
    assert hit.mean() > 0.3  # walls the robot saw are mostly mapped


def test_window_forgets_old_scans(hall_log: RobotLog) -> None:
    mapper = IncrementalMapper(MapperParams(window=5), start=hall_log.reference_poses[0])
    for scan in hall_log.scans[:12]:
        mapper.add_scan(scan)
    assert len(mapper._recent) == 5
    # the aligned-against counts are exactly those of the last five scans
    last5 = IncrementalMapper(MapperParams(window=None), start=hall_log.reference_poses[0])
    total = int(mapper._near_hits.sum())
    for scan, pose in zip(hall_log.scans[7:12], mapper.poses[7:12], strict=True):
        last5.integrate(scan, np.asarray(pose))
    assert total == int(last5._hits.sum())
    assert mapper._near_hits.min() >= 0
    assert mapper._near_misses.min() >= 0


def test_grid_grows_to_fit(hall_log: RobotLog) -> None:
    mapper = IncrementalMapper(MapperParams(initial_size=4.0), start=hall_log.reference_poses[0])
    for scan in hall_log.scans[:5]:
        mapper.add_scan(scan)
    grid = mapper.grid()
    assert grid.width > 15.0


def test_scan_without_odometry_is_an_error() -> None:
    geom = LaserGeometry(3, -0.1, 0.1, 10.0)
    with pytest.raises(MappingError, match="odometry"):
        IncrementalMapper().add_scan(Scan(0.0, np.ones(3), geom))


@pytest.mark.slow
def test_real_intel_log_start(shared_data: object) -> None:
    from pathlib import Path

    from tourbot.io.carmen import read_carmen

    assert isinstance(shared_data, Path)
    log = read_carmen(shared_data / "carmen" / "intel-corrected.log.gz")
    scans = log.scans[:150]
    mapper = IncrementalMapper(start=log.reference_poses[0])
    for scan in scans:
        mapper.add_scan(scan)
    ref = log.reference_poses[:150]
    slam = relative_pose_error(np.asarray(mapper.poses), ref)
    odom = relative_pose_error(log.odom_poses[:150], ref)
    assert slam.trans_mean < odom.trans_mean
    assert slam.rot_mean < 0.5 * odom.rot_mean


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(0, 30), radius=st.integers(0, 5))
def test_stamp_kernel_matches_numpy_reference(seed: int, n: int, radius: int) -> None:
    rng = np.random.default_rng(seed)
    field = rng.random((20, 25))
    rows = rng.integers(0, 20, n)
    cols = rng.integers(0, 25, n)
    weights = rng.normal(size=n)
    stamp = rng.random((2 * radius + 1, 2 * radius + 1))
    fast, slow = field.copy(), field.copy()
    _stamp_cells(fast, rows, cols, weights, stamp)
    _stamp_cells_reference(slow, rows, cols, weights, stamp)
    assert np.allclose(fast, slow)


def test_fields_after_forgetting_equal_fields_built_afresh(hall_log: RobotLog) -> None:
    """Stamping changes incrementally (adding and forgetting scans) gives the fields of the final map."""
    start = hall_log.reference_poses[0]
    mapper = IncrementalMapper(MapperParams(window=4), start=start)
    for scan in hall_log.scans[:10]:
        mapper.add_scan(scan)
    fresh = IncrementalMapper(MapperParams(window=None), start=start)
    fresh._centre_on(start)
    assert (fresh._x0, fresh._y0) == (mapper._x0, mapper._y0)
    rr, cc = np.nonzero((mapper._near_hits != 0) | (mapper._near_misses != 0))
    fresh._change(rr, cc, mapper._near_hits[rr, cc], mapper._near_misses[rr, cc])
    for a, b in zip(mapper._fields, fresh._fields, strict=True):
        assert np.allclose(a, b, atol=1e-9)


def test_a_wall_reads_one_and_unexplored_space_its_level() -> None:
    params = MapperParams(window=None)
    mapper = IncrementalMapper(params, start=np.zeros(3))
    mapper._centre_on(np.zeros(3))
    n = mapper._hits.shape[0]
    rows = np.arange(n // 4, 3 * n // 4)
    cols = np.full(len(rows), n // 2)
    ones = np.ones(len(rows), np.int32)
    # free space on the left of the wall, the wall, unexplored on the right
    free_r, free_c = np.meshgrid(np.arange(n // 4, 3 * n // 4), np.arange(n // 4, n // 2), indexing="ij")
    mapper._change(
        free_r.ravel(), free_c.ravel(), np.zeros(free_r.size, np.int32), np.ones(free_r.size, np.int32)
    )
    mapper._change(rows, cols, 5 * ones, 0 * ones)
    for field, factor in zip(mapper._fields, mapper._factors, strict=True):
        mid = n // 2 // factor
        assert field[mid, mid] == pytest.approx(1.0, abs=0.15)  # on the wall
        assert field[mid, (n // 4 + 8) // factor + 6] == pytest.approx(0.0, abs=0.05)  # free space
        assert field[mid, -3] == pytest.approx(params.unknown_level, abs=1e-6)  # never seen


def _three_beams_the_middle_one_free_only() -> tuple[IncrementalMapper, IncrementalMapper]:
    """One scan of three beams ending 2 m ahead, written whole and with its middle beam free-only
    (a person's beam)."""
    geom = LaserGeometry(3, -0.1, 0.1, 30.0)
    scan = Scan(0.0, np.array([2.0, 2.0, 2.0]), geom, odom=(0.0, 0.0, 0.0))
    both = IncrementalMapper(start=np.zeros(3))
    both.integrate(scan, np.zeros(3))
    person = IncrementalMapper(start=np.zeros(3))
    person.integrate(scan, np.zeros(3), free_only=np.array([False, True, False]))
    return both, person


def test_free_only_beams_clear_space_but_leave_no_obstacle() -> None:
    both, person = _three_beams_the_middle_one_free_only()
    ahead = np.array([[1.0, 0.0], [2.0, 0.0]])  # in front of the middle beam's end, and its end
    plain, cut = both.evidence(ahead), person.evidence(ahead)
    assert cut[0] == plain[0] < 0  # the space in front of the person is free as before
    assert plain[1] > 0  # the person's cell is no obstacle
    assert cut[1] == 0


def test_extra_hits_go_into_the_returned_grid_only() -> None:
    """A free-only beam's end given back as an extra hit makes the grid what writing the beam whole
    gives there; the map itself keeps its counts."""
    both, person = _three_beams_the_middle_one_free_only()
    end = np.array([[2.0, 0.0]])
    cell = tuple(person.grid().world_to_cell(end)[0])
    back = person.grid(extra_hits=end)
    assert not person.grid().occupied()[cell]
    assert back.occupied()[cell]
    assert back.prob[cell] == pytest.approx(both.grid().prob[cell])
    assert person.evidence(end)[0] == 0  # the map itself is unchanged
    far = person.grid(extra_hits=np.array([[500.0, 500.0]]))  # outside the map: ignored
    assert np.array_equal(far.prob, person.grid().prob)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), fill=st.floats(0.0, 1.0))
def test_counted_cells_kernel_matches_numpy_reference(seed: int, fill: float) -> None:
    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(1, 30)), int(rng.integers(1, 30)))
    hits = np.where(rng.random(shape) < fill, rng.integers(-2, 4, shape), 0).astype(np.int32)
    misses = np.where(rng.random(shape) < fill, rng.integers(-2, 4, shape), 0).astype(np.int32)
    fast = _counted_cells(hits, misses)
    slow = _counted_cells_reference(hits, misses)
    for k in range(4):
        assert np.array_equal(fast[k], slow[k])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(0, 60))
def test_apply_counts_kernel_matches_numpy_reference(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    hits = rng.integers(0, 4, (12, 9)).astype(np.int32)
    misses = rng.integers(0, 6, (12, 9)).astype(np.int32)
    flat = rng.choice(hits.size, size=min(n, hits.size), replace=False)
    rows, cols = np.divmod(flat, hits.shape[1])
    d_hits = rng.integers(-1, 3, len(flat)).astype(np.int32)
    d_misses = rng.integers(-1, 3, len(flat)).astype(np.int32)
    d_hits = np.maximum(d_hits, -hits[rows, cols])  # counts never go below zero
    d_misses = np.maximum(d_misses, -misses[rows, cols])
    fast_h, fast_m, slow_h, slow_m = hits.copy(), misses.copy(), hits.copy(), misses.copy()
    cells = MapperParams().cells
    fast = _apply_counts(fast_h, fast_m, rows, cols, d_hits, d_misses, cells.l_occ, cells.l_free)
    slow = _apply_counts_reference(slow_h, slow_m, rows, cols, d_hits, d_misses, cells.l_occ, cells.l_free)
    assert np.array_equal(fast_h, slow_h)
    assert np.array_equal(fast_m, slow_m)
    for a, b in zip(fast, slow, strict=True):
        assert np.array_equal(a, b)


def test_level_halvings_must_match_the_smoothing_levels() -> None:
    with pytest.raises(MappingError, match="level_halvings"):
        MapperParams(smoothing=(0.2, 0.05), level_halvings=(3, 3, 5))


def test_integrate_into_one_map_only(hall_log: RobotLog) -> None:
    """The returned map and the map scans are aligned against can be written separately."""
    scan, pose = hall_log.scans[0], hall_log.reference_poses[0]
    only_map = IncrementalMapper(start=pose)
    only_map.integrate(scan, pose, into="map")
    only_alignment = IncrementalMapper(start=pose)
    only_alignment.integrate(scan, pose, into="alignment")
    both = IncrementalMapper(start=pose)
    both.integrate(scan, pose)
    assert np.array_equal(only_map._hits, both._hits)
    assert not only_map._near_hits.any()
    assert np.array_equal(only_alignment._near_hits, both._near_hits)
    assert not only_alignment._hits.any()
    for a, b in zip(only_alignment._fields, both._fields, strict=True):
        assert np.array_equal(a, b)


def test_matching_a_scans_endpoints_is_matching_the_scan(hall_log: RobotLog) -> None:
    import copy

    mapper = IncrementalMapper(start=hall_log.reference_poses[0])
    for scan in hall_log.scans[:6]:
        mapper.add_scan(scan)
    scan = hall_log.scans[6]
    assert scan.odom is not None
    twin = copy.deepcopy(mapper)
    by_scan = mapper.match(scan)
    points, weights = twin._matched_beams(scan, None)
    by_points = twin.match_points(points, weights, np.asarray(scan.odom))
    assert by_points.pose == by_scan.pose
    assert by_points.score == by_scan.score


def test_a_climb_again_from_the_prediction_never_fits_worse(hall_log: RobotLog) -> None:
    import copy
    import dataclasses

    mapper = IncrementalMapper(start=hall_log.reference_poses[0])
    for scan in hall_log.scans[:8]:
        mapper.add_scan(scan)
    for scan in hall_log.scans[8:14]:
        plain = copy.deepcopy(mapper)
        again = copy.deepcopy(mapper)
        again.params = dataclasses.replace(mapper.params, prior_restart=1)
        a = plain.match(scan)
        b = again.match(scan)
        # the same climb is made first; the restart is kept only when it fits the finest map better
        assert b.score >= a.score
        mapper.add_scan(scan)


def _covariance_axes(information: np.ndarray) -> tuple[np.ndarray, float]:
    """The direction (x, y) of the covariance's longest axis and how much longer it is."""
    values, vectors = np.linalg.eigh(np.linalg.inv(information)[:2, :2])
    return vectors[:, 1], float(np.sqrt(values[1] / values[0]))


@pytest.mark.parametrize("heading", [0.0, np.pi / 2])
def test_a_corridor_match_is_uncertain_along_the_corridor(heading: float) -> None:
    """Two scans 0.5 m apart in a featureless corridor, the odometry 10 % short: the match's
    covariance is long along the corridor (where only the odometry says how far the robot
    went) and short across it; with the corridor's end in sight, it is not."""
    along = np.array([np.cos(heading), np.sin(heading)])
    moved = (0.45 * float(along[0]), 0.45 * float(along[1]), heading)
    mapper = IncrementalMapper(start=np.array([0.0, 0.0, heading]))
    mapper.add_scan(corridor_scan((0.0, 0.0, heading)))
    step = mapper.add_scan(corridor_scan(moved))
    axis, ratio = _covariance_axes(step.information)
    assert abs(float(axis @ along)) > 0.99
    assert ratio > 4.0
    closed = IncrementalMapper(start=np.array([0.0, 0.0, heading]))
    closed.add_scan(corridor_scan((0.0, 0.0, heading), end=4.0))
    step = closed.add_scan(corridor_scan(moved, end=3.5))
    _, ratio_closed = _covariance_axes(step.information)
    assert ratio_closed < 0.5 * ratio
    # and the end wall put it at 0.5 m, not the odometry's 0.45 (within a map cell)
    assert abs(float(np.asarray(step.pose[:2]) @ along) - 0.5) < 0.04
