"""The typed configuration of Monte Carlo localization, in four groups.

Defaults are the values of the papers and the textbook where they give one (Fox, Burgard, Dellaert
& Thrun 1999; Fox 2003; Thrun, Burgard & Fox, *Probabilistic Robotics*, 2005, "PR"; Nav2 AMCL where
the book leaves a number open); the rest are this implementation's own choices, said so. Values
tuned on a site live in that site's profile (``src/tourbot/sites/fhw/localization.yaml``), loaded by
``--config`` (:mod:`tourbot.configuration`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from tourbot.localization.beam_filters import BeamFilter, BeamFilterConfig
from tourbot.localization.errors import LocalizationError
from tourbot.localization.motion_model import OdometryMotionModel
from tourbot.maps.beam_model import BeamModel
from tourbot.maps.likelihood_field import LikelihoodFieldParams

__all__ = ["GlobalConfig", "MCLConfig", "RecoveryConfig", "SamplingConfig", "SearchConfig", "SensorConfig"]


@dataclass(frozen=True)
class SamplingConfig:
    """Sample count, KLD-sampling and resampling.

    - ``min_samples`` / ``max_samples``: bounds of the KLD-adapted sample count (Nav2 AMCL's
      ``min_particles`` 500 / ``max_particles`` 2000).
    - ``kld_epsilon`` 0.05, ``kld_quantile`` 0.99: the bound of Fox 2003, Eq. 13 (Nav2 AMCL's
      ``pf_err`` and ``pf_z``).
    - ``kld_bin`` (0.5 m, 0.5 m, 10 deg in radians): the histogram bins of KLD-sampling (Nav2
      AMCL's), also the bins of the clustering that gives the estimate.
    - ``resample_threshold`` 0.5: resample when the effective sample size falls below this
      fraction of the samples (Doucet, Godsill & Andrieu 2000; PR Sec. 4.3.4).
    - ``tracking_std`` (m, m, rad): the spread of :meth:`MonteCarloLocalization.reset_tracking`
      (this implementation's: 10 cm, 10 cm, 5 deg).
    """

    min_samples: int = 500
    max_samples: int = 2000
    kld_epsilon: float = 0.05
    kld_quantile: float = 0.99
    kld_bin: tuple[float, float, float] = (0.5, 0.5, math.radians(10.0))
    resample_threshold: float = 0.5
    tracking_std: tuple[float, float, float] = (0.1, 0.1, math.radians(5.0))

    def __post_init__(self) -> None:
        if not 1 <= self.min_samples <= self.max_samples:
            raise LocalizationError(
                f"sampling: need 1 <= min_samples <= max_samples, got {self.min_samples}, {self.max_samples}"
            )


def _measured_field() -> LikelihoodFieldParams:
    return LikelihoodFieldParams(sigma_hit=0.05, distance="surface")


@dataclass(frozen=True)
class SensorConfig:
    """The laser's sensor model and the beam filters of Fox et al. 1998.

    - ``beam_filter``: ``novelty``, the paper's recommendation (Fox et al. 1998, Conclusions: only
      the novelty filter localizes "in densely crowded environments, while retaining the ability to
      efficiently recover from extreme localization errors").
    - ``filters``: the filters' own parameters (``theta`` 0.99, Eq. 6).
    - ``entropy_cell`` (m, rad): the paper's grid of 15 cm and 2 deg; samples sharing a cell are
      one location for the entropy of Eq. 3 and for the novelty filter's ray casts.
    - ``novelty_samples``: hypotheses drawn by weight whose expected ranges are ray cast for the
      belief average of Eq. 6 (an unbiased estimate of it; this implementation's 64).
    - ``novelty_sigma``: the width of Eq. 5's ``p(d | l)``, "the probability of measuring distance
      ``d`` if the sensor detects the next obstacle in the map": the laser's own spread about the
      range cast in the map, learned from data as the paper's model is. Measured with ``tourbot
      bench sensor-model`` at the reference poses of the four shared logs: 3.5-6.3 cm (robust
      standard deviation); 5 cm. The belief average of Eq. 6 already carries the pose
      uncertainty, so the likelihood field's wider ``sigma_hit`` does not belong here: with
      0.2 m a visitor standing less than 47 cm in front of a wall was never "shorter than
      expected".
    - ``likelihood_exponent``: the likelihood of a scan is raised to this power. 1 is the
      textbook's product over independent beams (PR Eq. 6.2); PR Sec. 6.4 and 6.8 point out that
      neighbouring beams are not independent and that the product is then far too confident.
      Measured (``tourbot bench sensor-model``): the residuals of 8-20 neighbouring beams err
      together on the four shared logs (an exponent of 0.05-0.12). The default stays 1: with 0.1
      the simulator's standing robot, kidnapped 5 m in a sparse crowd, was not found again within
      60 s (the recovery's likelihood averages barely drop), while FHW's peak crowd keeps 0.0 %
      failures and 5.0-5.1 cm with 1 (seeds 0-1).
    - ``field``: the likelihood field (PR Table 6.3), its one home. Its ``sigma_hit`` is learned
      from data as PR Sec. 6.3 asks: the maximum-likelihood fit of the endpoints' distances at
      the reference poses of the four shared logs is 3.3-4.7 cm to the surface between free and
      occupied space (4.2-6.3 cm to the occupied cells' centres); 5 cm, with the ``surface``
      distance (the wall is where the free space ends, not at the centre of the cell behind it).
      The field's own defaults (Nav2 AMCL's 0.2 m to the centres) gave 3.1 % failures and 15 cm
      mean error in the FHW peak crowd.
    """

    beam_filter: BeamFilter = BeamFilter.NOVELTY
    filters: BeamFilterConfig = field(default_factory=BeamFilterConfig)
    entropy_cell: tuple[float, float] = (0.15, math.radians(2.0))
    novelty_samples: int = 64
    novelty_sigma: float = 0.05
    likelihood_exponent: float = 1.0
    field: LikelihoodFieldParams = field(default_factory=_measured_field)

    def __post_init__(self) -> None:
        if not self.novelty_sigma > 0:
            raise LocalizationError(f"sensor: novelty_sigma must be positive, got {self.novelty_sigma}")
        if not self.likelihood_exponent > 0:
            raise LocalizationError(
                f"sensor: likelihood_exponent must be positive, got {self.likelihood_exponent}"
            )


@dataclass(frozen=True)
class SearchConfig:
    """The reset search of sensor resetting (Lenser & Veloso 2000) and of the verification.

    Candidate poses are ``local_candidates`` around the estimate (``local_std`` metres, any
    heading) and, when the search goes far, the ``survivors`` best of ``far_candidates`` poses
    uniform over the free space, screened by the likelihood field of the ``long_fraction``
    longest returns; they are annealed on the crowd beam model (``RecoveryConfig.model``) in
    ``stages`` stages down to ``survivors`` poses. The verification uses
    ``verify_far_candidates`` and ``verify_local_candidates`` instead, plus the ``table_survivors``
    best poses of the expected-range table (:class:`tourbot.localization.range_table.
    ExpectedRangeTable`: a ``table_spacing`` lattice, ``table_directions`` headings, scored on
    ``table_beams`` returns spread over the scan). All this implementation's values.
    """

    far_candidates: int = 200000
    local_candidates: int = 10000
    local_std: float = 1.0
    stages: int = 3
    long_fraction: float = 0.5
    survivors: int = 1000
    verify_far_candidates: int = 0
    verify_local_candidates: int = 3000
    table_survivors: int = 500
    table_spacing: float = 0.25
    table_directions: int = 90
    table_beams: int = 12


def _crowd_model() -> BeamModel:
    return BeamModel(z_hit=0.5, z_short=0.4, z_max=0.05, z_rand=0.05, sigma_hit=0.2, lambda_short=0.2)


@dataclass(frozen=True)
class RecoveryConfig:
    """Recovery from a wrong track: augmented MCL, the too-long test, recovery guesses, verification.

    - ``alpha_slow`` 0.001 / ``alpha_fast`` 0.1: the averaging rates of the fit in augmented MCL
      (PR Table 8.3; Nav2 AMCL's ``recovery_alpha_slow`` / ``recovery_alpha_fast``).
    - ``ratio`` 1: injection starts when the short-term average falls below this fraction of the
      long-term one (PR Table 8.3: ``max(0, 1 - w_fast / w_slow)``). Unlike the book, samples are
      injected only while the track is in doubt (``Recovery.in_doubt``): a guess cannot replace a
      track that explains the scan, and each injection costs a reset search.
    - ``fit_distance``: the fit of a scan is the fraction of its integrated beams that the best
      sample ends within this distance of a mapped obstacle (this implementation's 15 cm).
    - ``min_used``: scans with fewer integrated beams than this fraction of their returns are no
      evidence for the averages (this implementation's 0.3).
    - ``max_injection``: at most this fraction of the samples is replaced per update (0 turns
      recovery off; this implementation's 0.2).
    - ``fresh_wins``: injected samples stay *fresh* until one guess (a cluster of them) has won
      this many consecutive scans (this implementation's 2).
    - ``lost_margin`` 0.5 m, ``lost_fraction`` 0.3, ``lost_min_beams`` 20, ``lost_hypotheses`` 8:
      the too-long test (Fox et al. 1998: the novelty filter keeps "very unlikely sensor
      measurements (especially too long readings)"): of the returns not shorter than expected,
      the fraction longer by ``lost_margin``; above ``lost_fraction`` the scan contradicts the
      track; fewer than ``lost_min_beams`` such returns is no evidence; judged at the estimate and
      ``lost_hypotheses`` samples. This implementation's values.
    - ``global_after`` 3: contradicted scans in a row before the reset search goes over the whole
      free space; also the passes in a row that confirm a track from global localization.
    - ``verify_period`` (seconds of scan time; None: never), ``verify_margin`` (nats per return),
      ``verify_distance`` (m, rad): the track is checked against the best other place the scan
      suggests, a likelihood ratio test (this implementation's; off by default).
    - ``blind_after`` (seconds of scan time; None: never): a track that no scan has judged for
      this long (the too-long test had no evidence: too few readings reach its walls) is
      verified the same way, and again every ``blind_after`` seconds while it stays so. A robot
      carried off among visitors reads short everywhere at its old place, so nothing else would
      ever contradict its track (this implementation's 5 s: in the simulator's peak crowd 10 of
      10 standing kidnaps recovered against 5 of 10 without).
    - ``odometry_drift`` (m per m travelled, rad per rad turned): a guess replacing a contradicted
      track must lie within ``verify_distance`` plus this much of the odometry's motion since the
      last scan the track explained (this implementation's 0.1, 0.1); beyond, only after
      ``global_after`` contradicted scans in a row.
    - ``model``: the crowd beam model (PR Table 6.1) that judges guesses and candidates: ``z_short``
      0.4 for the visitors, ``lambda_short`` 0.2 /m, ``sigma_hit`` 0.2 m (this implementation's).
    - ``search``: the reset search (:class:`SearchConfig`).
    """

    alpha_slow: float = 0.001
    alpha_fast: float = 0.1
    ratio: float = 1.0
    fit_distance: float = 0.15
    min_used: float = 0.3
    max_injection: float = 0.2
    fresh_wins: int = 2
    lost_margin: float = 0.5
    lost_fraction: float = 0.3
    lost_min_beams: int = 20
    lost_hypotheses: int = 8
    global_after: int = 3
    verify_period: float | None = None
    blind_after: float | None = 5.0
    verify_margin: float = 0.5
    verify_distance: tuple[float, float] = (1.0, math.radians(30.0))
    odometry_drift: tuple[float, float] = (0.1, 0.1)
    model: BeamModel = field(default_factory=_crowd_model)
    search: SearchConfig = field(default_factory=SearchConfig)

    def __post_init__(self) -> None:
        if not 0 <= self.max_injection <= 1:
            raise LocalizationError(f"recovery: max_injection must be in [0, 1], got {self.max_injection}")
        for name in ("verify_period", "blind_after"):
            value = getattr(self, name)
            if value is not None and not value > 0:
                raise LocalizationError(f"recovery: {name} must be positive seconds or null, got {value}")


@dataclass(frozen=True)
class GlobalConfig:
    """Global localization by annealed importance sampling (Neal 2001; Deutscher, Blake & Reid 2000).

    - ``samples``: samples the filter carries while the belief is spread (KLD-sampling then
      shrinks the set); ``candidates``: poses uniform over the free space scored on the first
      scan, every ``beam_step``-th of its ``long_fraction`` longest returns.
    - ``ess``: each annealing stage keeps the effective sample size at this fraction of the
      samples; ``stages``: at most this many stages; ``jitter`` (m, m, rad) between stages.
    - ``done``: global localization ends when one cluster holds this share of the weight.
    All this implementation's values (also used by the reset search's annealing).
    """

    samples: int = 50000
    candidates: int = 1_000_000
    beam_step: int = 4
    ess: float = 0.1
    jitter: tuple[float, float, float] = (0.05, 0.05, math.radians(2.0))
    stages: int = 8
    long_fraction: float = 0.5
    done: float = 0.95


@dataclass(frozen=True)
class MCLConfig:
    """Monte Carlo localization: the four groups and the odometry motion model (PR Table 5.6)."""

    sampling: SamplingConfig = field(default_factory=SamplingConfig)
    sensor: SensorConfig = field(default_factory=SensorConfig)
    recovery: RecoveryConfig = field(default_factory=RecoveryConfig)
    global_: GlobalConfig = field(default_factory=GlobalConfig)
    motion: OdometryMotionModel = field(default_factory=OdometryMotionModel)

    def with_samples(self, n: int, *, fixed: bool = False) -> MCLConfig:
        """This configuration with a sample budget of ``n`` (``fixed``: no KLD adaptation)."""
        from dataclasses import replace

        lo = n if fixed else min(self.sampling.min_samples, n)
        return replace(self, sampling=replace(self.sampling, max_samples=n, min_samples=lo))

    def with_filter(self, kind: BeamFilter) -> MCLConfig:
        """This configuration with the beam filter ``kind``."""
        from dataclasses import replace

        return replace(self, sensor=replace(self.sensor, beam_filter=kind))
