"""Monte Carlo localization (Fox, Burgard, Dellaert & Thrun 1999) with the beam filters of Fox et al. 1998.

The belief ``Bel(l)`` of Markov localization (Fox et al. 1998, Eq. 1-2) is held as weighted
samples. One :meth:`MonteCarloLocalization.update` per scan: predict by the odometry motion model
(Probabilistic Robotics Table 5.6), select the beams by the entropy or novelty filter (Eq. 3-6),
weight by the sensor model, recover (augmented MCL, Probabilistic Robotics Table 8.3, with sensor
resetting), resample (low variance, Table 4.4, with KLD-sampling, Fox 2003) and estimate (the
heaviest cluster of samples).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.geometry import compose, relative, wrap_angle
from tourbot.localization.beam_filters import BeamFilter, entropy_filter, novelty_filter_cast
from tourbot.localization.errors import LocalizationError
from tourbot.localization.estimate import LocalizationEstimate
from tourbot.localization.mcl.clustering import best_cluster_estimate, cell_keys, cluster_bins
from tourbot.localization.mcl.config import MCLConfig
from tourbot.localization.mcl.kld import kld_sample_count
from tourbot.localization.mcl.recovery import Recovery
from tourbot.localization.mcl.search import ResetSearch, anneal_step
from tourbot.localization.mcl.sensor import (
    LaserSensorModel,
    PoseLikelihood,
    longest_returns,
    uniform_free_poses,
)
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import LaserGeometry, Scan
from tourbot.sampling import systematic_resample

__all__ = ["MonteCarloLocalization"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]
_LOG_FLOOR = -600.0  # the established samples' floor below the best guess (exp: 1e-261, a normal float)


@dataclass
class _Reading:
    """One scan as the steps of an update see it."""

    timestamp: float
    ranges: FloatArray
    geometry: LaserGeometry
    valid: BoolArray  # returns: finite, within the laser's range
    info: dict[str, float] = field(default_factory=dict)
    global_start: bool = False  # this scan starts a global localization

    @property
    def n_returns(self) -> int:
        return int(self.valid.sum())


@dataclass(frozen=True)
class _Track:
    """The heaviest cluster of established samples: the tracked estimate."""

    labels: IntArray
    pose: FloatArray
    cov: FloatArray
    weight: float


class MonteCarloLocalization:
    """Monte Carlo localization on an occupancy grid.

    Use: ``mcl = MonteCarloLocalization(grid, config, seed=0)``, then ``mcl.reset_tracking(pose)``
    or ``mcl.reset_global()``, then ``mcl.update(odom_pose, scan)`` for each scan in order (the
    odometry pose at the scan's time). ``samples`` ``(N, 3)`` and ``weights`` ``(N,)`` are the
    belief; ``recovery`` its recovery state. Other sensors enter as ``extra_likelihoods``
    (:class:`~tourbot.localization.mcl.sensor.PoseLikelihood`) added to every scan's weights, or
    at their own times by :meth:`weigh`; a changed map by :meth:`set_map`, candidate poses by
    :meth:`inject`.
    """

    def __init__(
        self,
        grid: OccupancyGrid,
        config: MCLConfig | None = None,
        seed: int | None = None,
        *,
        extra_likelihoods: list[PoseLikelihood] | tuple[PoseLikelihood, ...] = (),
    ) -> None:
        self.config = config or MCLConfig()
        self.rng = np.random.default_rng(seed)
        # The verification's searches draw from their own stream: a verification that passes
        # leaves the filter exactly as it would be without verifying.
        self._verify_rng = np.random.default_rng(None if seed is None else [seed, 1])
        self.sensor = LaserSensorModel(grid, self.config.sensor, self.config.recovery.model)
        self.search = ResetSearch(self.sensor, self.config)
        self.extra_likelihoods: list[PoseLikelihood] = list(extra_likelihoods)
        self.recovery = Recovery(self.config.recovery)
        self.samples: FloatArray = np.zeros((0, 3))
        self.weights: FloatArray = np.zeros(0)
        self.last_estimate: LocalizationEstimate | None = None
        self._odom: FloatArray | None = None
        self._global_start: tuple[OccupancyGrid, IntArray] | None = None
        self._offered: FloatArray = np.zeros((0, 3))

    @property
    def grid(self) -> OccupancyGrid:
        """The map the laser's sensor model uses."""
        return self.sensor.grid

    # ------------------------------------------------------------------ the seams

    def add_likelihood(self, likelihood: PoseLikelihood) -> None:
        """Add ``likelihood.log_likelihood(samples)`` to the laser's log weights from now on."""
        self.extra_likelihoods.append(likelihood)

    def set_map(self, grid: OccupancyGrid) -> None:
        """Localize on ``grid`` from now on (doors, furniture in their estimated states)."""
        self.sensor.set_map(grid)

    def weigh(self, odom_pose: ArrayLike, likelihood: PoseLikelihood) -> None:
        """Another sensor's measurement at its own time (an image of the ceiling camera): the
        samples move by the odometry to ``odom_pose`` (step 1) and their weights take
        ``likelihood.log_likelihood`` (step 3, Bayes' rule as for a scan); the next scan's update
        resamples. Ignored before the first scan of a global localization."""
        if self.samples.shape[0] == 0:
            raise LocalizationError("call reset_tracking(pose) or reset_global() before weigh()")
        if self._global_start is not None:
            return
        self._predict(np.asarray(odom_pose, dtype=np.float64).reshape(3))
        loglik = np.asarray(likelihood.log_likelihood(self.samples), dtype=np.float64).reshape(-1)
        self._reweigh(np.log(np.maximum(self.weights, 1e-300)) + loglik)

    def inject(self, poses: ArrayLike) -> None:
        """Offer candidate poses ``(M, 3)`` to recovery: at the next update those in free space
        replace samples as recovery guesses, which must then win like any other guess."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        self._offered = np.vstack([self._offered, p])

    # ------------------------------------------------------------------ initialisation

    def reset_tracking(self, pose: ArrayLike, cov: ArrayLike | None = None) -> None:
        """Start from a known pose: ``max_samples`` samples from a Gaussian around ``pose``
        (``cov`` ``(3, 3)`` defaults to ``diag(sampling.tracking_std ** 2)``)."""
        p = np.asarray(pose, dtype=np.float64).reshape(3)
        std = self.config.sampling.tracking_std
        c = np.diag(np.square(std)) if cov is None else np.asarray(cov, np.float64)
        s = self.rng.multivariate_normal(p, c, size=self.config.sampling.max_samples)
        s[:, 2] = wrap_angle(s[:, 2])
        self._set_belief(s)

    def reset_global(self, grid: OccupancyGrid | None = None, rng: np.random.Generator | None = None) -> None:
        """Global localization: ``global.samples`` samples uniform over the free space of ``grid``
        (the localizer's map by default); ``rng``, when given, replaces the random generator."""
        if rng is not None:
            self.rng = rng
        g = self.grid if grid is None else grid
        cells = self.sensor.free_cells if grid is None else np.argwhere(grid.free())
        if cells.shape[0] == 0:
            raise LocalizationError("the map has no free cell to localize in")
        self._set_belief(
            uniform_free_poses(g, cells, self.config.global_.samples, self.rng), global_start=True
        )
        self._global_start = (g, cells)

    def _set_belief(self, samples: FloatArray, *, global_start: bool = False) -> None:
        self.samples = np.ascontiguousarray(samples, dtype=np.float64)
        self.weights = np.full(samples.shape[0], 1.0 / samples.shape[0])
        self.recovery.reset(samples.shape[0], global_start=global_start)
        self._odom = None
        self._global_start = None

    # ------------------------------------------------------------------ the filter

    def update(self, odom_pose: ArrayLike, scan: Scan) -> LocalizationEstimate:
        """Integrate one scan taken at odometry pose ``odom_pose``; return the new estimate."""
        t0 = time.perf_counter()
        reading = self._read(scan)
        self.recovery.match(self.weights.shape[0])
        self._predict(np.asarray(odom_pose, dtype=np.float64).reshape(3))  # 1. motion model
        if self._global_start is not None and reading.valid.any():
            used, inject = reading.valid, 0.0
            self._localize_globally(reading)  # the first scan of a global localization
        else:
            used = self._select_beams(reading)  # 2. entropy or novelty filter
            inject = self._weight(reading, used)  # 3. sensor model
        track, inject, reset_poses = self._recover(reading, used, inject)  # 4. recovery
        injected = self._resample(reading, used, track.pose, inject, reset_poses)  # 5. resampling
        reading.info["injected"] = float(injected)
        return self._estimate(reading, used, track, time.perf_counter() - t0)  # 6. estimate

    # ------------------------------------------------------------------ steps

    def _read(self, scan: Scan) -> _Reading:
        if self.samples.shape[0] == 0:
            raise LocalizationError("call reset_tracking(pose) or reset_global() before update()")
        geometry = scan.geometry
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        if ranges.shape != (geometry.num_beams,):
            raise LocalizationError(
                f"scan at t={scan.timestamp}: {ranges.shape[0]} ranges for {geometry.num_beams} beams"
            )
        valid = np.isfinite(ranges) & (ranges >= geometry.min_range) & (ranges < geometry.max_range)
        return _Reading(scan.timestamp, ranges, geometry, valid, {"n_valid_beams": float(valid.sum())})

    def _predict(self, odom: FloatArray) -> None:
        """1. Motion (Eq. 1): every sample moves by the odometry, with sampled noise."""
        if self._odom is not None:
            self.samples = self.config.motion.sample(self.samples, self._odom, odom, self.rng)
            step = relative(self._odom, odom)
            self.recovery.moved(math.hypot(step[0], step[1]), float(wrap_angle(step[2])))
        self._odom = odom

    def _select_beams(self, r: _Reading) -> BoolArray:
        """2. Beam selection: the entropy or novelty filter of Fox et al. 1998 (Eq. 3-6) over the
        established samples; while global localization spreads the belief, only the longest."""
        cfg = self.config.sensor
        valid = r.valid
        if cfg.beam_filter == BeamFilter.NONE or not valid.any():
            keep_mask = valid
        else:
            field_ = self.sensor.field(r.geometry)
            if cfg.beam_filter == BeamFilter.ENTROPY:
                # H(l | s) of Eq. 4 with the tempered likelihood, as the update integrates it.
                ll = field_.beam_log_likelihoods(self.samples, r.ranges, r.geometry)[:, valid]
                lik = np.exp(cfg.likelihood_exponent * ll.astype(np.float64))
                groups = cell_keys(self.samples, cfg.entropy_cell[0], cfg.entropy_cell[1])
                keep = entropy_filter(
                    lik, self.weights, groups, cfg.filters.entropy_tolerance, informative_only=True
                )
            else:
                keep = self._novelty(r)
            keep_mask = np.zeros_like(valid)
            keep_mask[np.flatnonzero(valid)[keep]] = True
        if self.recovery.state.global_phase:
            # A spread belief makes the novelty filter keep nearly every beam; a crowd only
            # shortens beams, so while the belief is spread only the longest are trusted.
            keep_mask = longest_returns(r.ranges, keep_mask, self.config.global_.long_fraction)
        return keep_mask

    def _novelty(self, r: _Reading) -> BoolArray:
        """Eq. 5-6 over ``novelty_samples`` hypotheses drawn by weight from the established
        samples, one ray cast per occupied cell of the paper's grid, heaviest first."""
        cfg = self.config.sensor
        m = min(cfg.novelty_samples, self.samples.shape[0])
        idx = systematic_resample(
            self.recovery.established_weights(self.weights), m, float(self.rng.random())
        )
        cells = cell_keys(self.samples[idx], cfg.entropy_cell[0], cfg.entropy_cell[1])
        _, first, counts = np.unique(cells, return_index=True, return_counts=True)
        order = np.argsort(-counts, kind="stable")
        idx, hyp_w = idx[first[order]], counts[order] / m
        laser = compose(self.samples[idx], np.asarray(r.geometry.offset, dtype=np.float64))
        max_range = float(r.geometry.max_range)
        return novelty_filter_cast(
            self.sensor.caster(max_range),
            laser,
            hyp_w,
            r.geometry.angles[r.valid],
            r.ranges[r.valid],
            cfg.novelty_sigma,
            max_range,
            cfg.filters.theta,
        )

    def _weight(self, r: _Reading, used: BoolArray) -> float:
        """3. Perception (Eq. 2), in log space: the tempered likelihood field of the used beams
        plus the extra likelihoods. Returns augmented MCL's injection fraction for the fit."""
        cfg = self.config
        n_used = int(used.sum())
        extra = self._extra_log_likelihood()
        if not n_used:
            if extra is not None:
                self._reweigh(np.log(np.maximum(self.weights, 1e-300)) + extra)
            return 0.0
        field_ = self.sensor.field(r.geometry)
        loglik = field_.log_likelihood(self.samples, r.ranges, r.geometry, beam_mask=used)
        # The fit: the fraction of the used beams that the best sample ends within fit_distance
        # of a mapped obstacle (robust to a few stray beams).
        best = int(np.argmax(loglik))
        lls = field_.beam_log_likelihoods(self.samples[best : best + 1], r.ranges, r.geometry)[0, used]
        fit = float(np.mean(lls >= field_.params.log_p(cfg.recovery.fit_distance)))
        temper = cfg.sensor.likelihood_exponent
        prior = np.log(np.maximum(self.weights, 1e-300))
        if self.recovery.state.global_phase:
            # One scan may not collapse a spread belief: the effective sample size stays at
            # global.ess of the samples.
            temper = anneal_step(prior, loglik, temper, cfg.global_.ess * self.samples.shape[0])
        logw = prior + temper * loglik
        self._reweigh(logw if extra is None else logw + extra)
        evidence = n_used >= cfg.recovery.min_used * r.n_returns
        inject = self.recovery.injection_from_fit(fit, evidence)
        r.info.update(temper=temper, w_best=fit, inject_fraction=inject)
        return inject

    def _extra_log_likelihood(self) -> FloatArray | None:
        if not self.extra_likelihoods:
            return None
        total = np.zeros(self.samples.shape[0])
        for lik in self.extra_likelihoods:
            total += np.asarray(lik.log_likelihood(self.samples), dtype=np.float64).reshape(-1)
        return total

    def _reweigh(self, logw: FloatArray) -> None:
        """The weights of the log weights ``logw``. The established samples hold the track until
        a guess has won (:meth:`Recovery.arbitrate`): however much better the guesses explain a
        scan, the best established sample keeps a weight of at least ``exp(_LOG_FLOOR)`` of the
        best guess's, else every established weight would round to zero and the heaviest cluster
        (the track) would be a guess's without any contest."""
        logw = logw - logw.max()
        fresh = self.recovery.fresh
        if fresh.shape == logw.shape and fresh.any() and not fresh.all():
            top = float(logw[~fresh].max())
            if top < _LOG_FLOOR:
                logw = np.where(fresh, logw, logw + (_LOG_FLOOR - top))
        w = np.exp(logw)
        self.weights = w / w.sum()

    def _localize_globally(self, r: _Reading) -> None:
        """The first scan of a global localization, by annealed importance sampling over
        ``global.candidates`` poses uniform over the free space (:class:`ResetSearch`)."""
        glob = self.config.global_
        assert self._global_start is not None
        grid, cells = self._global_start
        self._global_start = None
        n = glob.samples
        cand = uniform_free_poses(grid, cells, max(glob.candidates, n), self.rng)
        beams = longest_returns(r.ranges, r.valid, glob.long_fraction)
        field_ = self.sensor.field(r.geometry)
        samples, stages = self.search.anneal(
            cand, n, r.ranges, r.geometry, field_, beams, glob.stages, self.rng
        )
        self.samples = samples
        self.weights = np.full(samples.shape[0], 1.0 / samples.shape[0])
        self.recovery.clear_guesses(samples.shape[0])
        r.info["global_stages"] = float(stages)
        r.global_start = True

    def _track(self) -> _Track:
        """The heaviest cluster of the established samples (no state changes)."""
        b = self.config.sampling.kld_bin
        labels = cluster_bins(self.samples, b[0], b[2])
        pose, cov, weight = best_cluster_estimate(
            self.samples, self.recovery.established_weights(self.weights), labels
        )
        return _Track(labels, pose, cov, weight)

    def _too_long(self, r: _Reading, pose: FloatArray, others: FloatArray | None) -> float:
        """The too-long test at ``pose`` and ``others`` (by default ``lost_hypotheses`` samples
        drawn by weight from the established belief); NaN when no evidence."""
        rec = self.config.recovery
        if not r.valid.any():
            return math.nan
        if others is None:
            k = min(rec.lost_hypotheses, self.samples.shape[0])
            idx = systematic_resample(
                self.recovery.established_weights(self.weights), k, float(self.rng.random())
            )
            others = self.samples[idx]
        poses = np.vstack([pose[None, :], others])
        return self.sensor.too_long_fraction(
            poses, r.ranges, r.geometry, r.valid, rec.lost_margin, rec.lost_min_beams
        )

    def _recover(
        self, r: _Reading, used: BoolArray, inject: float
    ) -> tuple[_Track, float, FloatArray | None]:
        """4. Recovery: the track is judged by the too-long test, the guesses compete with it
        (:meth:`Recovery.arbitrate`), and the verification (``verify_period``) may search the map.
        Returns the track, the fraction of samples to replace and the verification's poses."""
        rec_cfg, recovery = self.config.recovery, self.recovery
        state = recovery.state
        global_start = r.global_start
        judged = bool(used.any()) and not global_start and not state.global_phase

        def judge(p: FloatArray, others: FloatArray | None = None) -> float:
            return self._too_long(r, p, others) if judged else math.nan

        def score(poses: FloatArray) -> FloatArray:
            return self.sensor.crowd_log_likelihood(poses, r.ranges, r.geometry, r.valid)

        track = self._track()
        too_long = judge(track.pose, None)
        recovery.judge_track(too_long, r.timestamp)
        decision = recovery.arbitrate(
            self.samples, self.weights, track.labels, track.pose, too_long, score, judge, r.n_returns
        )
        if decision.weights is not None:
            self.weights = decision.weights
        if decision.became_track:
            pose, cov, weight = best_cluster_estimate(self.samples, self.weights, track.labels)
            track = _Track(track.labels, pose, cov, weight)
        r.info.update(
            ess=1.0 / float(np.sum(self.weights**2)), cluster_weight=track.weight, too_long=too_long
        )
        if state.global_phase and not global_start and track.weight >= self.config.global_.done:
            state.global_phase = False
        if not recovery.in_doubt:
            inject = 0.0  # augmented MCL's guesses could not compete with a track that explains the scan
        elif too_long > rec_cfg.lost_fraction:
            inject = rec_cfg.max_injection
        r.info["lost_scans"] = float(state.lost_scans)
        reset_poses: FloatArray | None = None
        due = recovery.verification_due(r.timestamp)
        tracking = not global_start and not state.global_phase and r.n_returns >= rec_cfg.lost_min_beams
        if tracking and rec_cfg.max_injection > 0 and due:
            n = max(
                1, round(rec_cfg.max_injection * max(self.samples.shape[0], self.config.sampling.max_samples))
            )
            earlier = self.samples[recovery.fresh] if recovery.fresh.any() else None
            reset_poses, margin = self.search.verify(
                track.pose, n, r.ranges, r.geometry, r.valid, self._verify_rng, earlier
            )
            r.info["verify_margin"] = margin
            if recovery.verified(r.timestamp, margin):
                inject = rec_cfg.max_injection
            else:
                reset_poses = None
        r.info["suspect"] = float(state.suspect)
        return track, inject, reset_poses

    def _resample(
        self,
        r: _Reading,
        used: BoolArray,
        estimate: FloatArray,
        inject: float,
        reset_poses: FloatArray | None,
    ) -> int:
        """5. Resampling: low variance with the KLD-adapted count, when the effective sample size
        is low or samples are to be replaced; ``inject`` of them are replaced by ``reset_poses``
        (a verification's), the offered poses (:meth:`inject`) or scan-drawn ones."""
        cfg = self.config
        offered = self._take_offered()
        if offered.shape[0]:
            inject = max(inject, min(cfg.recovery.max_injection, offered.shape[0] / self.samples.shape[0]))
        ess = 1.0 / float(np.sum(self.weights**2))
        if r.global_start or not (used.any() or reset_poses is not None or offered.shape[0]):
            return 0
        if not (ess < cfg.sampling.resample_threshold * self.samples.shape[0] or inject > 0.0):
            return 0
        recovery = self.recovery
        n_max = max(cfg.sampling.max_samples, cfg.sampling.min_samples)
        if recovery.state.global_phase:
            n_max = max(n_max, cfg.global_.samples)  # a spread belief keeps its large sample set
        fresh_now = recovery.fresh
        if fresh_now.any() and not fresh_now.all():
            # Until a guess has won, the guesses and the established samples keep their shares.
            n_f = round(n_max * fresh_now.mean())
            parts = []
            for g, k in zip(
                (np.flatnonzero(~fresh_now), np.flatnonzero(fresh_now)), (n_max - n_f, n_f), strict=True
            ):
                wg = self.weights[g]
                wg = wg / wg.sum() if wg.sum() > 0 else np.full(g.size, 1.0 / g.size)
                parts.append(g[systematic_resample(wg, k, float(self.rng.random()))])
            idx = np.concatenate(parts)
        else:
            idx = systematic_resample(self.weights, n_max, float(self.rng.random()))
        idx = idx[self.rng.permutation(n_max)]
        drawn = self.samples[idx]
        s = cfg.sampling
        n = kld_sample_count(drawn, s.kld_bin, s.kld_epsilon, s.kld_quantile, s.min_samples, n_max)
        new = drawn[:n].copy()
        fresh = fresh_now[idx[:n]].copy()
        held = recovery.held[idx[:n]]
        n_inject = round(inject * n)
        if n_inject:
            # New guesses replace older guesses that have not won first, then established samples;
            # the guess that won this scan (held) must win the next one and stays.
            slots = np.concatenate([np.flatnonzero(fresh & ~held), np.flatnonzero(~fresh)])[:n_inject]
            poses = reset_poses if reset_poses is not None else offered[:n_inject]
            if poses.shape[0] < n_inject and reset_poses is None:
                far, table = recovery.wide_search()
                scan_drawn = self.search.scan_drawn_poses(
                    n_inject - poses.shape[0],
                    r.ranges,
                    r.geometry,
                    r.valid,
                    estimate,
                    self.rng,
                    far=far,
                    table=table,
                )
                poses = np.vstack([poses, scan_drawn])
            slots = slots[: poses.shape[0]]
            new[slots] = poses[: slots.size]
            fresh[slots] = True
        self.samples = np.ascontiguousarray(new)
        self.weights = np.full(n, 1.0 / n)
        recovery.fresh = fresh
        recovery.held = held & fresh
        return n_inject

    def _take_offered(self) -> FloatArray:
        offered, self._offered = self._offered, np.zeros((0, 3))
        if offered.shape[0] == 0:
            return offered
        offered = offered.copy()
        offered[:, 2] = wrap_angle(offered[:, 2])
        return offered[self.sensor.in_free_space(offered)]

    def _estimate(self, r: _Reading, used: BoolArray, track: _Track, seconds: float) -> LocalizationEstimate:
        """6. The estimate: the track's mean and covariance, as a snapshot."""
        est = LocalizationEstimate(
            timestamp=r.timestamp,
            pose=track.pose,
            covariance=track.cov,
            used_beams=used,
            n_samples=int(self.samples.shape[0]),
            updated=bool(used.any()),
            update_seconds=seconds,
            info=r.info,
        )
        self.last_estimate = est
        return est
