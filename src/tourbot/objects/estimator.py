"""State estimation of doors and furniture from the moving robot (Schulz and Burgard 2001).

Each dynamic object keeps its own sample set ``p(s)`` over continuous states (the paper used
10-degree bins for doors; here the samples move freely). One update, for every object within
``max_distance`` of the robot (Sec. 4.1: 3.5 m), follows the inner loop of their Table 1:

1. **Prediction**, Eq. 5: ``p(s) <- int p(s | t, s') p(s') ds'``. The motion model is a diffusion
   (``std * sqrt(t)``, never less than a floor per update) and a *jump*: with probability
   ``1 - exp(-t / change_time)`` (at least ``jump_min``) a sample is drawn afresh over the object's
   whole range, so a door closed while the robot was away is found again.
2. **Correction**, Eq. 8-10, integrating over the robot's pose *samples* ``L`` (the localizer's
   belief, not its mean): ``p(s | o) = sum_l p(o | s, l) p(s) / p(o | l)`` with
   ``p(o | l) = sum_s p(o | s, l)`` (Eq. 9) and ``p(o | s, l) = prod_i p(d_i | \\hat d_i(s, l))``
   (Eq. 10). The expected ranges ``\\hat d_i`` are the sensor simulation of
   :mod:`tourbot.maps.objects` (the static map's cast, lowered to the object's outline and to the
   other objects in their current estimates), over the consecutive beams that hit the object's
   bounding box in some sample state (Sec. 3). ``p(d | \\hat d)`` is the paper's Gaussian as the
   hit part of the project's beam-model mixture (:class:`tourbot.maps.beam_model.BeamModel`),
   whose short-reading part absorbs visitors standing in a doorway.
3. **Resampling** by the posterior weights (low-variance resampling, the project's one resampler).

Beyond the paper (its Sec. 5 future work), every estimate says how well it was observed
(:class:`Quality`): the beams that discriminate between the sample states, how many of them the
reading explains and how many read shorter than every state (something in front: occlusion), and
the posterior spread (an ambiguous, e.g. nearly symmetric, view). A poorly observed object is
reported as such instead of as a confident state; the sample set integrates the sequence of
viewpoints the robot passes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose, wrap_angle
from tourbot.localization.mcl import low_variance_resample
from tourbot.maps.beam_model import BeamModel
from tourbot.maps.objects import (
    ObjectIndex,
    ObjectShape,
    beam_window,
    segment_ranges,
    segment_ranges_reference,
)
from tourbot.maps.raycast import RayCaster
from tourbot.objects.likelihood import log_likelihoods
from tourbot.records import Scan

__all__ = [
    "ObjectBelief",
    "ObjectEstimate",
    "ObjectEstimatorConfig",
    "ObjectStateEstimator",
    "Observation",
    "Quality",
]

FloatArray = NDArray[np.float64]


class Observation(StrEnum):
    """How well the latest estimate of an object is backed by what the laser saw."""

    UNSEEN = "unseen"  # never within reach of an update
    OBSERVED = "observed"  # enough beams explained, small spread
    FEW_BEAMS = "few-beams"  # too few discriminating beams explained by the estimate
    OCCLUDED = "occluded"  # most discriminating beams read shorter than any state
    AMBIGUOUS = "ambiguous"  # the posterior stays wide (a symmetric or edge-on view)


@dataclass(frozen=True)
class ObjectEstimatorConfig:
    """Parameters of the object state estimator; the paper's values as defaults where it has them.

    ``max_distance`` 3.5 m: a door is estimated as soon as the robot is closer (Sec. 4.1).
    ``door_samples`` / ``furniture_samples``: state samples per object (the paper: 40 for the
    U-shaped object, Sec. 4.2; more here because the jump prior spreads some over the whole range).
    ``pose_samples``: the localizer's belief is drawn down to this many equally weighted poses for
    Eq. 8 (the paper sums over the whole sample set; the cost is linear in it).
    ``beam``: ``p(d | \\hat d)``. The paper's Gaussian (``sigma_hit``; 3 cm covers a 1-2 cm laser
    and the localizer's 1-3 cm of pose error) is the hit part; ``z_short`` / ``lambda_short`` take
    visitors in front of the object, ``z_max`` / ``z_rand`` lost and spurious readings. The
    paper's pure Gaussian is ``BeamModel(z_hit=1, z_short=0, z_max=0, z_rand=0)``.
    ``door_diffusion`` (rad / sqrt(s)), ``furniture_diffusion`` (m, m, rad per sqrt(s)) and their
    ``*_floor`` per update keep the samples from collapsing; ``*_change_time`` (s): the mean time
    between changes of the object (the jump rate); ``jump_min``: the least share of samples drawn
    over the whole range at every update. ``search_margin`` (m): furniture may stand this far
    from its site pose, at any heading; ``prior_std``: the spread of the prior around the site pose;
    ``nudge_std``: half of a piece of furniture's jumps land this close to where the sample was
    (turned or pushed a little) rather than anywhere.
    ``min_beams``, ``min_explained`` (the least share of the discriminating beams the estimate must
    explain), ``occluded_fraction``, ``max_door_std`` (rad), ``max_position_std`` (m),
    ``max_heading_std`` (rad): the tests of :class:`Quality`; ``min_constraint``: the weakest
    direction of the information of a piece of furniture's pose from the readings on its outline,
    as a share of the strongest, for it to count as pinned down (:meth:`ObjectBelief._constrained`).
    """

    max_distance: float = 3.5
    door_samples: int = 50
    furniture_samples: int = 300
    pose_samples: int = 8
    beam: BeamModel = field(
        default_factory=lambda: BeamModel(
            z_hit=0.8, z_short=0.15, z_max=0.025, z_rand=0.025, sigma_hit=0.03, lambda_short=0.5
        )
    )
    door_diffusion: float = math.radians(2.0)
    door_floor: float = math.radians(0.3)
    furniture_diffusion: tuple[float, float, float] = (0.01, 0.01, math.radians(1.0))
    furniture_floor: tuple[float, float, float] = (0.003, 0.003, math.radians(0.3))
    door_change_time: float = 60.0
    furniture_change_time: float = 300.0
    jump_min: float = 0.02
    search_margin: float = 0.5
    prior_std: tuple[float, float, float] = (0.1, 0.1, math.radians(10.0))
    nudge_std: tuple[float, float, float] = (0.1, 0.1, math.radians(30.0))
    min_beams: int = 5
    min_explained: float = 0.6
    occluded_fraction: float = 0.5
    max_door_std: float = math.radians(3.0)
    max_position_std: float = 0.05
    max_heading_std: float = math.radians(5.0)
    min_constraint: float = 0.15

    def __post_init__(self) -> None:
        if min(self.door_samples, self.furniture_samples, self.pose_samples) < 1:
            raise ValueError("ObjectEstimatorConfig: sample counts must be >= 1")
        if not self.max_distance > 0 or not 0 <= self.jump_min < 1:
            raise ValueError("ObjectEstimatorConfig: max_distance > 0 and 0 <= jump_min < 1 required")


@dataclass(frozen=True)
class Quality:
    """What backs an estimate: discriminating beams, those the estimate explains, those occluded."""

    status: Observation
    beams: int = 0
    explained: int = 0
    occluded: int = 0

    @property
    def poor(self) -> bool:
        return self.status != Observation.OBSERVED


@dataclass(frozen=True)
class ObjectEstimate:
    """An object's estimated state (door ``(angle,)``, furniture ``(x, y, theta)``), spread, quality."""

    name: str
    kind: str
    time: float
    state: tuple[float, ...]
    std: tuple[float, ...]
    quality: Quality
    updates: int


