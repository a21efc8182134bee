"""Monte Carlo localization with the entropy and novelty filters of Fox et al. (1998).

The belief ``Bel(l)`` of Markov localization (Fox, Burgard, Thrun & Cremers 1998, Eq. 1-2) is
held as weighted samples (Dellaert, Fox, Burgard & Thrun 1999, "Monte Carlo localization"). One
:meth:`MonteCarloLocalization.update` per scan:

1. *motion* (Eq. 1): every sample moves by the odometry since the last scan, with noise sampled
   from the odometry motion model (:mod:`tourbot.localization.motion_model`);
2. *beam selection* (Eq. 3-6): beams without a return are skipped, then the entropy or the novelty
   filter (:mod:`tourbot.localization.beam_filters`) picks the beams to integrate, over the
   current weighted samples. The novelty filter's expected ranges are ray cast for a few hundred
   samples drawn by weight (an unbiased estimate of the belief average of Eq. 6);
3. *perception* (Eq. 2): the weights are multiplied by the likelihood-field likelihood of the
   selected beams (:class:`tourbot.maps.likelihood_field.LikelihoodField`), tempered by
   ``likelihood_exponent`` because neighbouring beams are not independent;
4. *recovery*: augmented MCL (Thrun, Burgard & Fox, *Probabilistic Robotics*, Table 8.3) with
   sensor resetting (Lenser & Veloso 2000). The fit of a scan is how well the *best* sample
   explains the integrated beams: the fraction of them that end within ``fit_distance`` of a mapped
   obstacle. While tracking, some sample explains nearly all of them, whatever the spread of the
   prediction; right after a kidnap none does. A short- and a long-term average of the fit are
   kept (``alpha_fast``, ``alpha_slow``);
   when the short-term one falls below ``recovery_ratio`` times the long-term one, a fraction
   ``1 - w_fast / (recovery_ratio * w_slow)`` (at most ``max_injection``) of the samples is
   replaced by poses drawn from the current scan (see below). The dead band ``recovery_ratio``
   and the rule that a scan with fewer than ``recovery_min_used`` of its returns integrated is
   no evidence keep the ups and downs of a crowded museum from resetting a filter that tracks
   well. The second, crowd-proof sign of a wrong estimate is the one Fox et al. point to (the
   novelty filter "forces the incorporation of very unlikely sensor measurements (especially
   too long readings)"): readings that pass through mapped walls. Visitors only ever shorten a
   beam, so of the returns that are not shorter than expected at the estimate, the fraction
   longer than expected by ``lost_margin`` is near zero at the true pose however dense the
   crowd, and large at a wrong one; it is judged at the estimate and ``lost_hypotheses``
   samples of the track (the smallest counts) and is no evidence when fewer than
   ``lost_min_beams`` returns are left to judge. Above ``lost_fraction`` the scan
   *contradicts* the track and ``max_injection`` of the samples are reset. The reset poses are
   drawn from candidates around the estimate (a drift in a crowd, a kidnap by a metre) and,
   once the track has been contradicted on ``global_after`` scans in a row, also over the whole
   free space (at once, and with the cast table's screening, :mod:`tourbot.localization.
   cast_table`, while the track is one that global localization settled on and that has not yet
   passed the too-long test on ``global_after`` judged scans in a row: such a track was never
   right, and a look-alike may lie anywhere; FHW, docs/design-notes.md "Run 7d"), annealed on
   the scan's likelihood under a beam model with ray-cast expected ranges whose "short"
   component is the crowd (``recovery_model``): unlike the likelihood field, which scores a
   beam by its endpoint, it sees a look-alike place's beams cross walls.
   Injected samples are *fresh* (guesses) until one guess has won ``fresh_wins`` consecutive
   scans: each scan, the guesses (clusters of fresh samples) are judged at their means by the
   crowd beam model against the track, and the best one that the too-long test does not
   contradict (or contradicts less than the track) wins when the scan contradicts the track,
   or, on a scan that does not, when it is at another place and explains the scan better by the
   verification's ``verify_margin``. A
   guess that wins is *held*: the other guesses lose their weight and new guesses do not
   replace it, so that it must win the next scan itself. The guesses are judged by the beam
   model and not by their weights, which carry the likelihood field: in a crowd the field may
   rate a look-alike place turned around above the true one, whose readings the beam model sees
   pass through walls (FHW, docs/design-notes.md "Run 7"). Guesses that lie in the track's own
   cluster on a scan that does not contradict it join the track. A scan that is no evidence
   (fewer than ``lost_min_beams`` returns to judge, or none integrated) neither confirms nor
   contradicts anything: no guess wins it, the held guess stays held, and the count of
   contradicted scans is neither raised nor reset (else a guess drawn while the track it has
   just replaced was contradicted could displace the found one on such a scan, FHW,
   docs/design-notes.md "Run 7b"); a failed verification (below) still contradicts the track
   on such a scan. The novelty filter averages
   Eq. 6 over the established samples only (a two-peaked belief would let a crowd's short beams
   through), the estimate is the heaviest cluster of the established samples, resampling keeps
   each group's share, and new guesses replace older fresh ones. So a crowd that makes a
   look-alike place fit a few scans better cannot hand it the belief while the track still
   explains the scan. During global localization (no track yet) the heaviest cluster wins
   instead, when fresh samples hold most of its weight (or the crowd beam model prefers the
   heaviest fresh cluster to the heaviest established one). The too-long test cannot see every
   wrong pose (moved along a hall, the track's readings are shorter than expected on one side,
   which a crowd would explain, and about right elsewhere), and a robot that stands gives the
   filter the same scan over and over and no motion to spread its samples. So, when
   ``verify_period`` is set, the track is *verified* every ``verify_period`` seconds: the
   reset search above (around the estimate, and over the whole free space on a table of ray
   cast ranges, :mod:`tourbot.localization.cast_table`, whose beam model sees a nook's short
   walls where the likelihood field of the longest returns does not) is run, and the best
   pose it finds is compared with the tracked estimate under the crowd beam model, a likelihood
   ratio test of the track against its best alternative. When the alternative explains the
   scan better by more than ``verify_margin`` nats per return the track counts as contradicted,
   the search's poses are injected as fresh samples, and every scan is verified until a
   verification passes, and for ``verify_period`` seconds after a recovery guess has become
   the track (one search may miss the true place, and the guess then only had to beat a
   track that was wrong);
5. *resampling*: low-variance (systematic) resampling when the effective sample size falls below
   ``resample_threshold * N`` (Probabilistic Robotics, Table 4.4), with the number of samples
   chosen by KLD-sampling (Fox 2003, "Adapting the sample size in particle filters through
   KLD-sampling", Eq. 13);
6. *estimate*: the samples are clustered on a grid of bins (neighbouring occupied bins join);
   the estimate is the weighted mean of the heaviest cluster, with its covariance.

Hot loops (motion sampling, likelihood look-ups, entropy, resampling, KLD counting, clustering)
are numba kernels; each has a plain-numpy reference beside it (see the tests).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from statistics import NormalDist
from typing import Literal

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.errors import TourbotError
from tourbot.geometry import compose, invert, wrap_angle
from tourbot.localization.beam_filters import (
    BeamFilter,
    BeamFilterConfig,
    entropy_filter,
    novelty_filter_cast,
)
from tourbot.localization.cast_table import CastTable
from tourbot.localization.estimate import LocalizationEstimate
from tourbot.localization.motion_model import OdometryMotionModel, _wrap
from tourbot.maps.beam_model import BeamModel
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.likelihood_field import LikelihoodField, LikelihoodFieldParams
from tourbot.maps.raycast import DistanceCaster, RayCaster
from tourbot.records import LaserGeometry, Scan

__all__ = [
    "LocalizationError",
    "MCLConfig",
    "MonteCarloLocalization",
    "best_cluster_estimate",
    "best_cluster_estimate_reference",
    "cluster_bins",
    "cluster_bins_reference",
    "kld_bounds",
    "kld_sample_count",
    "low_variance_resample",
    "low_variance_resample_reference",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class LocalizationError(TourbotError):
    """A localizer used wrongly: no map free space, no start, a scan it cannot read."""


@dataclass(frozen=True)
class MCLConfig:
    """Parameters of Monte Carlo localization; defaults cited where a source gives them.

    Samples
        ``min_samples`` / ``max_samples``: bounds of the KLD-adapted sample count (Nav2 AMCL:
        500 / 2000; 5000 here, the budget of the project's benchmark). ``global_samples``: samples
        spread over the free space by :meth:`MonteCarloLocalization.reset_global` (KLD-sampling then
        shrinks the set as the belief concentrates). ``kld_epsilon`` 0.05 and ``kld_quantile``
        0.99: Nav2 AMCL's ``pf_err`` and ``pf_z`` (Fox 2003, Eq. 13). ``kld_bin`` (0.5 m, 0.5 m,
        10 deg): AMCL's histogram bins, also the bins of the clustering of the estimate.
        ``resample_threshold`` 0.5: resample when the effective sample size falls below half the
        samples (Doucet, Godsill & Andrieu 2000; Probabilistic Robotics Sec. 4.3.4).
    Filters
        ``beam_filter``: ``novelty`` by default, the paper's recommendation (Fox et al. 1998,
        Conclusions: "only the localization algorithm with the novelty filter is able to localize
        robots in densely crowded environments, while retaining the ability to efficiently recover
        from extreme localization errors"). ``filters.theta`` 0.99 (Eq. 6 threshold).
        ``entropy_cell`` (15 cm, 2 deg): the paper's grid; samples sharing a cell are one location
        when the entropy of the belief is computed (Eq. 3). ``novelty_samples``: hypotheses drawn
        by weight for which expected ranges are ray cast for Eq. 6 (64: on FHW, 128 gave the same
        accuracy at twice the cost, 32 let a few failures through).
    Sensor
        ``likelihood_exponent``: the likelihood field of all beams of a scan is raised to this
        power: consecutive beams of a scan are strongly correlated and the product over 180 of them
        would be far too confident (Probabilistic Robotics Sec. 6.4 and 6.8 discuss this; Nav2
        AMCL sidesteps it with its own heuristic); 0.2 measured best on FHW among 0.05, 0.1, 0.2 and
        0.3 (mean error 11.1, 8.4, 8.0, 7.9 cm). ``z_hit`` 0.95, ``z_rand`` 0.05, ``max_dist``
        2 m: the likelihood field's own defaults (Nav2 AMCL's). ``sigma_hit`` 0.1 m instead of
        AMCL's 0.2 m, for the likelihood field and for the novelty filter's "shorter than
        expected" (Eq. 5): on FHW with 5 cm reference maps it gave 7.2 cm mean error against 8.0 cm
        at 0.2 m, with every kidnap still recovered; 0.07 m let failures through.
        ``field_distance`` ``"surface"``: the likelihood field scores an endpoint by its distance to
        the surface of the free space, also when it lies behind it
        (:class:`tourbot.maps.likelihood_field.LikelihoodFieldParams`); the book's ``"centre"``
        (distance to the nearest occupied cell centre, zero anywhere inside a wall) pulls the pose
        about 5 cm towards the walls ahead on FHW.
    Recovery
        ``alpha_slow`` / ``alpha_fast``: the averaging rates of augmented MCL (Probabilistic
        Robotics Table 8.3, Nav2 AMCL ``recovery_alpha_slow`` 0.001 / ``recovery_alpha_fast`` 0.1);
        per update, and AMCL updates every 0.25 m whereas a scan of the museum logs comes every
        ~0.8 m, so ours are faster (``alpha_fast`` 1: the fit of the current scan itself).
        ``recovery_ratio``: injection starts when the short-term average falls below this fraction
        of the long-term one (1 in Probabilistic Robotics; 0.5 here: on the FHW log the best
        sample's fit, ``fit_distance`` 15 cm, stays above 0.9 while tracking and drops to 0-0.4 at
        a kidnap; in the simulated peak crowd it dips to 0.4-0.6 now and then while tracking).
        ``recovery_min_used``: scans with fewer integrated beams than this fraction of their
        returns leave the averages alone. ``max_injection`` 0.2: at most this fraction of the
        samples is replaced per update, so a false alarm in a crowd adds a small cluster that
        must then win on the next scans rather than replacing the belief.
        ``fresh_wins`` 2: injected samples stay *fresh* until one guess (a cluster of them) has
        beaten the track on this many consecutive scans (:meth:`MonteCarloLocalization.
        _estimate`). Fresh samples are left out of the novelty filter's belief average (Eq. 6)
        and out of the estimate, and resampling keeps the fresh and the established samples'
        shares, so a recovery guess at a look-alike place must beat the track twice before it
        replaces it (in the simulated peak crowd one scan sometimes favours such a place).
        ``lost_margin`` 0.5 m, ``lost_fraction`` 0.3, ``lost_min_beams`` 20, ``lost_hypotheses``
        8: the too-long test (module docstring, step 4). Measured on the peak-crowd FHW and Intel
        logs (crowd seeds 0-2, 2026-12-01): at 0.3, 2-4 % of the scans of a correct track are
        false alarms on FHW (map corners, glass) and 0.4-1.4 % on Intel, while 98-100 % of the
        scans of a track more than 1 m off are caught (0.4: 0.5-1 % and 84-100 %).
        ``verify_period`` (seconds of scan time; None: never), ``verify_margin`` 0.5 nats per
        return and ``verify_distance`` (1 m, 30 deg): the verification of the track (module
        docstring, step 4; :meth:`MonteCarloLocalization._verify`). Each costs one reset search
        (about 30 ms at 90 returns on the FHW site). The figures behind the margin are in
        docs/design-notes.md ("Simulated runtime"); not tuned beyond them. The verification's search
        screens its far candidates on the cast table (:class:`tourbot.localization.cast_table.
        CastTable`: ``table_spacing`` 0.25 m lattice over the free space, ``table_directions`` 90
        headings, the crowd beam model of ``table_beams`` 12 returns spread over the scan, the
        ``table_survivors`` 500 best) instead of the likelihood field of the longest returns
        (``verify_candidates`` 0 of those; 200000 as sensor resetting's): in a nook with short
        walls all round and the crowd in its opening the field ranks the true place below
        thousands of others, the beam model among the first ten (FHW, docs/design-notes.md).
        Its candidates around the estimate are ``verify_local_candidates`` 3000 (sensor
        resetting's ``injection_local_candidates`` 10000): only places more than
        ``verify_distance`` away count, and the table covers the whole free space.
        ``global_after`` 3: consecutive contradicted scans before the reset candidates include the
        whole free space (from the first one, with the cast table's poses, for a track from
        global localization that has not yet passed the too-long test on ``global_after`` judged
        scans in a row).
        ``injection_local_candidates`` poses around the estimate
        (``injection_local_std`` 1 m, any heading) and the ``injection_survivors`` best of
        ``injection_candidates`` uniform ones (screened by the likelihood field of the
        ``injection_long_fraction`` longest returns, no ray casting) are annealed on the crowd
        beam model in ``injection_stages`` stages down to ``injection_survivors`` poses, from
        which the reset samples are taken. ``recovery_model``: Probabilistic Robotics' beam
        model with ``z_hit`` 0.5, ``z_short`` 0.4 (in the peak crowd about half of the returns hit
        a visitor), ``lambda_short`` 0.2 /m (visitors stand around the robot), ``sigma_hit`` 0.2 m
        (candidate poses are a few centimetres and a degree off), ``z_max`` = ``z_rand`` 0.05;
        not tuned.
    """

    min_samples: int = 500
    max_samples: int = 5000
    global_samples: int = 50000
    kld_epsilon: float = 0.05
    kld_quantile: float = 0.99
    kld_bin: tuple[float, float, float] = (0.5, 0.5, math.radians(10.0))
    resample_threshold: float = 0.5
    beam_filter: BeamFilter = BeamFilter.NOVELTY
    filters: BeamFilterConfig = field(default_factory=BeamFilterConfig)
    entropy_cell: tuple[float, float] = (0.15, math.radians(2.0))
    novelty_samples: int = 64
    likelihood_exponent: float = 0.2
    sigma_hit: float = 0.1
    z_hit: float = 0.95
    z_rand: float = 0.05
    max_dist: float = 2.0
    field_distance: Literal["centre", "surface"] = "surface"
    motion: OdometryMotionModel = field(default_factory=OdometryMotionModel)
    alpha_slow: float = 0.01
    alpha_fast: float = 1.0
    recovery_ratio: float = 0.5
    recovery_min_used: float = 0.3
    fit_distance: float = 0.15
    max_injection: float = 0.2
    injection_candidates: int = 200000
    injection_local_std: float = 1.0
    fresh_wins: int = 2
    global_candidates: int = 1_000_000
    global_beam_step: int = 4
    global_ess: float = 0.1
    global_jitter: tuple[float, float, float] = (0.05, 0.05, math.radians(2.0))
    global_stages: int = 8
    global_long_fraction: float = 0.5
    global_done: float = 0.95
    injection_stages: int = 3
    injection_long_fraction: float = 0.5
    injection_survivors: int = 1000
    injection_local_candidates: int = 10000
    verify_candidates: int = 0
    verify_local_candidates: int = 3000
    table_survivors: int = 500
    table_spacing: float = 0.25
    table_directions: int = 90
    table_beams: int = 12
    recovery_model: BeamModel = field(
        default_factory=lambda: BeamModel(
            z_hit=0.5, z_short=0.4, z_max=0.05, z_rand=0.05, sigma_hit=0.2, lambda_short=0.2
        )
    )
    lost_margin: float = 0.5
    lost_fraction: float = 0.3
    verify_period: float | None = None
    verify_margin: float = 0.5
    verify_distance: tuple[float, float] = (1.0, math.radians(30.0))
    lost_min_beams: int = 20
    lost_hypotheses: int = 8
    global_after: int = 3
    tracking_std: tuple[float, float, float] = (0.1, 0.1, math.radians(5.0))

    def __post_init__(self) -> None:
        if not 1 <= self.min_samples <= self.max_samples:
            raise LocalizationError(
                f"need 1 <= min_samples <= max_samples, got {self.min_samples}, {self.max_samples}"
            )
        if not self.likelihood_exponent > 0:
            raise LocalizationError(f"likelihood_exponent must be positive, got {self.likelihood_exponent}")
        if not 0 <= self.max_injection <= 1:
            raise LocalizationError(f"max_injection must be in [0, 1], got {self.max_injection}")


class MonteCarloLocalization:
    """Monte Carlo localization on an occupancy grid, with the beam filters of Fox et al. 1998.

    Use: ``mcl = MonteCarloLocalization(grid, config, seed=0)``, then ``mcl.reset_tracking(pose)``
    or ``mcl.reset_global()``, then ``mcl.update(odom_pose, scan)`` for each scan in order (the
    odometry pose at the scan's time, in the odometry frame). ``samples`` ``(N, 3)`` and
    ``weights`` ``(N,)`` are the belief, for drawing.
    """

    def __init__(self, grid: OccupancyGrid, config: MCLConfig | None = None, seed: int | None = None) -> None:
        self.grid = grid
        self.config = config or MCLConfig()
        self.rng = np.random.default_rng(seed)
        # The verification's searches draw from their own stream: a verification that passes
        # leaves the filter exactly as it would be without verifying.
        self._verify_rng = np.random.default_rng(None if seed is None else [seed, 1])
        free = grid.free()
        if not free.any():
            raise LocalizationError("the map has no free cell to localize in")
        self._free = free
        self._free_cells = np.argwhere(free)
        self._field_params = LikelihoodFieldParams(
            sigma_hit=self.config.sigma_hit,
            z_hit=self.config.z_hit,
            z_rand=self.config.z_rand,
            max_dist=self.config.max_dist,
            distance=self.config.field_distance,
        )
        self._fields: dict[float, LikelihoodField] = {}
        self._casters: dict[float, RayCaster] = {}
        self._tables: dict[float, CastTable] = {}
        self.samples: FloatArray = np.zeros((0, 3))
        self.weights: FloatArray = np.zeros(0)
        # Samples injected by recovery that have not yet won a scan (see ``update``, step 4).
        self._fresh: NDArray[np.bool_] = np.zeros(0, dtype=bool)
        self._fresh_won = 0  # consecutive scans on which the held recovery guess beat the track
        # The samples of the guess that won the last scan (``_estimate``): no new guess replaces them.
        self._held: NDArray[np.bool_] = np.zeros(0, dtype=bool)
        self._n_returns = 0  # returns of the scan being integrated (the guesses' margin per return)
        self._odom: FloatArray | None = None
        self._w_slow = 0.0
        self._w_fast = 0.0
        self._lost_scans = 0  # consecutive scans whose estimate has readings through mapped walls
        # Verification (``verify_period``): the next scan time due, and whether the last one
        # found a place that explains the scan clearly better than the track (or a recovery
        # guess has just replaced the track): until a verification passes, every scan verifies.
        self._next_verify = -math.inf
        self._suspect = False
        self._recovered = False  # a recovery guess became the track on this scan
        self._verify_until = -math.inf  # until then every scan is verified (after a recovery)
        # Set by reset_global: the first scan is integrated by the annealed global start.
        self._global_cells: tuple[OccupancyGrid, IntArray] | None = None
        self._global_phase = False  # from reset_global until one cluster holds the belief
        # From reset_global until the track has passed the too-long test on global_after judged
        # scans in a row: a track that was never right (global localization settled on a
        # look-alike) is searched for over the whole free space at once.
        self._unconfirmed = False
        self._passed = 0  # consecutive judged scans whose track passed the too-long test
        self.last_estimate: LocalizationEstimate | None = None

    # ------------------------------------------------------------------ initialisation

    def reset_tracking(self, pose: ArrayLike, cov: ArrayLike | None = None) -> None:
        """Start from a known pose: ``max_samples`` samples from a Gaussian around ``pose``.

        ``cov`` ``(3, 3)`` defaults to ``diag(tracking_std**2)`` (10 cm, 10 cm, 5 deg).
        """
        p = np.asarray(pose, dtype=np.float64).reshape(3)
        c = np.diag(np.square(self.config.tracking_std)) if cov is None else np.asarray(cov, np.float64)
        n = self.config.max_samples
        s = self.rng.multivariate_normal(p, c, size=n)
        s[:, 2] = wrap_angle(s[:, 2])
        self._set_belief(s)

    def reset_global(self, grid: OccupancyGrid | None = None, rng: np.random.Generator | None = None) -> None:
        """Global localization: ``global_samples`` samples uniform over the free space of ``grid``.

        ``grid`` defaults to the localizer's map; ``rng``, when given, replaces the localizer's
        random generator.
        """
        if rng is not None:
            self.rng = rng
        cells = self._free_cells if grid is None else np.argwhere(grid.free())
        g = self.grid if grid is None else grid
        if cells.shape[0] == 0:
            raise LocalizationError("the map has no free cell to localize in")
        self._set_belief(_uniform_free_poses(g, cells, self.config.global_samples, self.rng))
        self._global_cells = (g, cells)
        self._global_phase = True
        self._unconfirmed = True

    def _set_belief(self, samples: FloatArray) -> None:
        self.samples = np.ascontiguousarray(samples, dtype=np.float64)
        self.weights = np.full(samples.shape[0], 1.0 / samples.shape[0])
        self._fresh = np.zeros(samples.shape[0], dtype=bool)
        self._fresh_won = 0
        self._held = np.zeros(samples.shape[0], dtype=bool)
        self._odom = None
        self._w_slow = 0.0
        self._w_fast = 0.0
        self._lost_scans = 0
        self._next_verify = -math.inf
        self._suspect = False
        self._recovered = False  # a recovery guess became the track on this scan
        self._verify_until = -math.inf  # until then every scan is verified (after a recovery)
        self._global_cells = None
        self._global_phase = False
        self._unconfirmed = False
        self._passed = 0

    # ------------------------------------------------------------------ the filter

    def update(self, odom_pose: ArrayLike, scan: Scan) -> LocalizationEstimate:
        """Integrate one scan taken at odometry pose ``odom_pose``; return the new estimate."""
        if self.samples.shape[0] == 0:
            raise LocalizationError("call reset_tracking(pose) or reset_global() before update()")
        t0 = time.perf_counter()
        cfg = self.config
        odom = np.asarray(odom_pose, dtype=np.float64).reshape(3)
        geometry = scan.geometry
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        if ranges.shape != (geometry.num_beams,):
            raise LocalizationError(
                f"scan at t={scan.timestamp}: {ranges.shape[0]} ranges for {geometry.num_beams} beams"
            )

        if self._fresh.shape != self.weights.shape:  # the belief was set from outside
            self._fresh = np.zeros(self.weights.shape, dtype=bool)
        if self._held.shape != self.weights.shape:
            self._held = np.zeros(self.weights.shape, dtype=bool)

        # 1. Motion (Eq. 1): sample the odometry motion model.
        if self._odom is not None:
            self.samples = cfg.motion.sample(self.samples, self._odom, odom, self.rng)
        self._odom = odom

        # 2. Beam selection: returns only, then the paper's filter (Eq. 3-6).
        field_ = self._field(geometry)
        valid = np.isfinite(ranges) & (ranges >= geometry.min_range) & (ranges < geometry.max_range)
        info: dict[str, float] = {"n_valid_beams": float(valid.sum())}
        injected = 0
        global_start = self._global_cells is not None and bool(valid.any())
        if global_start:
            # Global localization: the first scan is integrated over a large candidate set.
            info["global_stages"] = float(self._global_start(ranges, geometry, field_, valid))
            used = valid
        else:
            used = self._select_beams(valid, ranges, geometry, field_)
            if self._global_phase:
                # A spread belief makes the novelty filter keep nearly every beam; a crowd only
                # shortens beams, so while the belief is spread only the longest are trusted.
                used = _longest(ranges, used, cfg.global_long_fraction)

        # 3. Perception (Eq. 2), in log space, tempered.
        n_used = int(used.sum())
        if n_used and not global_start:
            loglik = field_.log_likelihood(self.samples, ranges, geometry, beam_mask=used)
            # How well the best hypothesis explains the integrated beams: the fraction of them
            # ending within fit_distance of a mapped obstacle (robust to a few stray beams).
            best = int(np.argmax(loglik))
            lls = field_.beam_log_likelihoods(self.samples[best : best + 1], ranges, geometry)[0, used]
            w_best = float(np.mean(lls >= field_.params.log_p(cfg.fit_distance)))
            temper = cfg.likelihood_exponent
            prior = np.log(np.maximum(self.weights, 1e-300))
            if self._global_phase:
                # While the belief is spread, one scan may not collapse it: its exponent is cut
                # to keep the effective sample size at global_ess of the samples.
                temper = _anneal_step(prior, loglik, temper, cfg.global_ess * self.samples.shape[0])
            info["temper"] = temper
            logw = prior + temper * loglik
            logw -= logw.max()
            w = np.exp(logw)
            self.weights = w / w.sum()
            # 4. Recovery: augmented MCL's short- and long-term averages of that fit.
            evidence = n_used >= cfg.recovery_min_used * valid.sum()
            if not evidence:
                pass  # too few beams to judge the fit (a crowd all around): no evidence either way
            elif self._w_slow == 0.0:
                self._w_slow = self._w_fast = w_best
            else:
                self._w_slow += cfg.alpha_slow * (w_best - self._w_slow)
                self._w_fast += cfg.alpha_fast * (w_best - self._w_fast)
            ratio = self._w_fast / (cfg.recovery_ratio * self._w_slow) if self._w_slow > 0 else 1.0
            # No injection on a scan that is no evidence (the averages are those of older scans).
            inject_fraction = min(cfg.max_injection, max(0.0, 1.0 - ratio)) if evidence else 0.0
            info["w_best"] = w_best
            info["inject_fraction"] = inject_fraction
        else:
            inject_fraction = 0.0

        # 6. Estimate, before resampling (the weights carry the scan). Readings that pass through
        # mapped walls at the tracked estimate (a crowd cannot lengthen a beam) say it is wrong,
        # however many beams the filter dropped: only then may a recovery guess replace it.
        judged = bool(n_used) and not global_start and not self._global_phase

        def judge(p: FloatArray, others: FloatArray | None = None) -> float:
            return self._too_long_fraction(p, ranges, geometry, valid, others) if judged else math.nan

        def score(poses: FloatArray) -> FloatArray:
            return self._crowd_log_likelihood(poses, ranges, geometry, valid)

        self._n_returns = int(valid.sum())
        pose, cov, cluster_weight, too_long = self._estimate(judge, score)
        ess = 1.0 / float(np.sum(self.weights**2))
        info["ess"] = ess
        info["cluster_weight"] = cluster_weight
        if self._global_phase and not global_start and cluster_weight >= cfg.global_done:
            self._global_phase = False

        # 4b. Recovery on too-long readings: sensor resetting, first around the estimate.
        info["too_long"] = too_long
        if too_long > cfg.lost_fraction:
            inject_fraction = cfg.max_injection
        info["lost_scans"] = float(self._lost_scans)

        # 4c. Verification against the best other place the scan suggests (``verify_period``):
        # due every verify_period seconds, on every scan while the last one failed, and for
        # verify_period seconds after a recovery guess became the track. Judged on every return,
        # also when the filter kept none (a track so wrong that every reading is shorter than
        # expected looks like a crowd all around to the filter).
        reset_poses: FloatArray | None = None
        if self._recovered and cfg.verify_period is not None:
            self._verify_until = scan.timestamp + cfg.verify_period
        self._recovered = False
        due = self._suspect or scan.timestamp >= self._next_verify or scan.timestamp < self._verify_until
        tracking = not global_start and not self._global_phase and valid.sum() >= cfg.lost_min_beams
        if tracking and cfg.verify_period is not None and cfg.max_injection > 0 and due:
            self._next_verify = scan.timestamp + cfg.verify_period
            reset_poses, margin = self._verify(pose, ranges, geometry, field_, valid)
            info["verify_margin"] = margin
            self._suspect = margin > cfg.verify_margin
            if self._suspect:
                inject_fraction = cfg.max_injection
            else:
                reset_poses = None
        if cfg.verify_period is not None:
            info["suspect"] = float(self._suspect)

        # 5. Resampling with KLD-adapted count, and injection of scan-drawn samples.
        if (
            (n_used or reset_poses is not None)
            and not global_start
            and (ess < cfg.resample_threshold * self.samples.shape[0] or inject_fraction > 0.0)
        ):
            injected = self._resample(inject_fraction, ranges, geometry, field_, valid, pose, reset_poses)
        info["injected"] = float(injected)

        est = LocalizationEstimate(
            timestamp=scan.timestamp,
            pose=pose,
            covariance=cov,
            used_beams=used,
            n_samples=int(self.samples.shape[0]),
            updated=n_used > 0,
            update_seconds=time.perf_counter() - t0,
            info=info,
        )
        self.last_estimate = est
        return est

    # ------------------------------------------------------------------ steps

    def _field(self, geometry: LaserGeometry) -> LikelihoodField:
        """The likelihood field for this laser's maximum range (built once per laser)."""
        key = float(geometry.max_range)
        f = self._fields.get(key)
        if f is None:
            f = LikelihoodField.from_grid(self.grid, replace(self._field_params, max_range=key))
            self._fields[key] = f
        return f

    def _caster(self, max_range: float) -> RayCaster:
        """The project's ray caster for expected ranges (built once per laser)."""
        c = self._casters.get(max_range)
        if c is None:
            c = DistanceCaster(self.grid, max_range)
            self._casters[max_range] = c
        return c

    def _select_beams(
        self, valid: NDArray[np.bool_], ranges: FloatArray, geometry: LaserGeometry, field_: LikelihoodField
    ) -> NDArray[np.bool_]:
        cfg = self.config
        if cfg.beam_filter == BeamFilter.NONE or not valid.any():
            return valid
        if cfg.beam_filter == BeamFilter.ENTROPY:
            # H(l | s) of Eq. 4 is the entropy of the belief after integrating s as the update
            # integrates it: with the tempered likelihood p(s | l) ** likelihood_exponent.
            ll = field_.beam_log_likelihoods(self.samples, ranges, geometry)[:, valid]
            lik = np.exp(cfg.likelihood_exponent * ll.astype(np.float64))
            groups = _cell_keys(self.samples, cfg.entropy_cell[0], cfg.entropy_cell[1])
            # Beams equally likely under every sample (a visitor far from any mapped surface: the
            # field is flat there) change nothing and are not counted as integrated: the recovery
            # below would read them as a scan that the best sample explains badly.
            keep = entropy_filter(
                lik, self.weights, groups, cfg.filters.entropy_tolerance, informative_only=True
            )
        else:
            m = min(cfg.novelty_samples, self.samples.shape[0])
            # Eq. 6 averages over the belief that has earned it: freshly injected samples (a
            # recovery guess that has not yet won a scan) would make it two-peaked, and a crowd's
            # short beams would then not look "shorter than expected" enough to be dropped.
            w_est = self._established_weights()
            idx = low_variance_resample(w_est, m, float(self.rng.random()))
            # The drawn hypotheses on the paper's grid (entropy_cell, 15 cm x 2 deg): one ray cast
            # per occupied cell, weighted by its share of the draws, heaviest first.
            cells = _cell_keys(self.samples[idx], cfg.entropy_cell[0], cfg.entropy_cell[1])
            _, first, counts = np.unique(cells, return_index=True, return_counts=True)
            order = np.argsort(-counts, kind="stable")
            idx, hyp_w = idx[first[order]], counts[order] / m
            laser = compose(self.samples[idx], np.asarray(geometry.offset, dtype=np.float64))
            # Eq. 5-6 in one kernel: a beam is ray cast for more hypotheses only while undecided.
            keep = novelty_filter_cast(
                self._caster(float(geometry.max_range)),
                laser,
                hyp_w,
                geometry.angles[valid],
                ranges[valid],
                cfg.sigma_hit,
                float(geometry.max_range),
                cfg.filters.theta,
            )
        used = np.zeros_like(valid)
        used[np.flatnonzero(valid)[keep]] = True
        return used

    def _global_start(
        self, ranges: FloatArray, geometry: LaserGeometry, field_: LikelihoodField, valid: NDArray[np.bool_]
    ) -> int:
        """Integrate the first scan of a global localization by annealed importance sampling.

        ``global_candidates`` poses uniform over the free space (far more than the filter carries:
        on a 1000 m^2 museum, 50000 samples leave a pose within 20 cm and 3 deg of the robot
        unlikely) are scored against every ``global_beam_step``-th return. The tempered likelihood
        ``L ** likelihood_exponent`` of the scan is then brought in by stages ``L ** d_k``
        (Neal 2001, "Annealed importance sampling"; Deutscher, Blake & Reid 2000, the annealed
        particle filter): each ``d_k`` is the largest step that keeps the effective sample size at
        ``global_ess`` of ``global_samples``; the candidates are resampled (low variance) to
        ``global_samples``, jittered by ``global_jitter`` and scored again, with all returns,
        until the exponents sum to ``likelihood_exponent`` (or after ``global_stages`` stages, the
        last one taking what is left). The scan is thus counted once, at the usual temper, while
        the candidates close to its best explanations are refined on the way. KLD-sampling then
        shrinks the set at the next resampling as the belief concentrates. Returns the stages used.
        """
        cfg = self.config
        assert self._global_cells is not None
        grid, cells = self._global_cells
        self._global_cells = None
        n = cfg.global_samples
        cand = _uniform_free_poses(grid, cells, max(cfg.global_candidates, n), self.rng)
        beams = _longest(ranges, valid, cfg.global_long_fraction)
        samples, stages = self._anneal(cand, n, ranges, geometry, field_, beams, cfg.global_stages)
        self.samples = samples
        self.weights = np.full(samples.shape[0], 1.0 / samples.shape[0])
        self._fresh = np.zeros(samples.shape[0], dtype=bool)
        self._held = np.zeros(samples.shape[0], dtype=bool)
        return stages

    def _anneal(
        self,
        cand: FloatArray,
        n: int,
        ranges: FloatArray,
        geometry: LaserGeometry,
        field_: LikelihoodField,
        beams: NDArray[np.bool_],
        max_stages: int,
        score: Callable[[FloatArray, NDArray[np.bool_]], FloatArray] | None = None,
        rng: np.random.Generator | None = None,
    ) -> tuple[FloatArray, int]:
        """``n`` poses drawn from the candidates ``cand`` by the tempered likelihood of ``beams``,
        brought in by stages that keep the effective sample size at ``global_ess * n``; the first
        stage scores every ``global_beam_step``-th beam only, later ones (on ``n`` jittered
        survivors) all of them. ``score(poses, beam_mask)`` is the scan's log-likelihood per pose
        (the likelihood field by default). ``rng``: the localizer's generator by default.
        Returns the poses and the number of stages."""
        cfg = self.config
        rng = self.rng if rng is None else rng
        if score is None:

            def score(poses: FloatArray, mask: NDArray[np.bool_]) -> FloatArray:
                return field_.log_likelihood(poses, ranges, geometry, beam_mask=mask)

        mask = np.zeros_like(beams)
        mask[:: max(1, cfg.global_beam_step)] = True
        mask &= beams
        if not mask.any():
            mask = beams
        ll = score(cand, mask) * (beams.sum() / mask.sum())
        logw = np.zeros(cand.shape[0])
        left = cfg.likelihood_exponent
        jitter = np.asarray(cfg.global_jitter, dtype=np.float64)
        stages = 0
        while True:
            stages += 1
            step = _anneal_step(logw, ll, left, cfg.global_ess * n)
            logw = logw + step * ll
            left -= step
            w = np.exp(logw - logw.max())
            idx = low_variance_resample(w / w.sum(), n, float(rng.random()))
            cand = cand[idx] + rng.standard_normal((n, 3)) * jitter
            cand[:, 2] = wrap_angle(cand[:, 2])
            inside = self._in_free_space(cand)
            if left <= 1e-12 or stages >= max_stages or not inside.any():
                break
            cand = cand[inside]
            ll = score(cand, beams)
            logw = np.zeros(cand.shape[0])
        return np.ascontiguousarray(cand), stages

    def _crowd_log_likelihood(
        self, poses: FloatArray, ranges: FloatArray, geometry: LaserGeometry, beams: NDArray[np.bool_]
    ) -> FloatArray:
        """The scan's log-likelihood per pose under the beam model with expected ranges ray cast
        in the map (Fox et al. 1998 Sec. 2.3: ``p(d | l)`` from the expected distance ``o_l``;
        Probabilistic Robotics Table 6.1), ``recovery_model``'s mixture: its "short" part is the
        visitors (people only ever shorten a beam), while a reading through a mapped wall only
        has the small "random" part. Unlike the likelihood field, which scores a beam by its
        endpoint alone, this sees a look-alike place's beams cross walls."""
        idx = np.flatnonzero(beams)
        if idx.size == 0 or poses.shape[0] == 0:
            return np.zeros(poses.shape[0])
        laser = compose(poses, np.asarray(geometry.offset, dtype=np.float64))
        expected = self._caster(float(geometry.max_range)).cast(laser, geometry.angles[idx])
        return self.config.recovery_model.log_likelihood(expected, ranges[idx], float(geometry.max_range))

    def _established_weights(self) -> FloatArray:
        """The weights with the freshly injected samples' set to zero (all of them if none is left)."""
        if not self._fresh.any():
            return self.weights
        w = np.where(self._fresh, 0.0, self.weights)
        return w if w.sum() > 0 else self.weights

    def _estimate(
        self,
        judge: Callable[[FloatArray, FloatArray | None], float],
        score: Callable[[FloatArray], FloatArray],
    ) -> tuple[FloatArray, FloatArray, float, float]:
        """The heaviest cluster's mean and covariance, its weight, and ``judge`` of the tracked
        estimate (the fraction of too-long readings there, NaN when not judged).

        Freshly injected samples count only once a *guess* (a cluster of them) has won
        ``fresh_wins`` scans in a row (:meth:`_best_guess`): on a scan that contradicts the
        tracked estimate (more than ``lost_fraction`` of its readings pass through mapped walls
        there, or a verification failed), the guess that the crowd beam model (``score``,
        :meth:`_crowd_log_likelihood`) rates highest at its mean, and that the too-long test
        (``judge``) contradicts less than the track, wins if it scores above the track; on a scan that does
        not, only a guess at another place can win, by the verification's margin. The guess is
        chosen by that model and not by the weights: the weights carry the likelihood field,
        which scores a beam by its endpoint alone and, in a crowd, may rate a look-alike place
        turned around above the true one (FHW, docs/design-notes.md) while the beam model sees the
        look-alike's readings pass through walls. The guess that wins a scan is *held*: the
        other fresh samples lose their weight, new guesses do not replace it
        (:meth:`_resample`), and it is judged first on the next scan, where it must win again.
        Then its cluster becomes the belief (the other samples lose their weight) and every
        sample is established; until then the estimate is the heaviest cluster of the
        established samples. Guesses in the track's own cluster on a scan that does not
        contradict the track join it. On a scan that is no evidence (``judge`` NaN, and no
        failed verification) no guess is judged: none wins, the held guess stays held,
        ``_lost_scans`` is kept. During
        global localization the rule of
        :meth:`_heaviest_guess` applies. A crowd makes a look-alike place fit some scans better
        than the true one, but it cannot make the true pose see through walls.
        """
        cfg = self.config
        labels = cluster_bins(self.samples, cfg.kld_bin[0], cfg.kld_bin[2])
        pose, cov, weight = best_cluster_estimate(self.samples, self._established_weights(), labels)
        too_long = judge(pose, None)
        if math.isnan(too_long):
            pass  # not judged, or the crowd hides the building: no evidence either way
        elif too_long > cfg.lost_fraction:
            self._lost_scans += 1
            self._passed = 0
        else:
            self._lost_scans = 0
            self._passed += 1
            # A wrong track passes now and then (0.28 at a look-alike 17 m off, FHW seed 4):
            # only global_after passes in a row confirm a track from global localization.
            self._unconfirmed = self._unconfirmed and self._passed < cfg.global_after
        # The track stays contradicted through scans that are no evidence (NaN), and while the
        # last verification found a clearly better place (``_suspect``).
        contradicted = self._global_phase or self._lost_scans > 0 or self._suspect
        if self._fresh.any() and not contradicted:
            # Guesses that lie in the track's own cluster on a scan that does not contradict it
            # are the track: they join it (and no longer pose as another place).
            track = int(np.argmax(np.bincount(labels, weights=self._established_weights())))
            self._fresh &= labels != track
        guess: NDArray[np.bool_] | None = None
        if math.isnan(too_long) and not (self._global_phase or self._suspect):
            # A scan that is no evidence (too few returns to judge) neither confirms nor
            # contradicts anything: no guess wins it, and the held guess stays held. (A failed
            # verification judged every return under the crowd beam model: it still stands.)
            return pose, cov, weight, too_long
        if self._global_phase and self._fresh.any():
            guess = self._heaviest_guess(labels, pose, score)
            self._fresh_won = self._fresh_won + 1 if guess is not None else 0
        elif self._fresh.any():
            guess = self._best_guess(labels, pose, score, judge, contradicted, too_long)
            # The same guess (it holds samples of the last scan's winner) must win in a row.
            same = guess is not None and bool((guess & self._held).any())
            self._fresh_won = 0 if guess is None else self._fresh_won + 1 if same else 1
        else:
            self._fresh_won = 0
        self._held = np.zeros(self._fresh.shape, dtype=bool)
        if guess is not None and self._fresh_won >= cfg.fresh_wins:
            mine = labels == int(labels[np.flatnonzero(guess)[0]])
            w = np.where(mine, self.weights, 0.0)
            self.weights = w / w.sum() if w.sum() > 0 else mine / mine.sum()
            self._fresh[:] = False
            self._fresh_won = 0
            pose, cov, weight = best_cluster_estimate(self.samples, self.weights, labels)
            # a recovery guess is now the track: verify it on this scan already
            self._suspect = cfg.verify_period is not None
            self._recovered = True
        elif guess is not None and not self._global_phase:
            # The guess is held until the next scan (new guesses do not replace it); the other
            # guesses go.
            w = np.where(self._fresh & ~guess, 0.0, self.weights)
            if not w[guess].sum() > 0:
                w[guess] = w.sum() / guess.sum() if w.sum() > 0 else 1.0
            self.weights = w / w.sum()
            self._held = guess
        return pose, cov, weight, too_long

    def _heaviest_guess(
        self, labels: IntArray, tracked: FloatArray, score: Callable[[FloatArray], FloatArray]
    ) -> NDArray[np.bool_] | None:
        """During global localization (a spread belief, no track to contradict): the samples of
        the heaviest cluster if fresh samples hold most of its weight, else those of the
        heaviest cluster of fresh samples if the crowd beam model (``score``) rates its mean
        above the ``tracked`` estimate (the heaviest established cluster); None otherwise."""
        fresh_w = np.where(self._fresh, self.weights, 0.0)
        w_fresh = np.bincount(labels, weights=fresh_w)
        w_old = np.bincount(labels, weights=self.weights - fresh_w, minlength=w_fresh.size)
        best = int(np.argmax(w_fresh + w_old))
        if w_fresh[best] > w_old[best]:
            return labels == best
        guess = int(np.argmax(w_fresh))
        if not w_fresh[guess] > 0:
            return None
        mine = labels == guess
        f_pose = best_cluster_estimate(
            self.samples[mine], self.weights[mine], np.zeros(int(mine.sum()), np.int64)
        )[0]
        ll = score(np.stack([f_pose, tracked]))
        return mine if ll[0] > ll[1] else None

    def _best_guess(
        self,
        labels: IntArray,
        tracked: FloatArray,
        score: Callable[[FloatArray], FloatArray],
        judge: Callable[[FloatArray, FloatArray | None], float],
        contradicted: bool,
        track_too_long: float = math.nan,
    ) -> NDArray[np.bool_] | None:
        """The fresh samples of the best guess, if it beats the ``tracked`` estimate.

        The guesses are the clusters of fresh samples that carry weight, each judged at its
        weighted mean by ``score`` (the scan's log-likelihood under the crowd beam model per
        pose) beside the tracked estimate. When the track is ``contradicted`` (too-long readings,
        a failed verification, global localization) a guess wins when it scores above the
        track. Otherwise only guesses at another place (more than ``verify_distance`` from the
        track) are judged, and one wins when it explains the scan better than the track by more
        than ``verify_margin`` nats per return: the verification's likelihood ratio test
        (:meth:`_verify`) on the guesses the filter already carries, for a wrong track that the
        too-long test cannot see (moved along a hall, every reading shorter than expected).
        Either way a guess that the too-long test (``judge``, at its mean and its
        ``lost_hypotheses`` heaviest samples) contradicts cannot win unless the track's own
        fraction (``track_too_long``) is larger still (too few returns left to judge is no
        evidence either way): against a track that a crowd has pulled off by a few decimetres, a
        place whose walls the scan sees through may score higher under the crowd beam model and
        would replace a nearly right track by a wrong one, while the true pose itself fails the
        test on a few per cent of the scans where the map and the building disagree (glass,
        corners; ``lost_fraction`` in :class:`MCLConfig`). The best guess that passes wins,
        except that the guess held since the last scan (``_held``) stays the guess if it passes
        and scores within the verification's margin of the best: the means of small clusters
        score higher than those of spread ones by chance. Returns the mask of the winning
        guess's fresh samples, or None."""
        cfg = self.config
        live = self._fresh & (self.weights > 0)
        if not live.any():
            return None
        ids = np.unique(labels[live])
        means = np.empty((ids.size, 3))
        for k, c in enumerate(ids.tolist()):
            mine = live & (labels == c)
            means[k] = _weighted_mean_cov(self.samples[mine], self.weights[mine])[0]
        judged = np.ones(ids.size, dtype=bool)
        if not contradicted:
            judged = (
                np.hypot(means[:, 0] - tracked[0], means[:, 1] - tracked[1]) > cfg.verify_distance[0]
            ) | (np.abs(wrap_angle(means[:, 2] - tracked[2])) > cfg.verify_distance[1])
            if not judged.any():
                return None
        ids, means = ids[judged], means[judged]
        ll = score(np.vstack([means, tracked[None, :]]))
        margin = cfg.verify_margin * self._n_returns
        need = 0.0 if contradicted else margin
        held = np.isin(ids, labels[self._held & live])
        best: int | None = None
        for k in np.argsort(-ll[:-1], kind="stable").tolist():
            if not ll[k] - ll[-1] > need or (best is not None and not held[k]):
                continue
            mine = live & (labels == int(ids[k]))
            heaviest = np.flatnonzero(mine)[
                np.argsort(-self.weights[mine], kind="stable")[: cfg.lost_hypotheses]
            ]
            too_long = judge(means[k], self.samples[heaviest])
            if too_long > cfg.lost_fraction and not too_long < track_too_long:  # NaN: no evidence
                continue
            if held[k] and (best is None or ll[k] >= ll[best] - margin):
                best = k  # the held guess stays the guess unless another is clearly better
                break
            if best is None:
                best = k
                if not held.any():
                    break
        return None if best is None else live & (labels == int(ids[best]))

    def _resample(
        self,
        inject_fraction: float,
        ranges: FloatArray,
        geometry: LaserGeometry,
        field_: LikelihoodField,
        valid: NDArray[np.bool_],
        estimate: FloatArray,
        reset_poses: FloatArray | None = None,
    ) -> int:
        """Resample (KLD count) and replace ``inject_fraction`` of the samples by fresh poses:
        ``reset_poses`` when given (a verification's search), else :meth:`_scan_drawn_poses`."""
        cfg = self.config
        n_max = max(cfg.max_samples, cfg.min_samples)
        if self._global_phase:
            n_max = max(n_max, cfg.global_samples)  # a spread belief keeps its large sample set
        if self._fresh.any() and not self._fresh.all():
            # Until the fresh samples have won (see _estimate), each group keeps its share of the
            # samples: one scan that favours a look-alike place must not wipe out the track.
            n_f = round(n_max * self._fresh.mean())
            groups = [np.flatnonzero(~self._fresh), np.flatnonzero(self._fresh)]
            parts = []
            for g, k in zip(groups, (n_max - n_f, n_f), strict=True):
                wg = self.weights[g]
                wg = wg / wg.sum() if wg.sum() > 0 else np.full(g.size, 1.0 / g.size)
                parts.append(g[low_variance_resample(wg, k, float(self.rng.random()))])
            idx = np.concatenate(parts)
        else:
            idx = low_variance_resample(self.weights, n_max, float(self.rng.random()))
        idx = idx[self.rng.permutation(n_max)]
        drawn = self.samples[idx]
        n = kld_sample_count(drawn, cfg.kld_bin, cfg.kld_epsilon, cfg.kld_quantile, cfg.min_samples, n_max)
        new = drawn[:n].copy()
        fresh = self._fresh[idx[:n]].copy()
        held = self._held[idx[:n]]
        n_inject = round(inject_fraction * n)
        if n_inject:
            # The new guesses replace the older ones that have not won first, so fresh samples
            # never outnumber max_injection of the set, however long a crowd keeps resetting,
            # besides the guess that won this scan (held: it must win the next one too).
            slots = np.concatenate([np.flatnonzero(fresh & ~held), np.flatnonzero(~fresh)])[:n_inject]
            drawn_poses = reset_poses
            if drawn_poses is None:
                # A track that global localization found and that has not yet passed the too-long
                # test on global_after scans in a row may be a look-alike anywhere: it is searched
                # for over the whole free space at once, with the cast table's screening too
                # (docs/design-notes.md "Run 7d").
                wide = self._unconfirmed
                far = wide or self._lost_scans == 0 or self._lost_scans >= cfg.global_after
                drawn_poses = self._scan_drawn_poses(
                    n_inject, ranges, geometry, field_, valid, estimate, far, table=wide
                )
            slots = slots[: drawn_poses.shape[0]]
            new[slots] = drawn_poses[: slots.size]
            fresh[slots] = True
        self.samples = np.ascontiguousarray(new)
        self.weights = np.full(n, 1.0 / n)
        self._fresh = fresh
        self._held = held & fresh
        return n_inject

    def _scan_drawn_poses(
        self,
        n: int,
        ranges: FloatArray,
        geometry: LaserGeometry,
        field_: LikelihoodField,
        valid: NDArray[np.bool_],
        estimate: FloatArray,
        far: bool,
        keep_fresh: bool = False,
        rng: np.random.Generator | None = None,
        verifying: bool = False,
        table: bool = False,
    ) -> FloatArray:
        """Sensor resetting: ``n`` poses drawn from candidates by the crowd beam model of the
        current scan (:meth:`_crowd_log_likelihood`).

        Candidates are ``injection_local_candidates`` poses around the estimate
        (``injection_local_std`` metres, any heading: a drift in a crowd, a kidnap by a metre);
        with ``far`` (the caller's choice: once the estimate has been contradicted on
        ``global_after`` scans in a row, when the fit of the scan triggered the reset, or for a
        verification), also the ``injection_survivors`` best of
        ``injection_candidates`` poses uniform over the free space, screened by the likelihood
        field of the longest returns (cheap, no ray casting; ``verify_candidates`` of them for a
        verification, ``verifying``, which also adds the ``table_survivors`` best poses of the cast
        table, :meth:`_table_poses`; so does ``table``, for a track from global localization not
        yet confirmed by the too-long test), and with ``keep_fresh`` the fresh
        samples (earlier scans' guesses, moved by the odometry since: a search that missed the
        true place once need not miss it again). The pool is then annealed on the
        beam model (every ``global_beam_step``-th return first, all of them after) down to
        ``injection_survivors`` poses, of which ``n`` are kept at random.
        """
        cfg = self.config
        rng = self.rng if rng is None else rng
        keep = max(n, cfg.injection_survivors)
        m = cfg.verify_local_candidates if verifying else cfg.injection_local_candidates
        pool = [
            np.column_stack(
                [
                    estimate[0] + cfg.injection_local_std * rng.standard_normal(m),
                    estimate[1] + cfg.injection_local_std * rng.standard_normal(m),
                    rng.uniform(-math.pi, math.pi, m),
                ]
            )
        ]
        n_far = cfg.verify_candidates if verifying else cfg.injection_candidates
        if far and n_far > 0:
            far_poses = _uniform_free_poses(self.grid, self._free_cells, n_far, rng)
            longest = _longest(ranges, valid, cfg.injection_long_fraction)
            if longest.any():
                far_poses = self._anneal(far_poses, keep, ranges, geometry, field_, longest, 1, rng=rng)[0]
            pool.append(far_poses[: cfg.injection_survivors])
        if far and (verifying or table):
            pool.append(self._table_poses(ranges, geometry, valid))
        if keep_fresh and self._fresh.any():
            pool.append(self.samples[self._fresh])  # the guesses of earlier scans, moved since
        cand = np.vstack(pool)
        cand = cand[self._in_free_space(cand)]
        if not valid.any() or cand.shape[0] == 0:
            return cand[:n]

        def score(poses: FloatArray, mask: NDArray[np.bool_]) -> FloatArray:
            return self._crowd_log_likelihood(poses, ranges, geometry, mask)

        drawn = self._anneal(cand, keep, ranges, geometry, field_, valid, cfg.injection_stages, score, rng)[0]
        return drawn[rng.permutation(drawn.shape[0])[:n]]

    def _table_poses(
        self, ranges: FloatArray, geometry: LaserGeometry, valid: NDArray[np.bool_]
    ) -> FloatArray:
        """The ``table_survivors`` best poses of the cast table's lattice (:class:`CastTable`:
        ``table_spacing`` metres, ``table_directions`` headings) by the crowd beam model
        (``recovery_model``) of ``table_beams`` returns spread evenly over the scan. Unlike the
        likelihood field of the longest returns, this sees a place's short walls and the
        readings that would pass through them (a nook whose opening the crowd hides)."""
        cfg = self.config
        idx = np.flatnonzero(valid)
        if cfg.table_survivors <= 0 or idx.size == 0:
            return np.zeros((0, 3))
        key = float(geometry.max_range)
        table = self._tables.get(key)
        if table is None:
            table = CastTable.build(self.grid, self._caster(key), cfg.table_spacing, cfg.table_directions)
            self._tables[key] = table
        idx = idx[
            np.unique(np.round(np.linspace(0, idx.size - 1, min(cfg.table_beams, idx.size))).astype(np.int64))
        ]
        laser, _ = table.screen(ranges[idx], geometry.angles[idx], cfg.recovery_model, cfg.table_survivors)
        return compose(laser, invert(np.asarray(geometry.offset, dtype=np.float64)))

    def _verify(
        self,
        pose: FloatArray,
        ranges: FloatArray,
        geometry: LaserGeometry,
        field_: LikelihoodField,
        valid: NDArray[np.bool_],
    ) -> tuple[FloatArray, float]:
        """Search the map for the places that best explain the scan (:meth:`_scan_drawn_poses`,
        around the estimate and over the whole free space) and compare the best of them with the
        tracked ``pose`` under the crowd beam model (:meth:`_crowd_log_likelihood`): a likelihood
        ratio test of the track against its best alternative. Only other places are
        alternatives: poses more than ``verify_distance`` (1 m or 30 deg) from the track (the
        track a few centimetres off is the same place, and refining it is the filter's job).
        Returns the drawn poses (the reset samples, should the track lose) and the margin, the
        difference of the two log-likelihoods per return (0 when no other place explains the
        scan better).

        The too-long test (:meth:`_too_long_fraction`) cannot see every wrong pose: moved along
        a hall or a corridor, the track's readings are mostly shorter than expected on one side
        (excused as visitors) and about right elsewhere. Under the crowd model a shorter
        reading costs (``z_short`` instead of ``z_hit``) where the true pose explains it, so a
        true place wins by several nats per return, while at a correct track the best
        alternative is the track itself, a few centimetres off.
        """
        cfg = self.config
        n = max(1, round(cfg.max_injection * max(self.samples.shape[0], cfg.max_samples)))
        drawn = self._scan_drawn_poses(
            n,
            ranges,
            geometry,
            field_,
            valid,
            pose,
            True,
            keep_fresh=True,
            rng=self._verify_rng,
            verifying=True,
        )
        n_valid = int(valid.sum())
        # only another place counts: the track itself a little off is no alternative
        away = (np.hypot(drawn[:, 0] - pose[0], drawn[:, 1] - pose[1]) > cfg.verify_distance[0]) | (
            np.abs(wrap_angle(drawn[:, 2] - pose[2])) > cfg.verify_distance[1]
        )
        if not away.any() or n_valid == 0:
            return drawn, 0.0
        others = drawn[away]
        ll = self._crowd_log_likelihood(np.vstack([pose[None, :], others]), ranges, geometry, valid)
        return drawn, max(0.0, float(ll[1:].max() - ll[0]) / n_valid)

    def _too_long_fraction(
        self,
        pose: FloatArray,
        ranges: FloatArray,
        geometry: LaserGeometry,
        valid: NDArray[np.bool_],
        others: FloatArray | None = None,
    ) -> float:
        """Of the returns that are not shorter than expected (the ones a crowd left alone), the
        fraction longer than expected by more than ``lost_margin``: readings through mapped
        walls, the signature of a wrong pose (Fox et al. 1998: the novelty filter keeps "very
        unlikely sensor measurements (especially too long readings)"). Judged at ``pose`` and at
        ``lost_hypotheses`` samples drawn by weight from the established belief; the smallest
        fraction counts, so a scan contradicts the track only when no plausible pose of it
        explains the scan (a few centimetres or a degree off, long beams may graze past a
        corner). ``others``, when given, replace those samples (a recovery guess's own). NaN
        when every pose has fewer than ``lost_min_beams`` returns to judge."""
        cfg = self.config
        if not valid.any():
            return math.nan
        if others is None:
            k = min(cfg.lost_hypotheses, self.samples.shape[0])
            idx = low_variance_resample(self._established_weights(), k, float(self.rng.random()))
            others = self.samples[idx]
        poses = np.vstack([pose[None, :], others])
        laser = compose(poses, np.asarray(geometry.offset, dtype=np.float64))
        expected = self._caster(float(geometry.max_range)).cast(laser, geometry.angles[valid])
        measured = ranges[valid][None, :]
        longer = measured > expected + cfg.lost_margin
        n_seen = (longer | (measured >= expected - cfg.lost_margin)).sum(axis=1)
        judged = n_seen >= cfg.lost_min_beams
        if not judged.any():
            return math.nan
        return float(np.min(longer.sum(axis=1)[judged] / n_seen[judged]))

    def _in_free_space(self, poses: FloatArray) -> NDArray[np.bool_]:
        rc = self.grid.world_to_cell(poses[:, :2])
        inside = self.grid.inside(rc)
        out = np.zeros(poses.shape[0], dtype=bool)
        out[inside] = self._free[rc[inside, 0], rc[inside, 1]]
        return out


# ---------------------------------------------------------------------- helpers


def _uniform_free_poses(grid: OccupancyGrid, cells: IntArray, n: int, rng: np.random.Generator) -> FloatArray:
    """``n`` poses uniform over the free cells (uniform inside each cell, uniform heading)."""
    pick = cells[rng.integers(0, cells.shape[0], n)]
    local = (pick[:, ::-1] + rng.random((n, 2))) * grid.resolution  # (col, row) -> (x, y)
    th = rng.uniform(-math.pi, math.pi, n)
    return grid.grid_to_world(np.column_stack([local, th - grid.origin[2]]))


def _longest(ranges: FloatArray, valid: NDArray[np.bool_], fraction: float) -> NDArray[np.bool_]:
    """The ``fraction`` longest of the ``valid`` returns: people only ever shorten a beam, so
    in a crowd the longest readings are the ones most likely to see the building."""
    k = int(valid.sum())
    keep = max(1, math.ceil(fraction * k))
    if keep >= k:
        return valid
    cut = np.sort(ranges[valid])[k - keep]
    return valid & (ranges >= cut)


def _anneal_step(logw: FloatArray, ll: FloatArray, most: float, ess: float) -> float:
    """The largest exponent ``d <= most`` for which the weights ``exp(logw + d * ll)`` keep an
    effective sample size of at least ``ess`` (bisection; ESS falls as ``d`` grows)."""

    def ess_of(d: float) -> float:
        lw = logw + d * ll
        w = np.exp(lw - lw.max())
        return float(w.sum() ** 2 / np.sum(w * w))

    if ess_of(most) >= ess:
        return most
    lo, hi = 0.0, most
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        if ess_of(mid) >= ess:
            lo = mid
        else:
            hi = mid
    return lo


def _cell_keys(samples: FloatArray, cell: float, cell_theta: float) -> IntArray:
    """An integer label per sample: the cell of a ``cell x cell x cell_theta`` grid holding it."""
    ix = np.floor(samples[:, 0] / cell).astype(np.int64)
    iy = np.floor(samples[:, 1] / cell).astype(np.int64)
    n_th = max(1, round(2 * math.pi / cell_theta))
    it = np.floor((samples[:, 2] + math.pi) / (2 * math.pi) * n_th).astype(np.int64) % n_th
    ix -= ix.min()
    iy -= iy.min()
    return (ix * (int(iy.max()) + 1) + iy) * n_th + it


def best_cluster_estimate(
    samples: FloatArray, weights: FloatArray, labels: IntArray
) -> tuple[FloatArray, FloatArray, float]:
    """The heaviest cluster's weighted mean pose (circular mean of headings), covariance and weight.

    A numba kernel; :func:`best_cluster_estimate_reference` is its plain-numpy reference.
    """
    n_labels = int(labels.max()) + 1 if labels.size else 0
    pose = np.zeros(3)
    cov = np.zeros((3, 3))
    w = _best_cluster_kernel(
        np.ascontiguousarray(samples, dtype=np.float64),
        np.ascontiguousarray(weights, dtype=np.float64),
        np.ascontiguousarray(labels, dtype=np.int64),
        n_labels,
        pose,
        cov,
    )
    return pose, cov, w


@numba.njit(cache=True)
def _best_cluster_kernel(
    samples: FloatArray,
    weights: FloatArray,
    labels: IntArray,
    n_labels: int,
    pose: FloatArray,
    cov: FloatArray,
) -> float:
    cw = np.zeros(n_labels)
    for i in range(labels.shape[0]):
        cw[labels[i]] += weights[i]
    best = 0
    for k in range(n_labels):
        if cw[k] > cw[best]:
            best = k
    total = cw[best]
    mx = 0.0
    my = 0.0
    sn = 0.0
    cs = 0.0
    for i in range(labels.shape[0]):
        if labels[i] == best:
            w = weights[i] / total
            mx += w * samples[i, 0]
            my += w * samples[i, 1]
            sn += w * math.sin(samples[i, 2])
            cs += w * math.cos(samples[i, 2])
    mth = math.atan2(sn, cs)
    pose[0] = mx
    pose[1] = my
    pose[2] = mth
    c00 = c01 = c02 = c10 = c11 = c12 = c20 = c21 = c22 = 0.0
    for i in range(labels.shape[0]):
        if labels[i] == best:
            w = weights[i] / total
            d0 = samples[i, 0] - mx
            d1 = samples[i, 1] - my
            d2 = _wrap(samples[i, 2] - mth)
            c00 += w * d0 * d0
            c01 += w * d0 * d1
            c02 += w * d0 * d2
            c10 += w * d1 * d0
            c11 += w * d1 * d1
            c12 += w * d1 * d2
            c20 += w * d2 * d0
            c21 += w * d2 * d1
            c22 += w * d2 * d2
    cov[0, 0], cov[0, 1], cov[0, 2] = c00, c01, c02
    cov[1, 0], cov[1, 1], cov[1, 2] = c10, c11, c12
    cov[2, 0], cov[2, 1], cov[2, 2] = c20, c21, c22
    return total


def best_cluster_estimate_reference(
    samples: FloatArray, weights: FloatArray, labels: IntArray
) -> tuple[FloatArray, FloatArray, float]:
    """Plain-numpy reference of :func:`best_cluster_estimate`."""
    cw = np.bincount(labels, weights=weights)
    best = int(np.argmax(cw))
    sel = labels == best
    pose, cov = _weighted_mean_cov(samples[sel], weights[sel])
    return pose, cov, float(cw[best])


def _weighted_mean_cov(samples: FloatArray, weights: FloatArray) -> tuple[FloatArray, FloatArray]:
    w = weights / weights.sum()
    mx = float(w @ samples[:, 0])
    my = float(w @ samples[:, 1])
    mth = math.atan2(float(w @ np.sin(samples[:, 2])), float(w @ np.cos(samples[:, 2])))
    d = np.column_stack([samples[:, 0] - mx, samples[:, 1] - my, wrap_angle(samples[:, 2] - mth)])
    cov = (d * w[:, None]).T @ d
    return np.array([mx, my, mth]), np.asarray(cov, dtype=np.float64)


# ---------------------------------------------------------------------- resampling


@numba.njit(cache=True)
def _low_variance_kernel(cum: FloatArray, n: int, u0: float, out: IntArray) -> None:
    step = cum[-1] / n
    j = 0
    m = cum.shape[0]
    for i in range(n):
        u = (u0 + i) * step
        while j < m - 1 and cum[j] < u:
            j += 1
        out[i] = j


def low_variance_resample(weights: ArrayLike, n: int, u0: float) -> IntArray:
    """Low-variance (systematic) resampling: ``n`` indices drawn by weight (PR Table 4.4).

    ``u0`` in [0, 1) is the one random number: the ``i``-th pointer is ``(u0 + i) / n`` of the
    total weight.
    """
    w = np.asarray(weights, dtype=np.float64).ravel()
    cum = np.cumsum(w)
    out = np.empty(n, dtype=np.int64)
    if n:
        _low_variance_kernel(cum, n, u0, out)
    return out


def low_variance_resample_reference(weights: ArrayLike, n: int, u0: float) -> IntArray:
    """Plain-numpy reference of :func:`low_variance_resample`."""
    w = np.asarray(weights, dtype=np.float64).ravel()
    cum = np.cumsum(w)
    pointers = (u0 + np.arange(n)) * (cum[-1] / n)
    idx = np.searchsorted(cum, pointers, side="left")
    return np.minimum(idx, w.shape[0] - 1).astype(np.int64)


# ---------------------------------------------------------------------- KLD-sampling


def _bin_keys(samples: FloatArray, cell: float, cell_theta: float) -> tuple[IntArray, int, int]:
    """Integer bins ``(ix, iy, it)`` packed in one key, with the strides used to pack them."""
    return _bin_keys_kernel(np.ascontiguousarray(samples), cell, cell_theta)


@numba.njit(cache=True)
def _bin_keys_kernel(samples: FloatArray, cell: float, cell_theta: float) -> tuple[IntArray, int, int]:
    n = samples.shape[0]
    n_th = max(1, round(2.0 * math.pi / cell_theta))
    ix = np.empty(n, np.int64)
    iy = np.empty(n, np.int64)
    it = np.empty(n, np.int64)
    for i in range(n):
        ix[i] = math.floor(samples[i, 0] / cell)
        iy[i] = math.floor(samples[i, 1] / cell)
        t = math.floor((samples[i, 2] + math.pi) / (2.0 * math.pi) * n_th) % n_th
        it[i] = t
    x0 = ix.min() - 1 if n else 0
    y0 = iy.min() - 1 if n else 0
    ny = (iy.max() - y0 + 2) if n else 1
    keys = np.empty(n, np.int64)
    for i in range(n):
        keys[i] = ((ix[i] - x0) * ny + (iy[i] - y0)) * n_th + it[i]
    return keys, ny, n_th


def kld_bounds(k_max: int, epsilon: float, quantile: float) -> IntArray:
    """Fox 2003, Eq. 13, for ``k = 0 .. k_max``: samples needed so that, with probability
    ``quantile``, the KL divergence between the sample-based and the true belief stays below
    ``epsilon`` when the samples fall in ``k`` bins."""
    z = NormalDist().inv_cdf(quantile)
    k = np.arange(k_max + 1, dtype=np.float64)
    km1 = np.maximum(k - 1.0, 1.0)
    a = 2.0 / (9.0 * km1)
    n = np.ceil(km1 / (2.0 * epsilon) * (1.0 - a + np.sqrt(a) * z) ** 3)
    return np.where(k <= 1, 1, n).astype(np.int64)


@functools.lru_cache(maxsize=8)
def _kld_bounds_cached(k_max: int, epsilon: float, quantile: float) -> IntArray:
    return kld_bounds(k_max, epsilon, quantile)


@numba.njit(cache=True)
def _kld_count_kernel(keys: IntArray, bounds: IntArray, n_min: int, n_max: int) -> int:
    seen = set()
    seen.add(keys[0])
    k = 1
    for i in range(1, keys.shape[0]):
        if keys[i] not in seen:
            seen.add(keys[i])
            k += 1
        n = i + 1
        if n >= n_min and n >= bounds[min(k, bounds.shape[0] - 1)]:
            return n
        if n >= n_max:
            return n_max
    return keys.shape[0]


def kld_sample_count(
    drawn: FloatArray,
    kld_bin: tuple[float, float, float],
    epsilon: float,
    quantile: float,
    n_min: int,
    n_max: int,
) -> int:
    """KLD-sampling (Fox 2003, Table 1): how many of the samples ``drawn`` (in random order) to keep.

    Walks the samples, counting occupied bins ``k``, and stops as soon as the count reaches the
    bound of Eq. 13 for ``k`` (and ``n_min``), or ``n_max``.
    """
    n = drawn.shape[0]
    if n == 0:
        return 0
    keys, _, _ = _bin_keys(drawn, kld_bin[0], kld_bin[2])
    bounds = _kld_bounds_cached(n + 1, epsilon, quantile)
    return int(min(_kld_count_kernel(keys, bounds, n_min, min(n, n_max)), n))


# ---------------------------------------------------------------------- clustering


@numba.njit(cache=True)
def _find(parent: IntArray, i: int) -> int:
    root = i
    while parent[root] != root:
        root = parent[root]
    while parent[i] != root:
        nxt = parent[i]
        parent[i] = root
        i = nxt
    return root


_EMPTY = -1  # an empty slot of the bin hash table (bin keys are >= 0, see _bin_keys_kernel)


@numba.njit(cache=True, inline="always")
def _slot(table: IntArray, key: int, mask: int) -> np.int64:
    """The slot of ``key`` in the open-addressing hash table ``table`` (linear probing): where it
    is, or the empty slot where it would go."""
    h = (np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(32)
    j = np.int64(h) & mask
    while table[j] != _EMPTY and table[j] != key:
        j = (j + 1) & mask
    return j


@numba.njit(cache=True)
def _cluster_kernel(keys: IntArray, ny: int, n_th: int) -> IntArray:
    """Union-find over the occupied bins, found through a hash table of their keys (no sort):
    each bin is joined with its 26 neighbours that hold samples."""
    n = keys.shape[0]
    cap = 16
    while cap < 2 * n:
        cap *= 2
    mask = cap - 1
    table = np.full(cap, _EMPTY, np.int64)
    bin_at = np.empty(cap, np.int64)  # bin index of the key in each occupied slot
    bin_of = np.empty(n, np.int64)
    uniq = np.empty(n, np.int64)
    m = 0
    for i in range(n):
        j = _slot(table, keys[i], mask)
        if table[j] == _EMPTY:
            table[j] = keys[i]
            bin_at[j] = m
            uniq[m] = keys[i]
            m += 1
        bin_of[i] = bin_at[j]
    parent = np.arange(m)
    for b in range(m):
        key = uniq[b]
        it = key % n_th
        rest = key // n_th
        iy = rest % ny
        ix = rest // ny
        for dx in range(-1, 2):
            for dy in range(-1, 2):
                for dt in range(-1, 2):
                    t = (it + dt) % n_th
                    nk = ((ix + dx) * ny + (iy + dy)) * n_th + t
                    j = _slot(table, nk, mask)
                    if table[j] != _EMPTY:
                        ra = _find(parent, b)
                        rb = _find(parent, bin_at[j])
                        if ra != rb:
                            parent[max(ra, rb)] = min(ra, rb)
    # compact labels, numbered in order of first appearance
    label_of_root = np.full(m, -1, np.int64)
    labels = np.empty(n, np.int64)
    nl = 0
    for i in range(n):
        r = _find(parent, bin_of[i])
        if label_of_root[r] < 0:
            label_of_root[r] = nl
            nl += 1
        labels[i] = label_of_root[r]
    return labels


def cluster_bins(samples: ArrayLike, cell: float, cell_theta: float) -> IntArray:
    """Cluster labels ``(N,)``: samples in bins that touch (26-neighbourhood, heading wraps) share one.

    Labels are numbered in order of first appearance.
    """
    s = np.ascontiguousarray(samples, dtype=np.float64).reshape(-1, 3)
    if s.shape[0] == 0:
        return np.zeros(0, np.int64)
    keys, ny, n_th = _bin_keys(s, cell, cell_theta)
    return np.asarray(_cluster_kernel(keys, ny, n_th), dtype=np.int64)


def cluster_bins_reference(samples: ArrayLike, cell: float, cell_theta: float) -> IntArray:
    """Plain-Python reference of :func:`cluster_bins` (breadth-first search over occupied bins)."""
    s = np.asarray(samples, dtype=np.float64).reshape(-1, 3)
    n_th = max(1, round(2 * math.pi / cell_theta))
    bins = [
        (
            math.floor(x / cell),
            math.floor(y / cell),
            math.floor((t + math.pi) / (2 * math.pi) * n_th) % n_th,
        )
        for x, y, t in s
    ]
    occupied = set(bins)
    comp: dict[tuple[int, int, int], int] = {}
    for start in dict.fromkeys(bins):
        if start in comp:
            continue
        root = len(set(comp.values()))
        comp[start] = root
        stack = [start]
        while stack:
            bx, by, bt = stack.pop()
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    for dt in (-1, 0, 1):
                        nb = (bx + dx, by + dy, (bt + dt) % n_th)
                        if nb in occupied and nb not in comp:
                            comp[nb] = root
                            stack.append(nb)
    return np.array([comp[b] for b in bins], dtype=np.int64)
