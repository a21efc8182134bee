"""The search for the poses that best explain a scan: global localization and sensor resetting.

Candidates (uniform over the free space, around the estimate, the best of an expected-range
table) are brought to the scan's likelihood by annealed importance sampling (Neal 2001,
"Annealed importance sampling"; Deutscher, Blake & Reid 2000, the annealed particle filter): the
tempered likelihood ``L ** d_k`` is applied in stages, each the largest step that keeps the
effective sample size at ``ess`` of the set, with low-variance resampling and a small jitter in
between. Sensor resetting (Lenser & Veloso 2000) draws its new samples from the result; the
verification compares the best of them with the track, a likelihood ratio test.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import wrap_angle
from tourbot.localization.mcl.config import MCLConfig
from tourbot.localization.mcl.sensor import LaserSensorModel, longest_returns
from tourbot.maps.likelihood_field import LikelihoodField
from tourbot.records import LaserGeometry
from tourbot.sampling import systematic_resample

__all__ = ["ResetSearch", "anneal_step"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
BeamScore = Callable[[FloatArray, BoolArray], FloatArray]


def anneal_step(logw: FloatArray, ll: FloatArray, most: float, ess: float) -> float:
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


class ResetSearch:
    """The searches of one filter, on its sensor model and configuration."""

    def __init__(self, sensor: LaserSensorModel, config: MCLConfig) -> None:
        self.sensor = sensor
        self.config = config

    def anneal(
        self,
        cand: FloatArray,
        n: int,
        ranges: FloatArray,
        geometry: LaserGeometry,
        field_: LikelihoodField,
        beams: BoolArray,
        max_stages: int,
        rng: np.random.Generator,
        score: BeamScore | None = None,
    ) -> tuple[FloatArray, int]:
        """``n`` poses drawn from the candidates ``cand`` by the tempered likelihood of ``beams``
        (``score(poses, mask)``, the likelihood field by default), brought in by stages that keep
        the effective sample size at ``global.ess * n``; the first stage scores every
        ``global.beam_step``-th beam only. Returns the poses and the number of stages."""
        glob = self.config.global_
        if score is None:

            def score(poses: FloatArray, mask: BoolArray) -> FloatArray:
                return field_.log_likelihood(poses, ranges, geometry, beam_mask=mask)

        mask = np.zeros_like(beams)
        mask[:: max(1, glob.beam_step)] = True
        mask &= beams
        if not mask.any():
            mask = beams
        ll = score(cand, mask) * (beams.sum() / mask.sum())
        logw = np.zeros(cand.shape[0])
        left = self.config.sensor.likelihood_exponent
        jitter = np.asarray(glob.jitter, dtype=np.float64)
        stages = 0
        while True:
            stages += 1
            step = anneal_step(logw, ll, left, glob.ess * n)
            logw = logw + step * ll
            left -= step
            w = np.exp(logw - logw.max())
            idx = systematic_resample(w / w.sum(), n, float(rng.random()))
            cand = cand[idx] + rng.standard_normal((n, 3)) * jitter
            cand[:, 2] = wrap_angle(cand[:, 2])
            inside = self.sensor.in_free_space(cand)
            if left <= 1e-12 or stages >= max_stages or not inside.any():
                break
            cand = cand[inside]
            ll = score(cand, beams)
            logw = np.zeros(cand.shape[0])
        return np.ascontiguousarray(cand), stages

    def scan_drawn_poses(
        self,
        n: int,
        ranges: FloatArray,
        geometry: LaserGeometry,
        valid: BoolArray,
        estimate: FloatArray,
        rng: np.random.Generator,
        *,
        far: bool,
        table: bool = False,
        verifying: bool = False,
        earlier: FloatArray | None = None,
    ) -> FloatArray:
        """Sensor resetting: ``n`` poses drawn from candidates by the crowd beam model.

        Candidates: poses around the ``estimate``; with ``far`` also the best uniform ones over
        the free space (screened by the likelihood field of the longest returns); with
        ``verifying`` or ``table`` the best of the expected-range table; ``earlier``: the guesses
        of earlier scans. The pool is annealed down to ``search.survivors`` poses, of which ``n``
        are kept at random."""
        cfg = self.config
        search = cfg.recovery.search
        field_ = self.sensor.field(geometry)
        keep = max(n, search.survivors)
        m = search.verify_local_candidates if verifying else search.local_candidates
        pool = [
            np.column_stack(
                [
                    estimate[0] + search.local_std * rng.standard_normal(m),
                    estimate[1] + search.local_std * rng.standard_normal(m),
                    rng.uniform(-math.pi, math.pi, m),
                ]
            )
        ]
        n_far = search.verify_far_candidates if verifying else search.far_candidates
        if far and n_far > 0:
            far_poses = self.sensor.uniform_free_poses(n_far, rng)
            longest = longest_returns(ranges, valid, search.long_fraction)
            if longest.any():
                far_poses = self.anneal(far_poses, keep, ranges, geometry, field_, longest, 1, rng)[0]
            pool.append(far_poses[: search.survivors])
        if far and (verifying or table):
            pool.append(self.sensor.table_poses(ranges, geometry, valid, search))
        if earlier is not None and earlier.shape[0]:
            pool.append(earlier)
        cand = np.vstack(pool)
        cand = cand[self.sensor.in_free_space(cand)]
        if not valid.any() or cand.shape[0] == 0:
            return cand[:n]

        def score(poses: FloatArray, mask: BoolArray) -> FloatArray:
            return self.sensor.crowd_log_likelihood(poses, ranges, geometry, mask)

        drawn = self.anneal(cand, keep, ranges, geometry, field_, valid, search.stages, rng, score)[0]
        return drawn[rng.permutation(drawn.shape[0])[:n]]

    def verify(
        self,
        pose: FloatArray,
        n: int,
        ranges: FloatArray,
        geometry: LaserGeometry,
        valid: BoolArray,
        rng: np.random.Generator,
        earlier: FloatArray | None,
    ) -> tuple[FloatArray, float]:
        """Search the map for the ``n`` places that best explain the scan and compare the best of
        those more than ``verify_distance`` from the tracked ``pose`` with it under the crowd beam
        model: a likelihood ratio test. Returns the drawn poses (the reset samples, should the
        track lose) and the margin in nats per return (0 when no other place explains it better)."""
        rec = self.config.recovery
        drawn = self.scan_drawn_poses(
            n, ranges, geometry, valid, pose, rng, far=True, verifying=True, earlier=earlier
        )
        n_valid = int(valid.sum())
        away = (np.hypot(drawn[:, 0] - pose[0], drawn[:, 1] - pose[1]) > rec.verify_distance[0]) | (
            np.abs(wrap_angle(drawn[:, 2] - pose[2])) > rec.verify_distance[1]
        )
        if not away.any() or n_valid == 0:
            return drawn, 0.0
        ll = self.sensor.crowd_log_likelihood(
            np.vstack([pose[None, :], drawn[away]]), ranges, geometry, valid
        )
        return drawn, max(0.0, float(ll[1:].max() - ll[0]) / n_valid)
