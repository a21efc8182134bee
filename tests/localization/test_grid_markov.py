"""Grid Markov localization on a synthetic room: tracking, global localization, kidnapping, filters."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.geometry import compose, relative, wrap_angle
from tourbot.localization.beam_filters import BeamFilter
from tourbot.localization.errors import LocalizationError
from tourbot.localization.grid_markov import (
    ExpectedRangeTable,
    GridMarkovConfig,
    GridMarkovError,
    GridMarkovLocalization,
    PoseLattice,
    layer_kernels,
)
from tourbot.localization.motion_model import OdometryMotionModel
from tourbot.localization.profile import FHW_PROFILE, LocalizationProfile
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.raycast import DistanceCaster
from tourbot.records import LaserGeometry, RobotLog, Scan

RES = 0.05
GEOMETRY = LaserGeometry(num_beams=180, angle_min=-math.pi / 2, angle_increment=math.pi / 180, max_range=20.0)


def _room() -> OccupancyGrid:
    """A 9 m x 6 m room with walls and a few asymmetric obstacles (so global localization is unique)."""
    h, w = int(6 / RES), int(9 / RES)
    p = np.zeros((h, w), np.float32)
    p[:2, :] = p[-2:, :] = p[:, :2] = p[:, -2:] = 1.0

    def box(x0: float, x1: float, y0: float, y1: float) -> None:
        p[int(y0 / RES) : int(y1 / RES), int(x0 / RES) : int(x1 / RES)] = 1.0

    box(2.0, 4.5, 2.0, 2.3)
    box(6.0, 6.3, 3.0, 6.0)
    box(7.2, 8.0, 1.0, 1.6)
    box(1.0, 1.6, 4.2, 5.0)
    return OccupancyGrid(p, RES, (-1.0, -0.5, 0.0))


@pytest.fixture(scope="module")
def room() -> OccupancyGrid:
    return _room()


@pytest.fixture(scope="module")
def caster(room: OccupancyGrid) -> DistanceCaster:
    return DistanceCaster(room, GEOMETRY.max_range)


def _scan(
    caster: DistanceCaster,
    pose: np.ndarray,
    t: float,
    rng: np.random.Generator,
    people: np.ndarray | None = None,
) -> Scan:
    if people is None:
        r = caster.cast(pose[None], GEOMETRY.angles)[0]
    else:
        r = caster.cast_with_circles(pose[None], GEOMETRY.angles, people, np.full(len(people), 0.2))[0]
    return Scan(t, r.astype(np.float64) + rng.normal(0.0, 0.02, r.shape), GEOMETRY)


def _path(start: tuple[float, float, float], steps: int, step: float = 0.25, turn: float = 0.0) -> np.ndarray:
    poses = [np.asarray(start, dtype=np.float64)]
    for _ in range(steps - 1):
        poses.append(compose(poses[-1], [step, 0.0, turn]))
    return np.array(poses)


def _odometry(truth: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Odometry with a few percent of error per step, starting from a wrong origin."""
    odom = [np.array([10.0, -3.0, 1.0])]
    for a, b in itertools.pairwise(truth):
        d = relative(a, b)
        d = d * (1.0 + rng.normal(0.0, 0.03, 3)) + rng.normal(0.0, [0.005, 0.005, 0.005])
        odom.append(compose(odom[-1], d))
    return np.array(odom)


_FHW = LocalizationProfile.load(FHW_PROFILE).grid  # the values these scenes were written for


def _localizer(room: OccupancyGrid, **cfg: object) -> GridMarkovLocalization:
    return GridMarkovLocalization(room, replace(_FHW, **cfg))  # type: ignore[arg-type]


