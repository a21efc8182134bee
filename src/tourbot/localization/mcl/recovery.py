"""Recovery of Monte Carlo localization from a wrong track, with its state in one typed object.

Augmented MCL (Thrun, Burgard & Fox, *Probabilistic Robotics*, Table 8.3) with sensor resetting
(Lenser & Veloso 2000): a short- and a long-term average of how well the best sample explains the
scan; when the short one falls below ``ratio`` times the long one, scan-drawn samples are
injected, but only while the track is in doubt (:attr:`Recovery.in_doubt`; the book injects
whenever the short one is lower, on most scans, each a reset search here for guesses that could
not win). A second sign of a wrong track is the one Fox et al. 1998 point to: readings *too long*
for the map (visitors only ever shorten a beam). Injected samples are *guesses* (fresh) until one
of them has beaten the track on ``fresh_wins`` scans in a row, judged by the crowd beam model
(Probabilistic Robotics Table 6.1); the guess that wins a scan is *held* and must win the next one.

A guess never replaces a good track that explains the scan (passes the too-long test; a track
is good once it has passed on ``global_after`` scans in a row, from a known start): a crowd only
shortens beams, so such a track is consistent with the scan, and a jump away from it would be a
jump the odometry does not show. While the track is contradicted, a guess must also be consistent
with the odometry since the last scan the track explained (the *agreement*): within
``verify_distance`` plus ``odometry_drift`` of the odometry's path since then. A guess anywhere
else (the robot was carried, or the odometry failed) replaces only a track contradicted on
``global_after`` judged scans in a row, and only once it has explained the scan better than the
track by ``verify_margin`` nats per return on ``fresh_wins`` scans in a row.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import wrap_angle
from tourbot.localization.mcl.clustering import best_cluster_estimate, weighted_mean_cov
from tourbot.localization.mcl.config import RecoveryConfig

__all__ = ["Arbitration", "Recovery", "RecoveryState", "local_lattice"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]
Judge = Callable[[FloatArray, FloatArray | None], float]
Score = Callable[[FloatArray], FloatArray]


@dataclass
class RecoveryState:
    """Everything recovery remembers between scans (reset as a whole by :meth:`Recovery.reset`).

    - ``w_slow``, ``w_fast``: augmented MCL's long- and short-term averages of the fit (0: none yet).
    - ``lost_scans``: consecutive judged scans whose track had readings through mapped walls.
    - ``passed``: consecutive judged scans whose track passed that test.
    - ``global_phase``: from a global start until one cluster holds the belief.
    - ``unconfirmed``: a track from global localization that has not yet passed the too-long test
      on ``global_after`` judged scans in a row (it is searched for over the whole free space).
    - ``suspect``: the last verification found a clearly better place than the track.
    - ``recovered``: a recovery guess became the track on the last scan.
    - ``next_verify``: scan time of the next periodic verification.
    - ``verify_until``: until this scan time every scan is verified (after a recovery).
    - ``guess_wins``: consecutive scans on which the held guess beat the track.
    - ``clear_wins``: of those, the last consecutive ones it won by ``verify_margin`` per return.
    - ``new_track``: a recovery guess became the track and it has not yet passed the too-long
      test on ``global_after`` judged scans in a row (it is no good track yet).
    - ``odom_path``, ``odom_turn``: the odometry's travel (m) and turning (rad) since the last
      judged scan whose track passed the too-long test (the last agreement).
    - ``seen_at``: scan time of the last scan that judged the track, or of the last verification
      of a blind track (NaN: none yet).
    """

    w_slow: float = 0.0
    w_fast: float = 0.0
    lost_scans: int = 0
    passed: int = 0
    global_phase: bool = False
    unconfirmed: bool = False
    suspect: bool = False
    recovered: bool = False
    next_verify: float = -math.inf
    verify_until: float = -math.inf
    guess_wins: int = 0
    clear_wins: int = 0
    new_track: bool = False
    odom_path: float = 0.0
    odom_turn: float = 0.0
    seen_at: float = math.nan


@dataclass(frozen=True)
class Arbitration:
    """What :meth:`Recovery.arbitrate` decided on a scan: the new ``weights`` (None: unchanged)
    and whether a guess ``became_track``."""

    weights: FloatArray | None
    became_track: bool


def local_lattice(
    pose: FloatArray, bound: tuple[float, float], step: float = 0.25, turn: float = math.radians(3.0)
) -> FloatArray:
    """Poses around ``pose`` ``(3,)``: a ``step`` lattice of positions within ``min(bound[0],
    0.5)`` metres, each at headings ``turn`` apart within ``bound[1]`` radians."""
    r = min(bound[0], 0.5)
    k, m = int(r // step), int(bound[1] // turn)
    d = np.arange(-k, k + 1) * step
    dx, dy, dt = np.meshgrid(d, d, np.arange(-m, m + 1) * turn, indexing="ij")
    keep = np.hypot(dx, dy) <= r + 1e-9
    c, sn = math.cos(pose[2]), math.sin(pose[2])
    out = np.empty((int(keep.sum()), 3))
    out[:, 0] = pose[0] + c * dx[keep] - sn * dy[keep]
    out[:, 1] = pose[1] + sn * dx[keep] + c * dy[keep]
    out[:, 2] = wrap_angle(pose[2] + dt[keep])
    return out


class Recovery:
    """The recovery state of one filter and its rules. ``fresh`` and ``held`` ``(N,)`` mark the
    samples that are guesses and the guess that won the last scan; ``state`` is the rest."""

    def __init__(self, config: RecoveryConfig, n: int = 0) -> None:
        self.config = config
        self.state = RecoveryState()
        self.fresh: BoolArray = np.zeros(n, dtype=bool)
        self.held: BoolArray = np.zeros(n, dtype=bool)
        self._gain = -math.inf  # the last best guess's lead over the track, nats per return
        self._margin = math.inf  # the last scan's margin, nats

    # ------------------------------------------------------------------ state

    def reset(self, n: int, *, global_start: bool = False) -> None:
        """Forget everything: a new belief of ``n`` samples (``global_start``: spread over the map)."""
        self.state = RecoveryState(global_phase=global_start, unconfirmed=global_start)
        self.fresh = np.zeros(n, dtype=bool)
        self.held = np.zeros(n, dtype=bool)

    def clear_guesses(self, n: int) -> None:
        """No sample is a guess (a new belief of ``n`` samples that keeps the state)."""
        self.fresh = np.zeros(n, dtype=bool)
        self.held = np.zeros(n, dtype=bool)

    def match(self, n: int) -> None:
        """Marks of the right length after the belief was set from outside (none is a guess)."""
        if self.fresh.shape != (n,):
            self.fresh = np.zeros(n, dtype=bool)
        if self.held.shape != (n,):
            self.held = np.zeros(n, dtype=bool)

    @property
    def contradicted(self) -> bool:
        """Whether the track stands contradicted: global localization, readings through walls on
        the last judged scan, or a failed verification."""
        s = self.state
        return s.global_phase or s.lost_scans > 0 or s.suspect

    @property
    def in_doubt(self) -> bool:
        """Whether a guess may compete with the track now (:meth:`best_guess` judges guesses only
        then): the track stands :attr:`contradicted`, or it comes from global localization or a
        far recovery and is not yet confirmed. Augmented MCL injects only then: a guess drawn
        while the track explains the scan cannot win while it does, and the scan that contradicts
        the track draws ``max_injection`` guesses of its own."""
        s = self.state
        return self.contradicted or s.unconfirmed or s.new_track

    def established_weights(self, weights: FloatArray) -> FloatArray:
        """``weights`` with the guesses' set to zero (all of them if nothing else is left)."""
        if not self.fresh.any():
            return weights
        w = np.where(self.fresh, 0.0, weights)
        return w if w.sum() > 0 else weights

    # ------------------------------------------------------------------ augmented MCL

    def injection_from_fit(self, fit: float, evidence: bool) -> float:
        """Augmented MCL (PR Table 8.3): update the averages with this scan's ``fit`` (when it is
        ``evidence``) and return the fraction of samples to replace, at most ``max_injection``."""
        cfg, s = self.config, self.state
        if not evidence:
            return 0.0  # too few beams to judge the fit (a crowd all around)
        if s.w_slow == 0.0:
            s.w_slow = s.w_fast = fit
        else:
            s.w_slow += cfg.alpha_slow * (fit - s.w_slow)
            s.w_fast += cfg.alpha_fast * (fit - s.w_fast)
        ratio = s.w_fast / (cfg.ratio * s.w_slow) if s.w_slow > 0 else 1.0
        return min(cfg.max_injection, max(0.0, 1.0 - ratio))

    def judge_track(self, too_long: float, t: float) -> None:
        """Count the too-long test's verdict on the track at scan time ``t`` (NaN: no evidence,
        nothing changes but the time the track has gone unjudged)."""
        cfg, s = self.config, self.state
        if math.isnan(s.seen_at):
            s.seen_at = t
        if math.isnan(too_long):
            return
        s.seen_at = t
        if too_long > cfg.lost_fraction:
            s.lost_scans += 1
            s.passed = 0
        else:
            s.lost_scans = 0
            s.passed += 1
            s.unconfirmed = s.unconfirmed and s.passed < cfg.global_after
            s.new_track = s.new_track and s.passed < cfg.global_after
            s.odom_path = s.odom_turn = 0.0  # the track and the odometry agree here

    def moved(self, trans: float, turn: float) -> None:
        """The odometry moved by ``trans`` metres and turned by ``turn`` radians since the last scan."""
        self.state.odom_path += abs(trans)
        self.state.odom_turn += abs(turn)

    @property
    def bound(self) -> tuple[float, float] | None:
        """How far (m, rad) from the track a guess may be and still be consistent with the
        odometry since the last agreement; None: anywhere (global localization, a track from it
        or from a recovery not yet confirmed, a failed verification)."""
        cfg, s = self.config, self.state
        if s.global_phase or s.unconfirmed or s.new_track or s.suspect:
            return None
        drift_m, drift_rad = cfg.odometry_drift
        return (
            cfg.verify_distance[0] + drift_m * s.odom_path,
            cfg.verify_distance[1] + drift_rad * s.odom_turn,
        )

    # ------------------------------------------------------------------ verification

    def verification_due(self, t: float) -> bool:
        """Whether the scan at time ``t`` verifies the track: while the last verification failed;
        when the track has gone ``blind_after`` seconds without a scan that judged it (and again
        every ``blind_after`` seconds while it stays so); and, with ``verify_period`` set,
        periodically and for ``verify_period`` seconds after a recovery guess became the track.

        A blind track is one whose readings do not reach its walls: the too-long test has no
        evidence on it. People all around hide the walls, or the track stands where the walls are
        not: a robot carried off among visitors reads short everywhere at its old place, no
        reading passes through a wall there, and no other test would ever contradict it."""
        cfg, s = self.config, self.state
        blind = cfg.blind_after is not None and not math.isnan(s.seen_at) and t - s.seen_at >= cfg.blind_after
        if blind:
            s.seen_at = t
        period = cfg.verify_period
        if period is None:
            s.recovered = False
            return blind or s.suspect
        if s.recovered:
            s.verify_until = t + period
        s.recovered = False
        return blind or s.suspect or t >= s.next_verify or t < s.verify_until

    def verified(self, t: float, margin: float) -> bool:
        """Record a verification at ``t`` whose best alternative beat the track by ``margin`` nats
        per return; returns whether the track is now suspect."""
        s, period = self.state, self.config.verify_period
        if period is not None:
            s.next_verify = t + period
        s.suspect = margin > self.config.verify_margin
        return s.suspect

    # ------------------------------------------------------------------ guesses

    def arbitrate(
        self,
        samples: FloatArray,
        weights: FloatArray,
        labels: IntArray,
        track: FloatArray,
        too_long: float,
        score: Score,
        judge: Judge,
        n_returns: int,
    ) -> Arbitration:
        """Let the guesses compete with the ``track`` on this scan (``too_long``: its too-long
        fraction, NaN when not judged).

        Guesses in the track's own cluster on a scan that does not contradict it join it. On a
        scan that is no evidence (``too_long`` NaN and no failed verification) no guess is judged.
        Otherwise the best guess (:meth:`best_guess`; during global localization
        :meth:`heaviest_guess`) wins the scan; when the same guess has won ``fresh_wins`` scans
        in a row and is :meth:`consistent` with the odometry, its samples become the belief
        (the other samples lose their weight, every sample is established); a guess that won
        fewer, or is not yet consistent, is held (the other guesses lose their weight)."""
        cfg, s = self.config, self.state
        contradicted = self.contradicted
        if self.fresh.any() and not contradicted:
            mine = int(np.argmax(np.bincount(labels, weights=self.established_weights(weights))))
            self.fresh &= labels != mine
        if math.isnan(too_long) and not (s.global_phase or s.suspect):
            return Arbitration(None, False)
        guess: BoolArray | None = None
        if s.global_phase and self.fresh.any():
            guess = self.heaviest_guess(samples, weights, labels, track, score)
            s.guess_wins = s.guess_wins + 1 if guess is not None else 0
        elif self.fresh.any():
            guess = self.best_guess(
                samples, weights, labels, track, score, judge, contradicted, too_long, n_returns
            )
            same = guess is not None and bool((guess & self.held).any())
            s.guess_wins = 0 if guess is None else s.guess_wins + 1 if same else 1
            clear = guess is not None and self._gain > cfg.verify_margin
            s.clear_wins = 0 if not clear else s.clear_wins + 1 if same else 1
        else:
            s.guess_wins = s.clear_wins = 0
        self.held = np.zeros(self.fresh.shape, dtype=bool)
        if (
            guess is not None
            and s.guess_wins >= cfg.fresh_wins
            and self.consistent(samples, weights, guess, track, score)
        ):
            # The guess's own samples: the track's, when it shares their cluster (a guess near
            # it, at a better heading), would hold the estimate where the track was.
            w = np.where(guess, weights, 0.0)
            new = w / w.sum() if w.sum() > 0 else guess / guess.sum()
            self.fresh[:] = False
            s.guess_wins = s.clear_wins = 0
            s.suspect = cfg.verify_period is not None  # verify the new track on this scan already
            s.recovered = True
            if not self.within_bound(samples, weights, guess, track):
                s.new_track, s.passed = True, 0  # a far recovery: no good track until it passes
            return Arbitration(np.asarray(new, dtype=np.float64), True)
        if guess is not None and not s.global_phase:
            w = np.where(self.fresh & ~guess, 0.0, weights)
            if not w[guess].sum() > 0:
                w[guess] = w.sum() / guess.sum() if w.sum() > 0 else 1.0
            self.held = guess
            return Arbitration(w / w.sum(), False)
        return Arbitration(None, False)

    def consistent(
        self,
        samples: FloatArray,
        weights: FloatArray,
        guess: BoolArray,
        track: FloatArray,
        score: Score | None = None,
    ) -> bool:
        """Whether the ``guess`` may replace the ``track`` as far as the odometry goes: its
        samples' weighted mean lies within the odometry's :attr:`bound` of the track, or the
        track has been contradicted on ``global_after`` scans in a row, the guess has won the
        last ``fresh_wins`` of them by ``verify_margin`` nats per return, and (given ``score``)
        it beats by that margin every pose of a small lattice within the bound around the track
        too (:func:`local_lattice`): a far look-alike never wins against a track that a nearby
        pose would correct. A guess that is not may still win scans (it is held)."""
        cfg, s = self.config, self.state
        bound = self.bound
        if bound is None or self.within_bound(samples, weights, guess, track):
            return True
        if s.lost_scans < cfg.global_after or s.clear_wins < cfg.fresh_wins:
            return False
        if score is None:
            return True
        ll = score(np.vstack([self._mean(samples, weights, guess)[None, :], local_lattice(track, bound)]))
        return bool(ll[0] - ll[1:].max() > self._margin)

    def within_bound(
        self, samples: FloatArray, weights: FloatArray, guess: BoolArray, track: FloatArray
    ) -> bool:
        """Whether the ``guess`` samples' weighted mean lies within the odometry's :attr:`bound`
        of the ``track`` (False when there is no bound)."""
        bound = self.bound
        if bound is None:
            return False
        mean = self._mean(samples, weights, guess)
        return bool(
            math.hypot(mean[0] - track[0], mean[1] - track[1]) <= bound[0]
            and abs(float(wrap_angle(mean[2] - track[2]))) <= bound[1]
        )

    @staticmethod
    def _mean(samples: FloatArray, weights: FloatArray, mask: BoolArray) -> FloatArray:
        w = weights[mask]
        return weighted_mean_cov(samples[mask], w if w.sum() > 0 else np.ones(w.size))[0]

    def heaviest_guess(
        self, samples: FloatArray, weights: FloatArray, labels: IntArray, track: FloatArray, score: Score
    ) -> BoolArray | None:
        """During global localization: the samples of the heaviest cluster if guesses hold most
        of its weight, else those of the heaviest cluster of guesses if the crowd beam model
        (``score``) rates its mean above the ``track``; None otherwise."""
        fresh_w = np.where(self.fresh, weights, 0.0)
        w_fresh = np.bincount(labels, weights=fresh_w)
        w_old = np.bincount(labels, weights=weights - fresh_w, minlength=w_fresh.size)
        best = int(np.argmax(w_fresh + w_old))
        if w_fresh[best] > w_old[best]:
            return labels == best
        guess = int(np.argmax(w_fresh))
        if not w_fresh[guess] > 0:
            return None
        mine = labels == guess
        f_pose = best_cluster_estimate(samples[mine], weights[mine], np.zeros(int(mine.sum()), np.int64))[0]
        ll = score(np.stack([f_pose, track]))
        return mine if ll[0] > ll[1] else None

    def best_guess(
        self,
        samples: FloatArray,
        weights: FloatArray,
        labels: IntArray,
        track: FloatArray,
        score: Score,
        judge: Judge,
        contradicted: bool,
        track_too_long: float,
        n_returns: int,
    ) -> BoolArray | None:
        """The guesses' samples of the best guess, if it beats the ``track``.

        Guesses are the clusters of weighted guesses, judged at their weighted means by ``score``
        (the crowd beam model) beside the track. When the track is ``contradicted`` a guess wins
        by scoring above it. A track that is not contradicted explains the scan and no guess
        replaces it, unless it comes from global localization or a recovery and is not yet
        confirmed (``global_after`` passes in a row): then only guesses at another place (beyond
        ``verify_distance``) are judged and one must beat the track by ``verify_margin`` nats
        per return (of ``n_returns``). A guess that the too-long
        test (``judge``, at its mean and its ``lost_hypotheses`` heaviest samples) contradicts
        cannot win unless the track's own fraction ``track_too_long`` is larger still. The held
        guess stays the guess if it passes and scores within the margin of the best."""
        cfg = self.config
        live = self.fresh & (weights > 0)
        if not live.any() or not (contradicted or self.state.unconfirmed or self.state.new_track):
            return None
        ids = np.unique(labels[live])
        means = np.empty((ids.size, 3))
        for k, c in enumerate(ids.tolist()):
            mine = live & (labels == c)
            means[k] = weighted_mean_cov(samples[mine], weights[mine])[0]
        judged = np.ones(ids.size, dtype=bool)
        if not contradicted:
            judged = (np.hypot(means[:, 0] - track[0], means[:, 1] - track[1]) > cfg.verify_distance[0]) | (
                np.abs(wrap_angle(means[:, 2] - track[2])) > cfg.verify_distance[1]
            )
        if not judged.any():
            return None
        ids, means = ids[judged], means[judged]
        ll = score(np.vstack([means, track[None, :]]))
        margin = cfg.verify_margin * n_returns
        need = 0.0 if contradicted else margin
        held = np.isin(ids, labels[self.held & live])
        best: int | None = None
        for k in np.argsort(-ll[:-1], kind="stable").tolist():
            if not ll[k] - ll[-1] > need or (best is not None and not held[k]):
                continue
            mine = live & (labels == int(ids[k]))
            heaviest = np.flatnonzero(mine)[np.argsort(-weights[mine], kind="stable")[: cfg.lost_hypotheses]]
            too_long = judge(means[k], samples[heaviest])
            if too_long > cfg.lost_fraction and not too_long < track_too_long:  # NaN: no evidence
                continue
            if held[k] and (best is None or ll[k] >= ll[best] - margin):
                best = k
                break
            if best is None:
                best = k
                if not held.any():
                    break
        self._gain = -math.inf if best is None else float(ll[best] - ll[-1]) / max(n_returns, 1)
        self._margin = margin
        return None if best is None else live & (labels == int(ids[best]))

    def wide_search(self) -> tuple[bool, bool]:
        """Where the next reset search looks: ``(far, table)``: over the whole free space (a track
        from global localization not yet confirmed, a reset by the fit while in doubt without
        readings through walls, or ``global_after`` contradicted scans in a row), and with the
        expected-range table (an unconfirmed track)."""
        s = self.state
        wide = s.unconfirmed
        far = wide or s.lost_scans == 0 or s.lost_scans >= self.config.global_after
        return far, wide
