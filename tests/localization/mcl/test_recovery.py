"""Recovery through its own API: the fit's averages, the too-long verdicts, the guesses' contest."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest

from tourbot.geometry import compose, wrap_angle
from tourbot.localization.mcl import MonteCarloLocalization, Recovery, RecoveryConfig, RecoveryState
from tourbot.localization.mcl.clustering import best_cluster_estimate, cluster_bins
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import LaserGeometry

from ..conftest import simulate, waypoints_path
from .conftest import tuned
from .scenes import crowd_around

Judge = Callable[[np.ndarray, np.ndarray | None], float]


def test_augmented_mcl_injects_when_the_short_term_fit_drops() -> None:
    # Probabilistic Robotics Table 8.3 with the textbook's ratio 1: inject max(0, 1 - w_fast / w_slow).
    rec = Recovery(RecoveryConfig(alpha_slow=0.1, alpha_fast=0.5, max_injection=1.0))
    assert rec.injection_from_fit(0.9, evidence=True) == 0.0  # the first scan starts both averages
    assert rec.state.w_slow == rec.state.w_fast == 0.9
    assert rec.injection_from_fit(0.9, evidence=True) == 0.0
    drop = rec.injection_from_fit(0.1, evidence=True)
    w_slow, w_fast = 0.9 + 0.1 * (0.1 - 0.9), 0.9 + 0.5 * (0.1 - 0.9)
    assert drop == pytest.approx(1.0 - w_fast / w_slow)
    before = RecoveryState(**vars(rec.state))
    assert rec.injection_from_fit(0.0, evidence=False) == 0.0  # no evidence: nothing changes
    assert rec.state == before
    capped = Recovery(RecoveryConfig(alpha_fast=1.0, max_injection=0.2))
    capped.injection_from_fit(1.0, evidence=True)
    assert capped.injection_from_fit(0.0, evidence=True) == 0.2


def test_too_long_verdicts_count_and_confirm() -> None:
    rec = Recovery(RecoveryConfig(lost_fraction=0.3, global_after=2))
    rec.reset(10, global_start=True)
    assert rec.state.global_phase
    assert rec.state.unconfirmed
    assert rec.contradicted
    rec.state.global_phase = False
    rec.judge_track(0.5, 0.0)
    assert rec.state.lost_scans == 1
    assert rec.contradicted
    rec.judge_track(math.nan, 0.0)  # no evidence: neither raised nor reset
    assert rec.state.lost_scans == 1
    rec.judge_track(0.1, 0.0)
    assert rec.state.lost_scans == 0
    assert rec.state.passed == 1
    assert rec.state.unconfirmed
    rec.judge_track(0.1, 0.0)
    assert not rec.state.unconfirmed
    assert not rec.contradicted
    assert rec.wide_search() == (True, False)  # a reset by the fit searches far, no table


def test_in_doubt_while_contradicted_or_not_yet_confirmed() -> None:
    rec = Recovery(RecoveryConfig(lost_fraction=0.3, global_after=2))
    rec.reset(10)
    assert not rec.in_doubt  # a known start
    rec.judge_track(0.5, 0.0)
    assert rec.in_doubt  # readings through walls
    rec.judge_track(0.1, 0.0)
    assert not rec.in_doubt
    rec.state.new_track = True  # a far recovery, not yet confirmed
    assert rec.in_doubt
    rec.judge_track(0.1, 0.0)
    rec.judge_track(0.1, 0.0)
    assert not rec.in_doubt
    rec.reset(10, global_start=True)
    rec.state.global_phase = False
    assert rec.in_doubt  # from global localization, unconfirmed


def test_verification_schedule() -> None:
    rec = Recovery(RecoveryConfig(verify_period=5.0, verify_margin=0.5))
    assert rec.verification_due(0.0)
    assert not rec.verified(0.0, 0.2)
    assert not rec.verification_due(4.0)
    assert rec.verification_due(5.0)
    assert rec.verified(5.0, 0.8)  # a clearly better place: suspect, and verified every scan
    assert rec.verification_due(5.5)
    assert not rec.verified(5.5, 0.0)
    rec.state.recovered = True  # a guess became the track: verified for verify_period seconds
    assert rec.verification_due(6.0)
    assert rec.state.verify_until == 11.0
    assert not Recovery(RecoveryConfig(blind_after=None)).verification_due(0.0)  # both None: never


def test_a_blind_track_is_verified() -> None:
    # No periodic verification (the default), but a track that no scan has judged for blind_after
    # seconds (too few readings reach its walls: a robot carried off among visitors reads short
    # everywhere at its old place) is verified, and again every blind_after seconds while blind.
    rec = Recovery(RecoveryConfig(blind_after=5.0))
    rec.judge_track(0.0, 0.0)
    assert not rec.verification_due(0.0)
    rec.judge_track(0.1, 4.0)  # judged: the clock starts again
    rec.judge_track(math.nan, 8.0)
    assert not rec.verification_due(8.0)
    rec.judge_track(math.nan, 9.0)
    assert rec.verification_due(9.0)  # 5 s since the last scan that judged the track
    assert not rec.verified(9.0, 0.2)  # nothing clearly better: the track stands
    rec.judge_track(math.nan, 10.0)
    assert not rec.verification_due(10.0)
    rec.judge_track(math.nan, 14.0)
    assert rec.verification_due(14.0)  # still blind 5 s after that verification
    assert rec.verified(14.0, 0.8)  # a clearly better place: suspect, verified every scan
    rec.judge_track(math.nan, 15.0)
    assert rec.verification_due(15.0)
    never = Recovery(RecoveryConfig(blind_after=None))
    never.judge_track(math.nan, 0.0)
    never.judge_track(math.nan, 100.0)
    assert not never.verification_due(100.0)


@dataclass
class _Scene:
    """A crowded scan at ``truth[4]`` and a belief of three groups: the established track
    (turned around and moved by a metre when lost, else moved 1.5 m along the robot's way),
    guesses at the true pose with almost no weight, and guesses at a decoy 2.6 m away holding
    most of the weight, as the likelihood field gives it to a look-alike place in a crowd."""

    mcl: MonteCarloLocalization
    recovery: Recovery
    samples: np.ndarray
    weights: np.ndarray
    track: np.ndarray
    near: np.ndarray
    far: np.ndarray
    ranges: np.ndarray
    valid: np.ndarray
    truth: np.ndarray
    geometry: LaserGeometry

    def judge(self, p: np.ndarray, others: np.ndarray | None = None) -> float:
        poses = p[None, :] if others is None else np.vstack([p[None, :], others])
        rec = self.mcl.config.recovery
        return self.mcl.sensor.too_long_fraction(
            poses, self.ranges, self.geometry, self.valid, rec.lost_margin, rec.lost_min_beams
        )

    def score(self, poses: np.ndarray) -> np.ndarray:
        return self.mcl.sensor.crowd_log_likelihood(poses, self.ranges, self.geometry, self.valid)

    def step(self, judge: Judge | None = None) -> np.ndarray:
        """One scan's recovery as the update runs it; returns the estimate."""
        j = self.judge if judge is None else judge
        b = self.mcl.config.sampling.kld_bin
        labels = cluster_bins(self.samples, b[0], b[2])
        est = self.recovery.established_weights(self.weights)
        pose = best_cluster_estimate(self.samples, est, labels)[0]
        too_long = j(pose, None)
        self.recovery.judge_track(too_long, 0.0)
        decision = self.recovery.arbitrate(
            self.samples, self.weights, labels, pose, too_long, self.score, j, int(self.valid.sum())
        )
        if decision.weights is not None:
            self.weights = decision.weights
        if decision.became_track:
            pose = best_cluster_estimate(self.samples, self.weights, labels)[0]
        return pose


def _scene(room: OccupancyGrid, lost_track: bool) -> _Scene:
    truth = waypoints_path(10)
    crowded = simulate(room, truth, seed=27, circles=crowd_around(truth, np.random.default_rng(27), 10))
    scan = crowded.scans[4]
    r = np.asarray(scan.ranges)
    valid = r < scan.geometry.max_range
    mcl = MonteCarloLocalization(room, tuned(300, 100), seed=28)
    wrong = compose(truth[4], np.array([0.5, -0.4, 2.7] if lost_track else [1.5, 0.0, 0.0]))
    decoy = np.array([4.69, 4.07, 2.29])  # a look-alike: no wall seen through, the truth explains more
    jitter = np.random.default_rng(29).normal(0.0, [0.02, 0.02, 0.01], (300, 3))
    samples = (
        np.vstack([np.tile(wrong, (200, 1)), np.tile(truth[4], (50, 1)), np.tile(decoy, (50, 1))]) + jitter
    )
    track, near, far = (np.arange(300) < 200), (np.arange(300) // 50 == 4), (np.arange(300) >= 250)
    weights = np.where(track, 0.5 / 200, np.where(near, 1e-9, 0.5 / 50))
    recovery = Recovery(mcl.config.recovery, 300)
    recovery.fresh = ~track
    return _Scene(
        mcl, recovery, samples, weights / weights.sum(), track, near, far, r, valid, truth[4], scan.geometry
    )


def test_a_recovery_guess_is_chosen_by_the_crowd_beam_model_and_must_win_twice(room: OccupancyGrid) -> None:
    # The scan contradicts the track (it sees through walls there). Of the two guesses, the one
    # at the true pose explains the scan under the crowd beam model, though the weights favour
    # the decoy: the true one wins the scan and is held (the decoy loses its weight), and
    # becomes the track only when it wins again. The track is turned around from the truth, more
    # than the odometry could have turned since the last agreement: the guess must also wait
    # until the track has been contradicted on global_after scans in a row.
    sc = _scene(room, lost_track=True)
    rec = sc.mcl.config.recovery
    assert sc.judge(sc.samples[0]) > rec.lost_fraction
    ll = sc.score(np.stack([sc.truth, sc.samples[260], sc.samples[0]]))
    assert ll[0] > ll[1] > ll[2]  # the decoy too explains the scan better than the lost track
    assert sc.judge(sc.samples[260], sc.samples[sc.far][:8]) <= rec.lost_fraction
    pose = sc.step()
    assert np.hypot(*(pose[:2] - sc.samples[0, :2])) < 0.1  # still the track after one win
    assert sc.recovery.state.guess_wins == 1
    assert sc.recovery.held[sc.near].all()
    assert not sc.recovery.held[sc.track | sc.far].any()
    assert sc.weights[sc.far].sum() == 0.0  # the losing guess is dropped
    for _ in range(rec.global_after - 2):
        pose = sc.step()  # won again, but not consistent with the odometry yet: held
        assert np.hypot(*(pose[:2] - sc.samples[0, :2])) < 0.1
        assert sc.recovery.held[sc.near].all()
    assert sc.recovery.state.lost_scans == rec.global_after - 1
    pose = sc.step()  # the next scan says the same: the track is lost, found again
    assert np.hypot(*(pose[:2] - sc.truth[:2])) < 0.1
    assert not sc.recovery.fresh.any()
    assert sc.recovery.state.recovered


def test_a_guess_consistent_with_the_odometry_replaces_a_contradicted_track_after_two_wins(
    room: OccupancyGrid,
) -> None:
    # The same scene with the track 1.5 m behind the truth on the robot's way: after 10 m of
    # odometry since the last agreement that is within the odometry's reach (verify_distance
    # plus odometry_drift of the path), so two wins are enough; right after an agreement it is
    # not, and the guess is held until the track has been contradicted global_after times.
    for travelled, wins_needed in ((10.0, 2), (0.0, RecoveryConfig().global_after)):
        sc = _scene(room, lost_track=True)
        wrong = compose(sc.truth, np.array([-1.5, 0.0, 0.1]))
        sc.samples[sc.track] = wrong + np.random.default_rng(3).normal(0.0, [0.02, 0.02, 0.01], (200, 3))
        assert sc.judge(sc.samples[0]) > sc.mcl.config.recovery.lost_fraction  # contradicted
        sc.recovery.moved(travelled, 0.0)
        for _ in range(wins_needed - 1):
            pose = sc.step()
            assert np.hypot(*(pose[:2] - wrong[:2])) < 0.1, travelled
        pose = sc.step()
        assert np.hypot(*(pose[:2] - sc.truth[:2])) < 0.1, travelled


def test_a_track_that_explains_the_scan_is_never_dropped_for_a_far_guess(room: OccupancyGrid) -> None:
    # issue 22: novelty MCL jumped metres away from a good track. Moved along its way, a track
    # passes the too-long test (a crowd excuses the short side): it explains the scan, and a
    # guess at another place that scores better by far more than the verification's margin per
    # return still never replaces it, however many scans it wins.
    sc = _scene(room, lost_track=False)

    def unsuspecting(p: np.ndarray, others: np.ndarray | None = None) -> float:
        return 0.0 if others is None else sc.judge(p, others)  # the track passes the too-long test

    gain = sc.score(sc.truth[None])[0] - sc.score(sc.samples[:1])[0]
    assert gain > 2 * sc.mcl.config.recovery.verify_margin * int(sc.valid.sum())
    for _ in range(5):
        pose = sc.step(unsuspecting)
        assert np.hypot(*(pose[:2] - sc.samples[0, :2])) < 0.1
        assert sc.recovery.state.guess_wins == 0
        assert not sc.recovery.held.any()


def test_a_track_a_recovery_just_made_is_no_good_track_yet(room: OccupancyGrid) -> None:
    # A recovery guess may be wrong though it passes the too-long test (a look-alike place):
    # until it has passed on global_after scans in a row, a guess at another place that explains
    # the scan better by more than the verification's margin per return replaces it.
    sc = _scene(room, lost_track=False)
    sc.recovery.state.new_track = True

    def unsuspecting(p: np.ndarray, others: np.ndarray | None = None) -> float:
        return 0.0 if others is None else sc.judge(p, others)

    sc.step(unsuspecting)
    assert sc.recovery.state.guess_wins == 1
    assert sc.recovery.held[sc.near].all()
    pose = sc.step(unsuspecting)
    assert np.hypot(*(pose[:2] - sc.truth[:2])) < 0.1
    assert sc.recovery.state.new_track  # the new track in turn must pass global_after times
    sc = _scene(room, lost_track=False)
    sc.recovery.state.new_track = True
    sc.samples[~sc.track] = sc.samples[0] + np.array([0.3, 0.0, 0.0])  # guesses at its own place
    sc.step(unsuspecting)
    assert sc.recovery.state.guess_wins == 0
    for _ in range(sc.mcl.config.recovery.global_after):
        sc.recovery.judge_track(0.0, 0.0)
    assert not sc.recovery.state.new_track  # confirmed: a good track from now on


def test_a_guess_far_from_a_contradicted_track_needs_clear_wins_and_a_lasting_contradiction(
    room: OccupancyGrid,
) -> None:
    # The scene's decoy, 2.6 m from the truth, as the only guess beside a track at the truth that
    # glass makes fail the too-long test: the guess is further than the odometry can have drifted
    # since the last agreement. Winning by a little it is held, never taken; winning by far more
    # than verify_margin per return it replaces the track once the track has been contradicted
    # on global_after scans in a row (a robot carried off).
    rec = RecoveryConfig()
    for lead, taken_at in ((1.0, None), (1000.0, rec.global_after)):
        sc = _scene(room, lost_track=True)
        sc.samples[sc.track] = sc.truth + np.random.default_rng(4).normal(0.0, [0.02, 0.02, 0.01], (200, 3))
        sc.weights = np.where(sc.far, 1.0, np.where(sc.track, 1e-3, 0.0))
        sc.weights /= sc.weights.sum()
        sc.recovery.fresh = sc.far.copy()
        decoy = sc.samples[260].copy()

        def glass(p: np.ndarray, others: np.ndarray | None = None) -> float:  # noqa: ARG001
            return 0.5 if others is None else 0.0  # the track fails the too-long test, the guess passes

        def toward_decoy(poses: np.ndarray, lead: float = lead, decoy: np.ndarray = decoy) -> np.ndarray:
            return -lead * np.hypot(poses[:, 0] - decoy[0], poses[:, 1] - decoy[1])

        sc.score = toward_decoy  # type: ignore[method-assign]
        for k in range(1, 2 * rec.global_after):
            pose = sc.step(glass)
            taken = taken_at is not None and k >= taken_at
            assert np.hypot(*(pose[:2] - (decoy if taken else sc.truth)[:2])) < 0.1, (lead, k)
            if taken:
                break
            assert sc.recovery.state.guess_wins == k


def test_a_far_look_alike_never_beats_a_track_that_a_nearby_pose_corrects(room: OccupancyGrid) -> None:
    # issue 22, Freiburg 079: the track's heading drifts 15 deg off, its long beams see through
    # walls for five scans, and a look-alike 13 m away explains the scan far better than the
    # track. A pose near the track, at the right heading, explains it better still: the far guess
    # stays held and the track is corrected where it is.
    rec = RecoveryConfig()
    sc = _scene(room, lost_track=True)
    off = sc.truth + np.array([0.0, 0.0, 0.26])
    sc.samples[sc.track] = off + np.random.default_rng(5).normal(0.0, [0.02, 0.02, 0.01], (200, 3))
    sc.weights = np.where(sc.far, 1.0, np.where(sc.track, 1e-3, 0.0))
    sc.weights /= sc.weights.sum()
    sc.recovery.fresh = sc.far.copy()
    decoy, truth = sc.samples[260].copy(), sc.truth.copy()

    def glass(p: np.ndarray, others: np.ndarray | None = None) -> float:  # noqa: ARG001
        return 0.5 if others is None else 0.0

    def two_places(poses: np.ndarray) -> np.ndarray:
        def dist(q: np.ndarray) -> np.ndarray:
            return np.hypot(poses[:, 0] - q[0], poses[:, 1] - q[1]) + np.abs(wrap_angle(poses[:, 2] - q[2]))

        return np.maximum(-1000.0 * dist(truth), -1000.0 * dist(decoy) - 20.0)

    sc.score = two_places  # type: ignore[method-assign]
    assert two_places(np.stack([decoy]))[0] - two_places(off[None])[0] > 2 * rec.verify_margin * int(
        sc.valid.sum()
    )
    for _ in range(2 * rec.global_after):
        pose = sc.step(glass)
        assert np.hypot(*(pose[:2] - truth[:2])) < 0.1
    assert sc.recovery.state.clear_wins >= rec.fresh_wins  # held, never taken
    assert sc.recovery.held[sc.far].all()


def test_a_guess_may_see_through_fewer_walls_than_the_track_it_replaces(room: OccupancyGrid) -> None:
    # Where the map and the building disagree (glass, corners) the true pose too fails the
    # too-long test now and then: a guess the test contradicts may still replace a track that it
    # contradicts more, never one that it contradicts less.
    sc = _scene(room, lost_track=True)
    b = sc.mcl.config.sampling.kld_bin
    labels = cluster_bins(sc.samples, b[0], b[2])
    n = int(sc.valid.sum())

    def glassy(p: np.ndarray, others: np.ndarray | None = None) -> float:  # noqa: ARG001
        return 0.35  # every guess sees through a few glass walls

    args = (sc.samples, sc.weights, labels, sc.samples[0], sc.score)
    won = sc.recovery.best_guess(*args, glassy, True, 0.8, n)
    assert won is not None
    assert won[sc.near].all()
    assert sc.recovery.best_guess(*args, glassy, True, 0.3, n) is None
    assert sc.recovery.best_guess(*args, sc.judge, True, math.nan, n) is not None


def test_a_scan_that_is_no_evidence_neither_confirms_nor_contradicts(room: OccupancyGrid) -> None:
    # Too few returns to judge (NaN) says nothing about the track nor about the guesses: none
    # wins such a scan, even against a track contradicted on the scans before, and the lost
    # count is neither raised nor reset.
    sc = _scene(room, lost_track=True)

    def blind(p: np.ndarray, others: np.ndarray | None = None) -> float:  # noqa: ARG001
        return math.nan

    sc.recovery.state.lost_scans = 1
    weights = sc.weights.copy()
    sc.step(blind)
    assert sc.recovery.state.guess_wins == 0
    assert not sc.recovery.held.any()
    assert sc.recovery.state.lost_scans == 1
    np.testing.assert_array_equal(sc.weights, weights)
    # A guess held since a scan with evidence stays held through one without, and becomes the
    # track when it wins the next scan with evidence.
    sc.step()
    assert sc.recovery.state.guess_wins == 1
    assert sc.recovery.held[sc.near].all()
    lost = sc.recovery.state.lost_scans
    pose = sc.step(blind)
    assert sc.recovery.state.guess_wins == 1
    assert sc.recovery.held[sc.near].all()
    assert sc.recovery.state.lost_scans == lost
    assert np.hypot(*(pose[:2] - sc.samples[0, :2])) < 0.1  # still the old track
    pose = sc.step()
    assert np.hypot(*(pose[:2] - sc.truth[:2])) < 0.1
    assert not sc.recovery.fresh.any()
    assert sc.weights[sc.far].sum() == 0.0
    # A failed verification judged every return of its scan: it still contradicts the track.
    sc = _scene(room, lost_track=True)
    sc.recovery.state.suspect = True
    sc.step(blind)
    assert sc.recovery.state.guess_wins == 1
    assert sc.recovery.held[sc.near].all()


def test_guesses_are_left_out_of_the_established_weights() -> None:
    rec = Recovery(RecoveryConfig(), 4)
    w = np.array([0.1, 0.2, 0.3, 0.4])
    np.testing.assert_array_equal(rec.established_weights(w), w)
    rec.fresh = np.array([False, True, False, True])
    np.testing.assert_array_equal(rec.established_weights(w), [0.1, 0.0, 0.3, 0.0])
    rec.fresh[:] = True  # nothing else left: all of them
    np.testing.assert_array_equal(rec.established_weights(w), w)
    rec.match(6)
    assert rec.fresh.shape == rec.held.shape == (6,)
    assert not rec.fresh.any()