def _errors(est_pose: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    return float(np.hypot(*(est_pose[:2] - truth[:2]))), float(abs(wrap_angle(est_pose[2] - truth[2])))


def test_default_config_is_the_papers_grid() -> None:
    cfg = GridMarkovConfig()
    assert cfg.cell_size == 0.15
    assert math.degrees(cfg.angle_step) == pytest.approx(2.0)
    assert cfg.filters.theta == 0.99
    assert cfg.beam_filter == BeamFilter.NOVELTY
    assert cfg.likelihood_power == 1.0  # the paper's plain product; the FHW profile damps it
    assert _FHW.likelihood_power == 0.1


@pytest.mark.parametrize(
    ("field", "value"), [("cell_size", 0.0), ("uniform_mixture", 1.0), ("prune_ratio", -0.1)]
)
def test_bad_config_is_a_clear_error(field: str, value: float) -> None:
    with pytest.raises(GridMarkovError, match=field):
        GridMarkovConfig(**{field: value})  # type: ignore[arg-type]


def test_lattice_has_free_cells_only_and_round_trips(room: OccupancyGrid) -> None:
    lat = PoseLattice.from_grid(room, 0.15, math.radians(2.0))
    assert lat.n_theta == 180
    idx = np.random.default_rng(1).choice(lat.n_poses, 500, replace=False)
    poses = lat.poses(idx)
    np.testing.assert_array_equal(lat.index_of(poses), idx)
    cells = room.world_to_cell(poses[:, :2])
    assert room.free()[cells[:, 0], cells[:, 1]].all()
    # inside a wall, and off the map
    assert lat.index_of([[-0.98, 1.0, 0.0], [50.0, 50.0, 0.0]]).tolist() == [-1, -1]


def test_map_without_free_space_is_an_error() -> None:
    with pytest.raises(GridMarkovError, match="no free cell"):
        GridMarkovLocalization(OccupancyGrid(np.ones((10, 10), np.float32), 0.1))


def test_update_before_reset_is_an_error(room: OccupancyGrid, caster: DistanceCaster) -> None:
    with pytest.raises(GridMarkovError, match="reset"):
        _localizer(room).update(
            np.zeros(3), _scan(caster, np.array([1.0, 1.0, 0.0]), 0.0, np.random.default_rng(0))
        )


@pytest.mark.parametrize(
    ("prev", "now"),
    [
        ((0.0, 0.0, 0.0), (0.8, 0.1, 0.2)),
        ((1.0, 2.0, 3.0), (1.0, 2.0, 2.5)),
        ((0.0, 0.0, 0.0), (-0.3, 0.0, 0.0)),
    ],
)
def test_layer_kernels_are_the_motion_models_kernels(
    prev: tuple[float, float, float], now: tuple[float, float, float]
) -> None:
    model = OdometryMotionModel()
    heads = np.arange(180) * math.radians(2.0)
    weights, offsets = layer_kernels(model, prev, now, 0.15, math.radians(2.0), heads, floor_std_cells=0.25)
    for k in (0, 17, 45, 90, 133, 179):
        ker = model.kernel(prev, now, 0.15, math.radians(2.0), heading=heads[k])
        a, b, c = ker.weights.shape
        assert tuple(offsets[k]) == ker.offset
        np.testing.assert_allclose(weights[k, :a, :b, :c], ker.weights, atol=1e-12)
        assert weights[k].sum() == pytest.approx(1.0)


def test_tracking_follows_the_robot(room: OccupancyGrid, caster: DistanceCaster) -> None:
    rng = np.random.default_rng(3)
    truth = _path((-0.3, 0.3, 0.0), 12, step=0.35, turn=0.03)
    odom = _odometry(truth, rng)
    loc = _localizer(room)
    loc.reset_tracking(truth[0] + [0.1, -0.1, 0.05], np.diag([0.2, 0.2, 0.1]) ** 2)
    for i, pose in enumerate(truth):
        est = loc.update(odom[i], _scan(caster, pose, float(i), rng))
        d, a = _errors(est.pose, pose)
        assert d < 0.15, f"step {i}: {d:.3f} m off"
        assert a < math.radians(4.0), f"step {i}: {math.degrees(a):.1f} deg off"
        assert est.used_beams.shape == (180,)
        assert est.n_samples == len(loc.belief()[1]) > 0
    assert est.info["motion_applied"] == 1.0
    assert loc.belief_map().sum() == pytest.approx(1.0)


def test_global_localization_finds_the_robot(room: OccupancyGrid, caster: DistanceCaster) -> None:
    rng = np.random.default_rng(4)
    truth = _path((4.5, 1.0, math.pi / 2), 4, step=0.3, turn=0.1)
    odom = _odometry(truth, rng)
    loc = _localizer(room)
    loc.reset_global()
    assert loc.belief()[1].size == loc.lattice.n_poses
    for i, pose in enumerate(truth):
        est = loc.update(odom[i], _scan(caster, pose, float(i), rng))
    d, a = _errors(est.pose, truth[-1])
    assert d < 0.2
    assert a < math.radians(4.0)
    assert est.n_samples < loc.lattice.n_poses // 100, "the belief should have collapsed to a few cells"


def _kidnap_errors(room: OccupancyGrid, caster: DistanceCaster, **cfg: object) -> list[float]:
    rng = np.random.default_rng(5)
    before = _path((0.0, 0.5, 0.0), 6)
    # Kidnapped (Fox et al. 1998, "Recovery"): turned by about 180 deg and moved, odometry unaware.
    after = _path((6.6, 2.0, math.pi / 2 + 0.3), 10)
    truth = np.concatenate([before, after])
    odom = _odometry(np.concatenate([before, compose(before[-1], relative(after[0], after))]), rng)
    loc = _localizer(room, **cfg)
    loc.reset_tracking(truth[0], np.diag([0.1, 0.1, 0.05]) ** 2)
    errors = []
    for i, pose in enumerate(truth):
        est = loc.update(odom[i], _scan(caster, pose, float(i), rng))
        errors.append(_errors(est.pose, pose)[0])
    return errors


@pytest.mark.parametrize("beam_filter", [BeamFilter.NOVELTY, BeamFilter.NONE])
def test_kidnapped_robot_recovers(
    room: OccupancyGrid, caster: DistanceCaster, beam_filter: BeamFilter
) -> None:
    errors = _kidnap_errors(room, caster, beam_filter=beam_filter, sweep_poses=40_000)
    assert max(errors[:6]) < 0.15
    recovered = [i for i in range(6, len(errors)) if all(e < 0.2 for e in errors[i:])]
    assert recovered, f"never recovered: {np.round(errors, 2).tolist()}"
    assert recovered[0] <= 6 + 4, f"recovered only at step {recovered[0]}"


def test_without_the_uniform_mixture_a_kidnapped_robot_stays_lost(
    room: OccupancyGrid, caster: DistanceCaster
) -> None:
    errors = _kidnap_errors(room, caster, beam_filter=BeamFilter.NOVELTY, uniform_mixture=0.0)
    assert max(errors[:6]) < 0.15
    assert min(errors[6:]) > 0.5


def test_novelty_filter_drops_the_beams_that_hit_people(room: OccupancyGrid, caster: DistanceCaster) -> None:
    rng = np.random.default_rng(6)
    truth = _path((0.0, 0.5, 0.0), 8, turn=0.05)
    odom = _odometry(truth, rng)
    loc = _localizer(room)
    loc.reset_tracking(truth[0], np.diag([0.05, 0.05, 0.03]) ** 2)
    for i, pose in enumerate(truth):
        # two people walking one metre ahead of the robot
        people = np.array([compose(pose, [1.0, 0.3, 0.0])[:2], compose(pose, [1.0, -0.3, 0.0])[:2]])
        scan = _scan(caster, pose, float(i), rng, people)
        est = loc.update(odom[i], scan)
        clean = caster.cast(pose[None], GEOMETRY.angles)[0]
        blocked = scan.ranges < clean - 1.0  # 5 sigma_hit shorter than the map explains
        assert blocked.sum() >= 10
        assert est.used_beams[blocked].mean() < 0.05, "beams hitting people should be filtered out"
        assert est.used_beams[np.abs(scan.ranges - clean) < 0.1].mean() > 0.9
        assert _errors(est.pose, pose)[0] < 0.15


def test_entropy_filter_keeps_tracking_among_people(room: OccupancyGrid, caster: DistanceCaster) -> None:
    rng = np.random.default_rng(7)
    truth = _path((0.0, 0.5, 0.0), 8, turn=0.05)
    odom = _odometry(truth, rng)
    loc = _localizer(room, beam_filter=BeamFilter.ENTROPY)
    loc.reset_tracking(truth[0], np.diag([0.05, 0.05, 0.03]) ** 2)
    for i, pose in enumerate(truth):
        people = np.array([compose(pose, [0.8, 0.2 * k, 0.0])[:2] for k in (-2, -1, 0, 1, 2)])
        est = loc.update(odom[i], _scan(caster, pose, float(i), rng, people))
        assert 0 < est.n_used_beams < 180
        assert _errors(est.pose, pose)[0] < 0.2


def test_max_range_readings_are_never_used(room: OccupancyGrid, caster: DistanceCaster) -> None:
    rng = np.random.default_rng(8)
    pose = np.array([1.0, 1.0, 0.3])
    scan = _scan(caster, pose, 0.0, rng)
    ranges = scan.ranges.copy()
    ranges[::7] = GEOMETRY.max_range
    ranges[3] = np.nan
    loc = _localizer(room, beam_filter=BeamFilter.NONE)
    loc.reset_tracking(pose, np.diag([0.1, 0.1, 0.05]) ** 2)
    est = loc.update(np.zeros(3), Scan(0.0, ranges, GEOMETRY))
    assert not est.used_beams[::7].any()
    assert not est.used_beams[3]
    assert est.n_used_beams == 180 - len(range(0, 180, 7)) - 1


@settings(max_examples=10, deadline=None)
@given(st.floats(0.02, 0.07))
def test_small_motions_accumulate_instead_of_rounding_away(step: float) -> None:
    # Steps below half a cell are held back and applied once they add up: no motion is lost.
    loc = GridMarkovLocalization(_room(), _FHW)
    start = np.array([2.0, 1.0, 0.0])
    loc.reset_tracking(start, np.diag([0.01, 0.01, 0.01]) ** 2)
    mean0 = _belief_mean(loc)
    odom = np.zeros(3)
    assert loc.predict(odom) is False  # the first reading only sets the reference
    for _ in range(12):
        odom = compose(odom, [step, 0.0, 0.0])
        loc.predict(odom)
    moved = _belief_mean(loc) - mean0
    ref = loc.odometry_reference
    assert ref is not None
    held_back = np.hypot(*(odom[:2] - ref[:2]))
    assert moved[0] == pytest.approx(12 * step - held_back, abs=0.03)
    assert abs(moved[1]) < 0.03
    assert held_back < 0.075


def _belief_mean(loc: GridMarkovLocalization) -> np.ndarray:
    poses, w = loc.belief()
    return np.asarray(w @ poses[:, :2])


def test_plain_markov_localization_is_misled_by_people(room: OccupancyGrid, caster: DistanceCaster) -> None:
    # Fox et al. 1998, Table 1: without a filter, crowds make Markov localization fail.
    rng = np.random.default_rng(7)
    truth = _path((0.0, 0.5, 0.0), 8, turn=0.05)
    odom = _odometry(truth, rng)
    loc = _localizer(room, beam_filter=BeamFilter.NONE)
    loc.reset_tracking(truth[0], np.diag([0.05, 0.05, 0.03]) ** 2)
    errors = []
    for i, pose in enumerate(truth):
        people = np.array([compose(pose, [0.8, 0.2 * k, 0.0])[:2] for k in (-2, -1, 0, 1, 2)])
        est = loc.update(odom[i], _scan(caster, pose, float(i), rng, people))
        errors.append(_errors(est.pose, pose)[0])
    assert max(errors) > 1.0


@pytest.fixture(scope="module")
def fhw_start(fhw_log_path: Path) -> tuple[RobotLog, GridMarkovLocalization]:
    """The first 18 scans of the FHW museum log and a grid localizer on their reference map."""
    from tourbot.io.carmen import read_carmen
    from tourbot.maps.reference import build_reference_map

    log = read_carmen(fhw_log_path)
    log.scans = log.scans[:18]
    # a smaller recovery sweep than the default keeps the test short; the tracking is the same
    loc = GridMarkovLocalization(build_reference_map(log), replace(_FHW, sweep_poses=20_000))
    loc.prepare(log.scans[0].geometry.max_range)
    return log, loc


def test_tracks_the_real_fhw_log(fhw_start: tuple[RobotLog, GridMarkovLocalization]) -> None:
    log, loc = fhw_start
    ref = log.reference_poses
    loc.reset_tracking(ref[0], np.diag([0.1, 0.1, 0.05]) ** 2)
    errors = []
    for scan, truth in zip(log.scans, ref, strict=True):
        est = loc.update(np.asarray(scan.odom), scan)
        errors.append(_errors(est.pose, truth))
        assert 0 < est.n_used_beams <= 180
    d = np.array(errors)
    assert d[:, 0].max() < 0.3, "the paper's failure threshold is 45 cm"
    assert d[:, 0].mean() < 0.15
    assert np.degrees(d[:, 1]).max() < 5.0


def test_localizes_globally_on_the_real_fhw_log(fhw_start: tuple[RobotLog, GridMarkovLocalization]) -> None:
    log, loc = fhw_start
    ref = log.reference_poses
    loc.reset_global()
    for i in range(10, 14):
        est = loc.update(np.asarray(log.scans[i].odom), log.scans[i])
    assert _errors(est.pose, ref[13])[0] < 0.3


def test_reset_tracking_defaults_to_the_tracking_std(room: OccupancyGrid) -> None:
    loc = _localizer(room)
    loc.reset_tracking([2.0, 1.0, 0.5])
    poses, w = loc.belief()
    mean = w @ poses[:, :2]
    spread = np.sqrt(w @ (poses[:, :2] - mean) ** 2)
    np.testing.assert_allclose(mean, [2.0, 1.0], atol=0.05)
    assert np.all((spread > 0.07) & (spread < 0.15)), spread


def test_grid_errors_are_localization_errors() -> None:

    assert issubclass(GridMarkovError, LocalizationError)


def test_unknown_cells_need_not_be_walls(room: OccupancyGrid, caster: DistanceCaster) -> None:
    # A trinary map (map_server PGM) turns uncertain cells unknown; with unknown_blocks=False they do
    # not act as walls in the expected ranges. The scans come from the room without them.
    prob = room.prob.copy()
    prob[int(1.0 / RES) : int(3.0 / RES), int(5.5 / RES) : int(6.0 / RES)] = -1.0
    patched = OccupancyGrid(prob, RES, room.origin)
    rng = np.random.default_rng(9)
    truth = _path((-0.3, 0.3, 0.0), 12, step=0.35, turn=0.03)
    odom = _odometry(truth, rng)
    loc = GridMarkovLocalization(patched, replace(_FHW, unknown_blocks=False))
    loc.reset_tracking(truth[0])
    for i, pose in enumerate(truth):
        est = loc.update(odom[i], _scan(caster, pose, float(i), rng))
        assert _errors(est.pose, pose)[0] < 0.15, f"step {i}"


def test_expected_range_table_is_cached_and_reused(room: OccupancyGrid, tmp_path: Path) -> None:
    first = _localizer(room)
    built = first.prepare(GEOMETRY.max_range, cache=tmp_path)
    assert first.table_source.startswith("built and saved to")
    saved = list(tmp_path.glob("*.npz"))
    assert len(saved) == 1

    second = _localizer(room)
    read = second.prepare(GEOMETRY.max_range, cache=tmp_path)
    assert second.table_source == f"read from {saved[0]}"
    np.testing.assert_array_equal(read.bins, built.bins)
    assert (read.angle_step, read.range_bin, read.max_range) == (
        built.angle_step,
        built.range_bin,
        built.max_range,
    )

    # another map, another maximum range or another table step: another table
    prob = room.prob.copy()
    prob[60:70, 60:70] = 1.0
    _localizer(OccupancyGrid(prob, room.resolution, room.origin)).prepare(GEOMETRY.max_range, cache=tmp_path)
    _localizer(room).prepare(GEOMETRY.max_range - 5.0, cache=tmp_path)
    _localizer(room, table_angle_step=math.radians(2.0)).prepare(GEOMETRY.max_range, cache=tmp_path)
    assert len(list(tmp_path.glob("*.npz"))) == 4


def test_a_corrupt_cached_table_is_built_again(room: OccupancyGrid, tmp_path: Path) -> None:
    first = _localizer(room)
    built = first.prepare(GEOMETRY.max_range, cache=tmp_path)
    (path,) = tmp_path.glob("*.npz")
    path.write_bytes(b"not a table")
    again = _localizer(room)
    table = again.prepare(GEOMETRY.max_range, cache=tmp_path)
    assert again.table_source.startswith("built and saved to")
    np.testing.assert_array_equal(table.bins, built.bins)
    path.write_bytes(b"still not a table")
    with pytest.raises(LocalizationError, match="not an expected-range table"):
        ExpectedRangeTable.load(path)


@pytest.mark.parametrize("power", [0.0, -0.5, 1.5])
def test_likelihood_power_must_be_in_0_1(power: float) -> None:
    with pytest.raises(GridMarkovError, match="likelihood_power"):
        GridMarkovConfig(likelihood_power=power)


def test_tempered_likelihood_keeps_a_broader_belief(room: OccupancyGrid, caster: DistanceCaster) -> None:
    # The product of 180 beams taken as independent is overconfident (neighbouring beams share
    # the map's and the lattice's errors); the power < 1 keeps more of the poses near the truth
    # (and makes a far pose need more evidence to take the belief over).
    rng = np.random.default_rng(11)
    truth = _path((0.5, 0.8, 0.2), 4)
    odom = _odometry(truth, rng)
    scans = [_scan(caster, p, float(i), rng) for i, p in enumerate(truth)]
    held = {}
    for power in (1.0, 0.1):
        loc = _localizer(room, likelihood_power=power, uniform_mixture=0.0)
        loc.reset_tracking(truth[0], np.diag([0.1, 0.1, 0.05]) ** 2)
        for i, scan in enumerate(scans):
            est = loc.update(odom[i], scan)
        assert _errors(est.pose, truth[-1])[0] < 0.15
        poses, w = loc.belief()
        held[power] = (w.size, float(w @ np.hypot(*(poses[:, :2] - truth[-1, :2]).T)))
    # many more poses kept (above the pruning ratio), and still centred on the truth
    assert held[0.1][0] > 5 * held[1.0][0], held
    assert held[0.1][1] < 0.15, held


def test_a_reset_localizer_runs_as_a_fresh_one(room: OccupancyGrid, caster: DistanceCaster) -> None:
    """What a localizer ran before a reset leaves no trace (the sweep of the uniform mixture starts
    its tour again): a benchmark that shares one localizer between runs gets the same figures in
    whatever order, or process, it runs them."""
    rng = np.random.default_rng(5)
    before = _path((0.0, 0.5, 0.0), 4)
    after = _path((6.6, 2.0, math.pi / 2 + 0.3), 4)  # kidnapped: the sweep's poses matter
    truth = np.concatenate([before, after])
    odom = _odometry(np.concatenate([before, compose(before[-1], relative(after[0], after))]), rng)
    scans = [_scan(caster, pose, float(i), rng) for i, pose in enumerate(truth)]

    def run(loc: GridMarkovLocalization) -> np.ndarray:
        loc.reset_tracking(truth[0], np.diag([0.1, 0.1, 0.05]) ** 2)
        out = [loc.update(odom[i], scan).pose for i, scan in enumerate(scans)]
        return np.concatenate([np.ravel(out), loc.belief()[1]])

    shared = _localizer(room, sweep_poses=5000)
    assert shared.lattice.n_poses > 4 * len(scans) * 5000  # the tour does not come round in a run
    first, second = run(shared), run(shared)
    fresh = run(_localizer(room, sweep_poses=5000))
    assert np.array_equal(first, fresh)
    assert np.array_equal(second, fresh)