class ObjectBelief:
    """The sample set ``p(s)`` of one object, with its motion model (Eq. 5) and update (Eq. 8-10)."""

    def __init__(self, shape: ObjectShape, config: ObjectEstimatorConfig, rng: np.random.Generator) -> None:
        self.shape = shape
        self.config = config
        self.rng = rng
        n = config.door_samples if shape.kind == "door" else config.furniture_samples
        self.samples = self._prior(n)
        self.time: float | None = None
        self.updates = 0
        self.estimate: ObjectEstimate = ObjectEstimate(
            shape.name,
            shape.kind,
            0.0,
            tuple(self._mean(np.full(n, 1.0 / n))),
            (math.inf,) * shape.dim,
            Quality(Observation.UNSEEN),
            0,
        )

    # -- motion model (Eq. 5) ---------------------------------------------------------------------

    def _prior(self, n: int) -> FloatArray:
        """Table 1's first loop: the prior samples. A door may be anywhere in its range; furniture
        is roughly where the site puts it (the paper, Sec. 4.2: "the position of the object is
        roughly known"), ``prior_std`` around it, with a ``jump_min`` share over the whole range."""
        if self.shape.kind == "door":
            return self._jump(n)
        spread = self.rng.random(n) < self.config.jump_min
        out = np.asarray(self.shape.nominal) + self.rng.standard_normal((n, 3)) * np.asarray(
            self.config.prior_std
        )
        out[spread] = self._jump(int(spread.sum()))
        return self._canonical(out)

    def _jump(self, n: int) -> FloatArray:
        """``n`` states drawn uniformly over the object's whole range."""
        s = self.shape
        if s.kind == "door":
            return self.rng.uniform(s.low, s.high, size=(n, 1))
        m = self.config.search_margin
        out = np.empty((n, 3))
        out[:, 0] = s.nominal[0] + self.rng.uniform(-m, m, n)
        out[:, 1] = s.nominal[1] + self.rng.uniform(-m, m, n)
        out[:, 2] = self.rng.uniform(-math.pi, math.pi, n)
        return self._canonical(out)

    def _canonical(self, states: FloatArray) -> FloatArray:
        """Headings of a symmetric outline folded into one period around its nominal heading."""
        s = self.shape
        if s.kind != "door" and s.symmetry > 1:
            period = 2 * math.pi / s.symmetry
            ref = s.nominal[2]
            states[:, 2] = ref + np.mod(states[:, 2] - ref + period / 2, period) - period / 2
        if s.kind != "door":
            states[:, 2] = wrap_angle(states[:, 2])
        return states

    def predict(self, time: float) -> None:
        """Eq. 5: diffuse the samples by the time since the last update and redraw some afresh."""
        cfg, s = self.config, self.shape
        dt = 0.0 if self.time is None else max(0.0, time - self.time)
        n = self.samples.shape[0]
        if s.kind == "door":
            std = np.array([max(cfg.door_diffusion * math.sqrt(dt), cfg.door_floor)])
            change = cfg.door_change_time
        else:
            std = np.maximum(
                np.asarray(cfg.furniture_diffusion) * math.sqrt(dt), np.asarray(cfg.furniture_floor)
            )
            change = cfg.furniture_change_time
        moved = self.samples + self.rng.standard_normal(self.samples.shape) * std
        if s.kind == "door":
            # a leaf stops at its end stops: reflect back into [low, high]
            lo, hi = s.low, s.high
            moved = np.where(moved < lo, 2 * lo - moved, moved)
            moved = np.where(moved > hi, 2 * hi - moved, moved)
            moved = np.clip(moved, lo, hi)
        p_jump = max(cfg.jump_min, 1.0 - math.exp(-dt / change)) if self.time is not None else 0.0
        jump: NDArray[np.bool_] = np.asarray(self.rng.random(n) < p_jump)
        if jump.any():
            moved[jump] = self._jump(int(jump.sum()))
            if s.kind != "door":
                # half of furniture's jumps land near where it was: people turn or push it a little
                near = np.flatnonzero(jump)[: int(jump.sum()) // 2]
                moved[near] = self.samples[near] + self.rng.standard_normal((near.size, 3)) * np.asarray(
                    cfg.nudge_std
                )
        self.samples = self._canonical(moved)
        self.time = time

    # -- correction (Eq. 8-10) --------------------------------------------------------------------

    def update(
        self,
        scan: Scan,
        laser_poses: FloatArray,
        pose_weights: FloatArray,
        caster: RayCaster,
        others: FloatArray,
    ) -> ObjectEstimate:
        """Integrate ``scan`` over the laser poses ``(P, 3)`` weighted ``pose_weights`` ``(P,)``
        (summing to one); ``others`` ``(1, M, 4)``: the edges of the other objects near, in their
        current estimates."""
        cfg, shape = self.config, self.shape
        g = scan.geometry
        self.predict(scan.timestamp)
        window = beam_window(
            laser_poses, shape.boxes(self.samples), g.angle_min, g.angle_increment, g.num_beams
        )
        measured = np.asarray(scan.ranges, dtype=np.float64)[window]
        usable = (measured >= max(g.min_range, 0.0)) & np.isfinite(measured)
        window, measured = window[usable], measured[usable]
        self.updates += 1
        if window.size == 0:
            return self._report(
                scan.timestamp,
                np.full(self.samples.shape[0], 1.0 / self.samples.shape[0]),
                Quality(Observation.FEW_BEAMS),
            )
        angles = g.angles[window]
        base = caster.cast(laser_poses, angles).astype(np.float64)
        if others.shape[1]:
            base = segment_ranges(laser_poses, angles, others, base)[:, 0, :].astype(np.float64)
        segs = shape.segments(self.samples)
        max_range = float(g.max_range)
        z = np.minimum(measured, max_range)
        loglik = log_likelihoods(laser_poses, angles, segs, base, z, cfg.beam, max_range)  # (P, S), Eq. 10
        # Eq. 8-9: for each pose sample l, p(o | s, l) / p(o | l) with p(o | l) = sum_s p(o | s, l)
        loglik -= loglik.max(axis=1, keepdims=True)
        ratio = np.exp(loglik)
        ratio /= ratio.sum(axis=1, keepdims=True)
        weights = pose_weights @ ratio
        weights /= weights.sum()
        # how well it was seen, from the likeliest pose sample
        top = int(np.argmax(pose_weights))
        expected = segment_ranges(laser_poses[top : top + 1], angles, segs, base[top : top + 1])[0]  # (S, W)
        probes = None
        if shape.kind == "door":
            # the door's range in the paper's 10-degree steps: a converged belief (its samples all
            # within a degree, no jump drawn this scan) still tells which beams would see a change
            n_probe = max(2, math.ceil(abs(shape.high - shape.low) / math.radians(10.0)) + 1)
            states = np.linspace(shape.low, shape.high, n_probe)[:, None]
            probes = segment_ranges(
                laser_poses[top : top + 1], angles, shape.segments(states), base[top : top + 1]
            )[0]
        quality = self._quality(expected, z, weights, probes)
        if quality.status == Observation.OBSERVED and shape.kind != "door":
            best = self.samples[int(np.argmax(weights))]
            if not self._constrained(laser_poses[top], angles, z, best, base[top]):
                quality = Quality(Observation.AMBIGUOUS, quality.beams, quality.explained, quality.occluded)
        estimate = self._report(scan.timestamp, weights, quality)
        s_ = self.samples.shape[0]
        idx = low_variance_resample(weights, s_, float(self.rng.random()))
        self.samples = self.samples[idx]
        return estimate

    def _constrained(
        self, laser: FloatArray, angles: FloatArray, z: FloatArray, state: FloatArray, base: FloatArray
    ) -> bool:
        """Whether the readings on the outline pin all three degrees of freedom of a pose.

        Each reading explained on edge ``e`` at point ``p`` constrains the pose along the edge's
        normal ``n``: a row ``(n_x, n_y, ((p - c) x n) / r)`` of the Jacobian (``c`` the object's
        frame origin, ``r`` its radius, so a turn counts by how far it moves the outline). The
        information ``J^T J`` must have no direction weaker than ``min_constraint`` of its
        strongest: readings on one face only (a desk seen from the front, the rest hidden) leave
        the shift along that face free, and the estimate is ambiguous however well it explains them.
        """
        cfg, shape = self.config, self.shape
        tol = 3.0 * cfg.beam.sigma_hit
        edges = shape.segments(state[None])[0]  # (E, 4)
        per_edge = segment_ranges_reference(
            laser[None], angles, edges[:, None, :], np.full((1, angles.size), np.inf)
        )[0]
        t = per_edge.min(axis=0)  # (W,)
        on = np.isfinite(t) & (t < base - tol) & (np.abs(z - t) < tol)
        if on.sum() < 3:
            return False
        e = edges[np.argmin(per_edge, axis=0)[on]]
        nx, ny = -(e[:, 3] - e[:, 1]), e[:, 2] - e[:, 0]
        norm = np.hypot(nx, ny)
        nx, ny = nx / norm, ny / norm
        a = laser[2] + angles[on]
        px = laser[0] + t[on] * np.cos(a) - state[0]
        py = laser[1] + t[on] * np.sin(a) - state[1]
        r = max(shape.radius, 1e-3)  # the heading in metres at the outline, comparable with shifts
        jac = np.column_stack([nx, ny, (px * ny - py * nx) / r])
        eig = np.linalg.eigvalsh(jac.T @ jac)
        return bool(eig[0] >= cfg.min_constraint * eig[-1])

    def _quality(
        self,
        expected: NDArray[np.float32],
        z: FloatArray,
        weights: FloatArray,
        probes: NDArray[np.float32] | None = None,
    ) -> Quality:
        """Discriminating beams (the states ``(S, W)``, with the ``probes`` states ``(K, W)`` when
        given, disagree by more than 3 sigma), how many the estimate explains (within 3 sigma at
        the best state), how many read shorter than every state."""
        cfg = self.config
        tol = 3.0 * cfg.beam.sigma_hit
        states = expected if probes is None else np.vstack([expected, probes])
        discriminating = (states.max(axis=0) - states.min(axis=0)) > tol
        at_best = expected[int(np.argmax(weights))]
        explained = discriminating & (np.abs(z - at_best) < tol)
        occluded = discriminating & (z < states.min(axis=0) - tol)
        nb, ne, no = int(discriminating.sum()), int(explained.sum()), int(occluded.sum())
        if nb and no >= cfg.occluded_fraction * nb:
            status = Observation.OCCLUDED
        elif ne < max(cfg.min_beams, cfg.min_explained * nb):
            status = Observation.FEW_BEAMS
        else:
            status = Observation.OBSERVED
        return Quality(status, nb, ne, no)

    def _mean(self, weights: FloatArray) -> FloatArray:
        """The weighted mean of the samples near the best one (a local mean, not across modes)."""
        s = self.samples
        best = s[int(np.argmax(weights))]
        if self.shape.kind == "door":
            near = np.abs(s[:, 0] - best[0]) < math.radians(10.0)
        else:
            near = (np.hypot(s[:, 0] - best[0], s[:, 1] - best[1]) < 0.15) & (
                np.abs(wrap_angle(s[:, 2] - best[2])) < math.radians(15.0)
            )
        w = weights * near
        w = w / w.sum()
        if self.shape.kind == "door":
            return np.array([float(w @ s[:, 0])])
        d = wrap_angle(s[:, 2] - best[2])
        return np.array([float(w @ s[:, 0]), float(w @ s[:, 1]), float(wrap_angle(best[2] + w @ d))])

    def _report(self, time: float, weights: FloatArray, quality: Quality) -> ObjectEstimate:
        cfg, s = self.config, self.samples
        mean = self._mean(weights)
        if self.shape.kind == "door":
            std: tuple[float, ...] = (float(np.sqrt(weights @ (s[:, 0] - mean[0]) ** 2)),)
            wide = std[0] > cfg.max_door_std
        else:
            pos = float(np.sqrt(weights @ ((s[:, 0] - mean[0]) ** 2 + (s[:, 1] - mean[1]) ** 2)))
            head = float(np.sqrt(weights @ wrap_angle(s[:, 2] - mean[2]) ** 2))
            std = (pos, pos, head)
            wide = pos > cfg.max_position_std or head > cfg.max_heading_std
        if quality.status == Observation.OBSERVED and wide:
            quality = Quality(Observation.AMBIGUOUS, quality.beams, quality.explained, quality.occluded)
        self.estimate = ObjectEstimate(
            self.shape.name, self.shape.kind, time, tuple(float(v) for v in mean), std, quality, self.updates
        )
        return self.estimate


class ObjectStateEstimator:
    """Every dynamic object of a site, estimated from scans and the localizer's pose samples.

    :meth:`update` is the ``else`` branch of Table 1 for one scan; which scans it gets (the odd
    ones, as in Table 1, or all) is the caller's choice (:mod:`tourbot.objects.runtime`).
    """

    def __init__(
        self,
        shapes: Sequence[ObjectShape],
        caster: RayCaster,
        config: ObjectEstimatorConfig | None = None,
        seed: int = 0,
        tile: float = 2.0,
    ) -> None:
        self.config = cfg = config or ObjectEstimatorConfig()
        self.shapes = list(shapes)
        self.caster = caster
        self.index = ObjectIndex(self.shapes, tile)
        rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(len(self.shapes) + 1)]
        self._rng = rngs[-1]
        self.beliefs = [ObjectBelief(s, cfg, r) for s, r in zip(self.shapes, rngs, strict=False)]
        self.update_seconds: list[float] = []

    def estimates(self) -> list[ObjectEstimate]:
        return [b.estimate for b in self.beliefs]

    def _pose_samples(self, samples: FloatArray, weights: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The belief drawn down to ``pose_samples`` poses; repeated draws merged into one weighted
        pose (a trajectory given as one pose costs one)."""
        w = np.asarray(weights, dtype=np.float64)
        idx = low_variance_resample(w / w.sum(), self.config.pose_samples, float(self._rng.random()))
        unique, counts = np.unique(idx, return_counts=True)
        return np.asarray(samples, dtype=np.float64)[unique], counts / counts.sum()

    def update(self, scan: Scan, samples: FloatArray, weights: FloatArray) -> list[ObjectEstimate]:
        """Integrate ``scan`` into every object within reach; returns the estimates updated.

        ``samples`` ``(N, 3)`` and ``weights`` ``(N,)``: the robot's pose belief at the scan.
        """
        import time as _time

        poses, pose_weights = self._pose_samples(samples, weights)
        laser = compose(poses, np.asarray(scan.geometry.offset, dtype=np.float64))
        centre = np.average(np.asarray(samples)[:, :2], axis=0, weights=weights)
        near = self.index.near(float(centre[0]), float(centre[1]), self.config.max_distance)
        out = []
        for i in near:
            if not self._within(self.shapes[i], centre):
                continue
            t0 = _time.process_time()  # CPU time: the machine is shared
            others = self._others(near, i)
            out.append(self.beliefs[i].update(scan, laser, pose_weights, self.caster, others))
            self.update_seconds.append(_time.process_time() - t0)
        return out

    def _within(self, shape: ObjectShape, centre: FloatArray) -> bool:
        """Whether the object's current estimate is within ``max_distance`` of the robot."""
        est = self.beliefs[self.shapes.index(shape)].estimate
        if shape.kind == "door":
            x, y = shape.hinge
        else:
            x, y = est.state[0], est.state[1]
        return math.hypot(x - centre[0], y - centre[1]) <= self.config.max_distance + shape.radius

    def _others(self, near: list[int], i: int) -> FloatArray:
        """Edges ``(1, M, 4)`` of the objects near other than ``i``, in their current estimates."""
        parts = [
            self.shapes[j].segments(np.asarray(self.beliefs[j].estimate.state))[0] for j in near if j != i
        ]
        return np.concatenate(parts)[None] if parts else np.zeros((1, 0, 4))
