"""Monte Carlo localization in the synthetic room, through its public API and its seams."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from tourbot.geometry import compose, relative, wrap_angle
from tourbot.localization.beam_filters import BeamFilter
from tourbot.localization.mcl import LocalizationError, MCLConfig, MonteCarloLocalization, PoseLikelihood
from tourbot.maps.grid import OccupancyGrid

from ..conftest import room_with_boxes, simulate, waypoints_path
from .conftest import tuned
from .scenes import (
    crowd_around,
    errors,
    legs_before_walls,
    people_in_front,
    phantom_kidnap,
    rarely_seen,
    run,
)


def test_tracking_follows_the_robot_with_the_defaults(room: OccupancyGrid) -> None:
    drive = simulate(room, waypoints_path(50), seed=1)
    mcl = MonteCarloLocalization(room, MCLConfig().with_samples(1000), seed=2)
    mcl.reset_tracking(drive.truth[0])
    est = run(mcl, drive)
    err = errors(est, drive.truth)
    assert err.mean() < 0.08
    assert err.max() < 0.3
    assert np.abs(wrap_angle(est[:, 2] - drive.truth[:, 2])).mean() < math.radians(3)


def test_tracking_follows_the_robot_with_the_fhw_profile(room: OccupancyGrid) -> None:
    drive = simulate(room, waypoints_path(50), seed=1)
    mcl = MonteCarloLocalization(room, tuned(1000, 200), seed=2)
    mcl.reset_tracking(drive.truth[0])
    err = errors(run(mcl, drive), drive.truth)
    assert err.mean() < 0.08
    assert err.max() < 0.3


def test_odometry_alone_would_drift(room: OccupancyGrid) -> None:
    """The tracking test is not trivial: dead reckoning alone drifts far more."""
    drive = simulate(room, waypoints_path(50), seed=1)
    dead = [drive.truth[0]]
    for k in range(1, len(drive.scans)):
        dead.append(compose(dead[-1], relative(drive.odom[k - 1], drive.odom[k])))
    assert errors(np.array(dead), drive.truth).mean() > 0.15


def test_global_localization_converges(room: OccupancyGrid) -> None:
    drive = simulate(room, waypoints_path(50), seed=3)
    mcl = MonteCarloLocalization(room, tuned(2000, 300, **{"global": {"samples": 20000}}), seed=4)
    mcl.reset_global()
    err = errors(run(mcl, drive), drive.truth)
    assert err[25:].max() < 0.3
    assert mcl.samples.shape[0] < 2000  # KLD shrank the set once localized


def test_global_start_among_people_localizes_on_the_first_scans(room: OccupancyGrid) -> None:
    # Two people in front of the robot at every scan: the annealed start over a large candidate
    # set, scored on the longest returns, must find the robot within a few scans.
    truth = waypoints_path(12)
    drive = simulate(room, truth, seed=11, circles=people_in_front(truth, np.random.default_rng(12)))
    cfg = tuned(2000, 300, **{"global": {"samples": 20000, "candidates": 200_000}})
    mcl = MonteCarloLocalization(room, cfg, seed=13)
    mcl.reset_global()
    assert mcl.recovery.state.global_phase
    assert mcl.recovery.state.unconfirmed
    first = mcl.update(drive.odom[0], drive.scans[0])
    assert first.n_samples == 20000
    assert first.info["global_stages"] >= 1
    est = [first.pose] + [mcl.update(drive.odom[k], drive.scans[k]).pose for k in range(1, len(truth))]
    assert errors(np.array(est), truth)[3:].max() < 0.3


def test_recovers_from_a_kidnap(room: OccupancyGrid) -> None:
    loop = waypoints_path(80)
    # After scan 20 the robot is carried 20 steps ahead on its loop (about 4 m away, heading
    # turned by about 90 deg) without its odometry knowing.
    taken = np.r_[np.arange(20), np.arange(40, 80)]
    unaware = np.vstack([loop[:20], compose(loop[19], relative(loop[39], loop[40:]))])
    drive = simulate(room, loop[taken], seed=5, odom_truth=unaware)
    mcl = MonteCarloLocalization(room, tuned(2000, 300), seed=6)
    mcl.reset_tracking(loop[0])
    err = errors(run(mcl, drive), drive.truth)
    assert err[:20].max() < 0.3
    assert err[20] > 0.45  # lost right after the kidnap
    assert err[40:].max() < 0.3  # and found again


def test_a_good_track_across_rarely_seen_space_keeps_it_when_offered_far_guesses(room: OccupancyGrid) -> None:
    # issue 22: the map knows a third of the room only as unknown cells (free space a map from
    # one log saw too rarely), the robot drives through the rest among people, and every fifth
    # scan a guess at the other side of its loop is offered. The track explains every scan (its
    # readings cross unknown cells, no wall): it is kept all along, no jump.
    loop = waypoints_path(60)
    drive = simulate(room, loop, seed=31, circles=crowd_around(loop, np.random.default_rng(31), 6))
    for cfg in (MCLConfig().with_samples(1000), tuned(1000, 300)):
        mcl = MonteCarloLocalization(rarely_seen(room, 9.0, 5.6), cfg, seed=32)
        mcl.reset_tracking(loop[0])
        est = []
        for k, s in enumerate(drive.scans):
            if k % 5 == 4:
                mcl.inject(np.tile(loop[(k + 30) % 60], (50, 1)))
            est.append(mcl.update(drive.odom[k], s).pose)
        err = errors(np.array(est), loop)
        assert err.max() < 0.3
        step = np.hypot(*np.diff(np.array(est)[:, :2], axis=0).T)
        assert step.max() < 1.0  # the loop's steps are 0.4 m


def test_a_kidnap_across_rarely_seen_space_is_still_recovered(room: OccupancyGrid) -> None:
    # The kidnap of test_recovers_from_a_kidnap on the map that knows a third of the room only
    # as unknown cells: readings through unknown cells no longer count against a pose, and the
    # readings through the walls the kidnapped track sees are enough to give it away.
    loop = waypoints_path(80)
    taken = np.r_[np.arange(20), np.arange(40, 80)]
    unaware = np.vstack([loop[:20], compose(loop[19], relative(loop[39], loop[40:]))])
    drive = simulate(room, loop[taken], seed=5, odom_truth=unaware)
    mcl = MonteCarloLocalization(rarely_seen(room, 9.0, 5.6), tuned(2000, 300), seed=6)
    mcl.reset_tracking(loop[0])
    err = errors(run(mcl, drive), drive.truth)
    assert err[:20].max() < 0.3
    assert err[20] > 0.45  # lost right after the kidnap
    assert err[30:].max() < 0.3  # and found again within ten scans


@pytest.mark.parametrize("kind", [BeamFilter.NOVELTY, BeamFilter.ENTROPY])
def test_filters_drop_beams_that_hit_people(room: OccupancyGrid, kind: BeamFilter) -> None:
    truth = waypoints_path(30)
    drive = simulate(room, truth, seed=7, circles=people_in_front(truth, np.random.default_rng(7)))
    clean = simulate(room, truth, seed=7)
    # With a narrow likelihood field, a beam ending far from every wall is equally (un)likely at
    # every sample: Delta H = 0 and Eq. 4 keeps it, harmlessly. The wider field of Nav2 AMCL
    # (sigma_hit 0.2 m) makes such beams informative, and the entropy filter must drop them.
    cfg = tuned(1000, 300, sensor={"beam_filter": kind.value, "field": {"sigma_hit": 0.2}})
    mcl = MonteCarloLocalization(room, cfg, seed=8)
    mcl.reset_tracking(truth[0])
    dropped_people = kept_people = dropped_other = kept_other = 0
    errs = []
    for k, (s, c) in enumerate(zip(drive.scans, clean.scans, strict=True)):
        est = mcl.update(np.asarray(s.odom), s)
        errs.append(float(np.hypot(*(est.pose[:2] - truth[k, :2]))))
        hit_person = c.ranges - s.ranges > 0.3
        dropped_people += int((~est.used_beams & hit_person).sum())
        kept_people += int((est.used_beams & hit_person).sum())
        other = ~hit_person & (s.ranges < s.geometry.max_range)
        dropped_other += int((~est.used_beams & other).sum())
        kept_other += int((est.used_beams & other).sum())
    assert dropped_other / (dropped_other + kept_other) < 0.1
    assert dropped_people / (dropped_people + kept_people) > (0.9 if kind == BeamFilter.NOVELTY else 0.5)
    assert max(errs) < 0.3


@pytest.mark.parametrize(("novelty_sigma", "dropped_least"), [(0.05, 0.6), (0.2, None)])
def test_novelty_filter_drops_visitors_standing_by_the_walls(
    room: OccupancyGrid, novelty_sigma: float, dropped_least: float | None
) -> None:
    # Eq. 5's p(d | l) is the laser's own spread about the mapped range (5 cm, bench
    # sensor-model); the belief average of Eq. 6 carries the pose uncertainty. With the likelihood
    # field's 0.2 m in its place a reading 25 cm short of the wall was never "shorter than expected".
    truth = waypoints_path(30)
    legs = legs_before_walls(truth, room, 0.25, np.random.default_rng(3))
    drive = simulate(room, truth, seed=7, circles=legs)
    clean = simulate(room, truth, seed=7)
    cfg = MCLConfig().with_samples(1000)
    cfg = replace(cfg, sensor=replace(cfg.sensor, novelty_sigma=novelty_sigma))
    mcl = MonteCarloLocalization(room, cfg, seed=8)
    mcl.reset_tracking(truth[0])
    dropped = kept = dropped_other = other = 0
    for s, c in zip(drive.scans, clean.scans, strict=True):
        est = mcl.update(np.asarray(s.odom), s)
        by_wall = c.ranges - s.ranges > 0.15
        dropped += int((~est.used_beams & by_wall).sum())
        kept += int((est.used_beams & by_wall).sum())
        returns = ~by_wall & (s.ranges < s.geometry.max_range)
        dropped_other += int((~est.used_beams & returns).sum())
        other += int(returns.sum())
    assert dropped + kept > 60  # the legs were seen
    assert dropped_other / other < 0.1  # the walls are not taken for visitors
    if dropped_least is None:
        assert dropped / (dropped + kept) < 0.3  # the old width lets most of them through
    else:
        assert dropped / (dropped + kept) > dropped_least


def test_entropy_filter_does_not_report_beams_that_change_nothing(room: OccupancyGrid) -> None:
    # With the narrow field of the FHW profile (sigma_hit 0.1 m) most beams that end on a person
    # far from every wall are equally likely at every sample: integrating them is a no-op, and
    # they are not reported as integrated (the recovery judges the fit of the integrated beams).
    truth = waypoints_path(30)
    drive = simulate(room, truth, seed=7, circles=people_in_front(truth, np.random.default_rng(7)))
    clean = simulate(room, truth, seed=7)
    mcl = MonteCarloLocalization(room, tuned(1000, 300, sensor={"beam_filter": "entropy"}), seed=8)
    mcl.reset_tracking(truth[0])
    kept_people = people = kept_other = other = 0
    for k, (s, c) in enumerate(zip(drive.scans, clean.scans, strict=True)):
        est = mcl.update(np.asarray(s.odom), s)
        assert np.hypot(*(est.pose[:2] - truth[k, :2])) < 0.3
        hit_person = c.ranges - s.ranges > 0.3
        returns = ~hit_person & (s.ranges < s.geometry.max_range)
        kept_people += int((est.used_beams & hit_person).sum())
        people += int(hit_person.sum())
        kept_other += int((est.used_beams & returns).sum())
        other += int(returns.sum())
    assert kept_people / people < 0.5
    assert kept_other / other > 0.9


def test_unfiltered_uses_every_return(room: OccupancyGrid) -> None:
    drive = simulate(room, waypoints_path(5), seed=9)
    mcl = MonteCarloLocalization(room, tuned(300, 100, sensor={"beam_filter": "none"}))
    mcl.reset_tracking(drive.truth[0])
    est = mcl.update(drive.odom[0], drive.scans[0])
    assert np.array_equal(est.used_beams, drive.scans[0].ranges < drive.scans[0].geometry.max_range)
    assert est.covariance.shape == (3, 3)
    assert est.n_samples == mcl.samples.shape[0] == mcl.weights.shape[0]


def test_update_before_reset_is_an_error(room: OccupancyGrid) -> None:
    drive = simulate(room, waypoints_path(2), seed=9)
    mcl = MonteCarloLocalization(room)
    with pytest.raises(LocalizationError, match="reset"):
        mcl.update(drive.odom[0], drive.scans[0])


def test_map_without_free_space() -> None:
    with pytest.raises(LocalizationError, match="free"):
        MonteCarloLocalization(OccupancyGrid(np.ones((5, 5), np.float32), 0.1))


def test_same_seed_same_result(room: OccupancyGrid) -> None:
    drive = simulate(room, waypoints_path(6), seed=10)
    runs = []
    for _ in range(2):
        mcl = MonteCarloLocalization(room, tuned(500, 100), seed=11)
        mcl.reset_tracking(drive.truth[0])
        runs.append(run(mcl, drive))
    assert np.array_equal(runs[0], runs[1])


def test_augmented_mcl_injects_only_while_the_track_is_in_doubt(room: OccupancyGrid) -> None:
    # ratio 2: the fit's averages ask for max_injection on every scan. A track from a known start
    # that explains every scan (the too-long test passes) gets none of it: no guess could win
    # against it. The same track, unconfirmed as global localization leaves one, is searched for.
    drive = simulate(room, waypoints_path(12), seed=5)
    config = replace(MCLConfig().with_samples(500), recovery=replace(MCLConfig().recovery, ratio=2.0))
    mcl = MonteCarloLocalization(room, config, seed=6)
    mcl.reset_tracking(drive.truth[0])
    asked, injected = 0, 0.0
    poses = []
    for k, s in enumerate(drive.scans):
        est = mcl.update(drive.odom[k], s)
        assert est.info["too_long"] <= config.recovery.lost_fraction
        asked += est.info["inject_fraction"] > 0
        injected += est.info["injected"]
        poses.append(est.pose)
    assert asked == len(drive.scans)
    assert injected == 0
    assert errors(np.array(poses), drive.truth).max() < 0.3
    doubted = MonteCarloLocalization(room, config, seed=6)
    doubted.reset_tracking(drive.truth[0])
    doubted.recovery.state.unconfirmed = True
    est = doubted.update(drive.odom[0], drive.scans[0])
    assert est.info["injected"] == round(config.recovery.max_injection * est.n_samples)
    assert doubted.recovery.fresh.sum() == est.info["injected"]


def test_dense_crowd_neither_triggers_recovery_nor_loses_tracking(room: OccupancyGrid) -> None:
    # A crowd hiding about half of every scan: the novelty filter removes its beams, so the fit of
    # the kept beams stays high, no sample is injected and the robot is tracked throughout.
    truth = waypoints_path(40)
    drive = simulate(room, truth, seed=11, circles=crowd_around(truth, np.random.default_rng(11), 14))
    clean = simulate(room, truth, seed=11)
    hidden = np.mean(
        [np.mean(c.ranges - s.ranges > 0.3) for s, c in zip(drive.scans, clean.scans, strict=True)]
    )
    assert 0.35 < hidden < 0.7  # the crowd really shortens about half of the beams
    mcl = MonteCarloLocalization(room, tuned(1000, 300), seed=12)
    mcl.reset_tracking(truth[0])
    injected = 0.0
    errs = []
    for k, s in enumerate(drive.scans):
        est = mcl.update(drive.odom[k], s)
        injected += est.info["injected"]
        errs.append(float(np.hypot(*(est.pose[:2] - truth[k, :2]))))
    assert injected == 0
    assert max(errs) < 0.3


@pytest.mark.parametrize(
    ("legs", "delta", "within"),
    [(14, (0.5, -0.4, 2.7), 6), (24, (0.5, -0.4, 2.7), 6), (24, (-0.6, 0.7, -2.0), 6)],
)
def test_recovers_from_the_papers_kidnap_in_a_crowd(
    room: OccupancyGrid, legs: int, delta: tuple[float, float, float], within: int
) -> None:
    # Fox et al.'s kidnap (heading turned by 180 +/- 90 deg, moved by up to 1 m) while a crowd
    # hides about half (14 legs) or two thirds (24 legs) of every scan: readings through walls at
    # the estimate give the kidnap away, the guesses are scored by the crowd beam model, and the
    # robot is found again within a few scans. (With 14 legs and the novelty filter's 5 cm, seed 22
    # takes 6 scans, seeds 23-24 one; with the 10 cm it had before, 0-1 scans, but 24 legs then
    # take 27-30 scans on seeds 23-24 against 6 and 25.)
    truth = waypoints_path(50)
    drive = simulate(room, truth, seed=21, circles=crowd_around(truth, np.random.default_rng(21), legs))
    odom = phantom_kidnap(drive.odom, 20, np.array(delta))

    def track(config: MCLConfig) -> np.ndarray:
        mcl = MonteCarloLocalization(room, config, seed=22)
        mcl.reset_tracking(truth[0])
        return errors(np.array([mcl.update(odom[k], s).pose for k, s in enumerate(drive.scans)]), truth)

    stuck = track(tuned(1000, 300, recovery={"max_injection": 0.0}))  # the kidnap is real
    assert stuck[:20].max() < 0.3
    assert np.median(stuck[20:]) > 0.45
    err = track(tuned(1000, 300))
    assert err[:20].max() < 0.3
    assert err[20 + within :].max() < 0.3  # found again within a few scans, and kept


def test_a_track_from_global_localization_is_searched_for_everywhere_until_confirmed(
    room: OccupancyGrid,
) -> None:
    # Global localization may settle on a look-alike far from the robot. Such a track was never
    # right, so on its first contradicted scan the reset guesses are drawn over the whole free
    # space (and the expected-range table), not only around it: some land at the true pose.
    truth = waypoints_path(10)
    drive = simulate(room, truth, seed=33)
    wrong = np.array([truth[9][0], truth[9][1], truth[4][2] + 1.0])
    assert np.hypot(*(wrong[:2] - truth[4][:2])) > 4.0

    def settled_after_global(at: np.ndarray) -> MonteCarloLocalization:
        # a tight cluster, as global localization leaves it: the global phase over, the track
        # never judged yet (unconfirmed)
        mcl = MonteCarloLocalization(room, tuned(300, 100), seed=31)
        mcl.reset_tracking(at, np.diag([4e-4, 4e-4, 1e-4]))
        mcl.recovery.state.unconfirmed = True
        return mcl

    def near_truth(mcl: MonteCarloLocalization) -> int:
        d = np.hypot(mcl.samples[:, 0] - truth[4][0], mcl.samples[:, 1] - truth[4][1])
        h = np.abs(wrap_angle(mcl.samples[:, 2] - truth[4][2]))
        return int(((d < 0.3) & (h < math.radians(10.0)) & mcl.recovery.fresh).sum())

    mcl = settled_after_global(wrong)
    est = mcl.update(drive.odom[4], drive.scans[4])
    assert est.info["too_long"] > mcl.config.recovery.lost_fraction
    assert mcl.recovery.state.lost_scans == 1
    assert near_truth(mcl) > 0
    # A known start is searched for around the estimate first, for global_after contradicted
    # scans (a drift, a kidnap by a metre).
    mcl = MonteCarloLocalization(room, tuned(300, 100), seed=31)
    mcl.reset_tracking(wrong, np.diag([4e-4, 4e-4, 1e-4]))
    assert not mcl.recovery.state.unconfirmed
    mcl.update(drive.odom[4], drive.scans[4])
    assert mcl.recovery.state.lost_scans == 1
    assert near_truth(mcl) == 0
    # The track at the true pose passes the test; global_after passes in a row confirm it.
    mcl = settled_after_global(truth[4])
    for k in range(4, 4 + mcl.config.recovery.global_after):
        assert mcl.recovery.state.unconfirmed
        est = mcl.update(drive.odom[k], drive.scans[k])
        assert est.info["too_long"] <= mcl.config.recovery.lost_fraction
    assert not mcl.recovery.state.unconfirmed


# ---------------------------------------------------------------------- the seams


class _Beacon:
    """A sensor that sees the robot within ``sigma`` of ``at`` (a ceiling camera, say)."""

    def __init__(self, at: np.ndarray, sigma: float) -> None:
        self.at = at
        self.sigma = sigma
        self.calls = 0

    def log_likelihood(self, poses: np.ndarray) -> np.ndarray:
        self.calls += 1
        d2 = (poses[:, 0] - self.at[0]) ** 2 + (poses[:, 1] - self.at[1]) ** 2
        return -0.5 * d2 / self.sigma**2


def test_an_extra_likelihood_is_added_to_the_laser(room: OccupancyGrid) -> None:
    # Two identical filters, one with a beacon that says the robot is 30 cm to the side of where
    # it is: the beacon pulls that filter's estimate towards it; the laser alone does not.
    truth = waypoints_path(6)
    drive = simulate(room, truth, seed=40)
    side = compose(truth[0], np.array([0.0, 0.3, 0.0]))
    beacon = _Beacon(side, 0.05)
    assert isinstance(beacon, PoseLikelihood)
    plain = MonteCarloLocalization(room, tuned(500, 500), seed=41)
    pulled = MonteCarloLocalization(room, tuned(500, 500), seed=41, extra_likelihoods=[beacon])
    for m in (plain, pulled):
        m.reset_tracking(truth[0], np.diag([0.04, 0.04, 1e-3]))
    e_plain = plain.update(drive.odom[0], drive.scans[0])
    e_pulled = pulled.update(drive.odom[0], drive.scans[0])
    assert beacon.calls == 1
    assert np.hypot(*(e_pulled.pose[:2] - side[:2])) < np.hypot(*(e_plain.pose[:2] - side[:2]))
    # added later by add_likelihood, it counts from the next update on
    late = _Beacon(side, 0.05)
    plain.add_likelihood(late)
    plain.update(drive.odom[1], drive.scans[1])
    assert late.calls == 1


def test_weigh_takes_a_measurement_at_its_own_time(room: OccupancyGrid) -> None:
    # A beacon measured between two scans, at the odometry pose of its own time: the samples move
    # there first, the weights take the beacon once, and the next scan's update resamples.
    truth = waypoints_path(6)
    drive = simulate(room, truth, seed=40)
    mcl = MonteCarloLocalization(room, tuned(500, 500), seed=41)
    mcl.reset_tracking(truth[0], np.diag([0.04, 0.04, 1e-3]))
    mcl.update(drive.odom[0], drive.scans[0])
    side = compose(truth[1], np.array([0.0, 0.3, 0.0]))
    beacon = _Beacon(side, 0.05)
    before = mcl.samples.copy()
    mcl.weigh(drive.odom[1], beacon)
    assert beacon.calls == 1
    moved = np.hypot(*(np.average(mcl.samples[:, :2] - before[:, :2], axis=0)))
    stepped = np.hypot(*(np.asarray(drive.odom[1])[:2] - np.asarray(drive.odom[0])[:2]))
    assert abs(moved - stepped) < 0.05 * stepped  # the motion model carried the samples there
    mean = np.average(mcl.samples[:, :2], axis=0, weights=mcl.weights)
    assert np.hypot(*(mean - side[:2])) < 0.15  # pulled to the beacon
    assert 1.0 / np.sum(mcl.weights**2) < 0.5 * len(mcl.weights)  # not yet resampled
    mcl.update(drive.odom[1], drive.scans[1])
    assert beacon.calls == 1  # once, not at every scan
    fresh = MonteCarloLocalization(room, tuned(500, 500), seed=41)
    fresh.reset_global()
    fresh.weigh(drive.odom[0], beacon)  # a global start waits for its first scan
    assert beacon.calls == 1
    with pytest.raises(LocalizationError, match="reset"):
        MonteCarloLocalization(room).weigh(drive.odom[0], beacon)


def test_set_map_rebuilds_the_sensor_model(room: OccupancyGrid) -> None:
    # A door closes: a wall across the room's middle. The laser model of the new map sees it,
    # and the free space shrinks by the wall's cells.
    mcl = MonteCarloLocalization(room, tuned(300, 100), seed=42)
    truth = waypoints_path(4)
    drive = simulate(room, truth, seed=43)
    mcl.reset_tracking(truth[0])
    mcl.update(drive.odom[0], drive.scans[0])
    before = mcl.sensor.field(drive.scans[0].geometry)
    prob = room.prob.copy()
    prob[:, 110:114] = 1.0
    closed = OccupancyGrid(prob, room.resolution, origin=room.origin)
    mcl.set_map(closed)
    assert mcl.grid is closed
    assert mcl.sensor.free_cells.shape[0] < np.argwhere(room.free()).shape[0]
    assert mcl.sensor.field(drive.scans[0].geometry) is not before
    pose = np.array([[room.origin[0] + 105 * room.resolution, 4.0, 0.0]])  # facing the new wall
    expected = mcl.sensor.caster(20.0).cast(pose, np.array([0.0]))[0, 0]
    assert expected < 0.5
    mcl.update(drive.odom[1], drive.scans[1])  # the filter runs on


def test_injected_poses_become_guesses_that_must_win(room: OccupancyGrid) -> None:
    # A ceiling camera sees the robot where it is while the filter tracks a wrong place: its
    # poses are offered to recovery, enter as guesses, and win over the contradicted track. The
    # filter's own search is switched off, so without the offer it stays lost.
    truth = waypoints_path(12)
    drive = simulate(room, truth, seed=44)
    blind = {
        "max_injection": 0.3,
        "search": {"local_candidates": 0, "far_candidates": 0, "table_survivors": 0},
    }
    wrong = compose(truth[0], np.array([0.5, -0.4, 2.7]))

    def lost_filter() -> MonteCarloLocalization:
        mcl = MonteCarloLocalization(room, tuned(500, 200, recovery=blind), seed=45)
        mcl.reset_tracking(wrong, np.diag([1e-4, 1e-4, 1e-4]))
        return mcl

    alone = lost_filter()
    for k in range(4):
        est = alone.update(drive.odom[k], drive.scans[k])
    assert np.hypot(*(est.pose[:2] - truth[3, :2])) > 0.45
    mcl = lost_filter()
    mcl.inject(truth[0] + np.random.default_rng(46).normal(0.0, [0.05, 0.05, 0.02], (100, 3)))
    mcl.inject(np.array([[-50.0, -50.0, 0.0]]))  # off the map: ignored
    est = mcl.update(drive.odom[0], drive.scans[0])
    # the scan contradicts the track: max_injection of the samples are replaced by offered poses
    assert est.info["injected"] == round(0.3 * est.n_samples)
    near = np.hypot(*(mcl.samples[:, :2] - truth[0, :2]).T) < 0.3
    assert (near & mcl.recovery.fresh).sum() == mcl.recovery.fresh.sum() == est.info["injected"]
    for k in range(1, 4):
        est = mcl.update(drive.odom[k], drive.scans[k])
    assert np.hypot(*(est.pose[:2] - truth[3, :2])) < 0.3


def test_a_standing_robot_keeps_its_track_under_the_defaults() -> None:
    room = room_with_boxes()
    truth = np.tile(waypoints_path(10)[2], (8, 1))
    drive = simulate(room, truth, seed=47)
    mcl = MonteCarloLocalization(room, seed=48)
    mcl.reset_tracking(truth[0])
    assert errors(run(mcl, drive), truth).max() < 0.15
