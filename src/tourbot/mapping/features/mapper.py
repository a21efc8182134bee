"""Feature-based mapping by EM with a Rauch-Tung-Striebel smoother (Burgard et al. Sec. 2.2).

The map's line features are the *parameters* of the dynamical system the robot's pose follows,
not part of its state (the paper, after Baltzakis and Trahanias 2002), so the problem is to find
the path and the parameters together, by EM (Dempster et al. 1977):

- **E-step**: the path given the map. An EKF runs forward over the scans (odometry prediction;
  the scan's segments associated to the map's by string search, :mod:`.association`; a Kalman
  update with the matched lines), then the RTS backward recursion (Eq. 3-5,
  :mod:`.smoother`) gives every pose from past *and* future scans. A segment that matches no map
  line starts a new one, its uncertainty that of the pose it was seen from.
- **M-step**: the map given the path. Every map line is refitted (total least squares) to all
  the scan points associated with it, placed at the smoothed poses; lines that now coincide (a
  wall mapped twice before a loop closed) are merged.

Loops are found in the first E-step by *multiple hypotheses* (the paper's switching state-space
model): "Whenever a corner point appears in the robot's measurements, new hypotheses will be
created at corresponding positions": each corner of the scan matched to a map corner of the same
angle seen long ago (at least ``loop_path`` m back along the path) and within reach of the
current pose gives a pose hypothesis, a Kalman tracker of its own. Every scan, each hypothesis and
the main track are scored by how well they explain the scan's segments with the map lines seen
that long ago (discrete Markov dynamics over the log-likelihood ratio); "hypotheses that cannot
be confirmed for a sequence of measurements typically vanish", and one that explains the
measurements better than the main track for ``confirm_scans`` scans by ``win_log_odds`` becomes
it: the pose it holds is fused as a measurement, and the smoother spreads the correction back
along the loop. "The resulting map always corresponds to the most likely hypothesis."

Iterations stop when the smoothed path moves less than ``converged`` m, or after
``iterations`` (the paper: "until the overall process has converged or until a certain number of
iterations has been carried out").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import relative, transform_points, wrap_angle
from tourbot.mapping.features.association import string_match
from tourbot.mapping.features.extraction import (
    Corner,
    ExtractionParams,
    Segment,
    extract_corners,
    extract_segments,
    fit_line,
    scan_points,
)
from tourbot.mapping.features.smoother import (
    MotionNoise,
    line_measurements,
    predict,
    rts_smooth,
    update,
)
from tourbot.records import Scan
from tourbot.union_find import components

__all__ = ["FeatureMap", "FeatureMapper", "FeatureMappingParams", "LoopClosure", "MapLine", "scan_features"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class FeatureMappingParams:
    """Parameters of feature-based mapping (the paper gives none in numbers; values measured on
    the CARMEN logs' 1-degree scanners).

    Association: ``gate`` the chi-square gate of a pair's ``(alpha, r)`` (2 dof, 99 %: 9.21),
    ``overlap_margin`` m the extents may miss each other by, ``consensus_angle`` rad the paired
    lines' angle innovations may differ by (one rotation explains them all), ``line_sigma_alpha`` (rad) and
    ``line_sigma_r`` (m) the least uncertainty of a scan's and a refitted map line (walls are not
    perfectly straight). Hypotheses: ``loop_path`` m of path before a corner can close a loop,
    ``corner_angle_tol`` rad between matched corners' angles, ``window_min`` / ``window_max`` m
    and ``window_sigmas`` the reach of the search around the pose (its standard deviations),
    ``window_angle`` rad, ``corner_sigma_xy`` m and ``corner_sigma_theta`` rad a new hypothesis'
    uncertainty, ``confirm_scans`` and ``win_log_odds`` to win, ``lose_log_odds`` and
    ``max_age`` scans to vanish, ``max_hypotheses`` alive at once, ``distinct_xy`` m /
    ``distinct_theta`` rad from the main track and each other to be new, ``cooldown`` scans after
    a closure, ``spawn_distance`` m of path between two rounds of new hypotheses (a corner that
    appears is matched once, not at every scan that still shows it). M-step: ``merge_angle``
    rad, ``merge_distance`` m, ``merge_gap`` m between extents; ``min_observations`` scans for a
    line to be drawn in the finished map. EM: ``iterations``, ``converged`` m.
    """

    extraction: ExtractionParams = field(default_factory=ExtractionParams)
    motion: MotionNoise = field(default_factory=MotionNoise)
    gate: float = 9.21
    overlap_margin: float = 0.5
    consensus_angle: float = math.radians(3.0)
    line_sigma_alpha: float = math.radians(1.0)
    line_sigma_r: float = 0.02
    loop_path: float = 10.0
    corner_angle_tol: float = math.radians(10.0)
    window_min: float = 1.0
    window_max: float = 8.0
    window_sigmas: float = 3.0
    window_angle: float = math.radians(30.0)
    corner_sigma_xy: float = 0.1
    corner_sigma_theta: float = math.radians(3.0)
    confirm_scans: int = 5
    win_log_odds: float = 40.0
    lose_log_odds: float = -10.0
    max_age: int = 25
    max_hypotheses: int = 20
    distinct_xy: float = 0.3
    distinct_theta: float = math.radians(3.0)
    cooldown: int = 10
    spawn_distance: float = 0.5
    merge_angle: float = math.radians(3.0)
    merge_distance: float = 0.08
    merge_gap: float = 0.3
    min_observations: int = 3
    iterations: int = 5
    converged: float = 0.01


@dataclass
class MapLine:
    """A line of the map in the world frame: normal form ``(alpha, r)``, its covariance, its extent
    ``[s0, s1]`` along the tangent ``(-sin alpha, cos alpha)`` from the foot of the normal, the
    path length when it was first seen, and the ``(scan, segment)`` observations associated to it."""

    alpha: float
    r: float
    cov: FloatArray
    s0: float
    s1: float
    born: float
    obs: list[tuple[int, int]] = field(default_factory=list)

    def ends(self) -> FloatArray:
        """The two end points ``(2, 2)``."""
        n = np.array([math.cos(self.alpha), math.sin(self.alpha)])
        t = np.array([-n[1], n[0]])
        return np.array([self.r * n + self.s0 * t, self.r * n + self.s1 * t])

    def extend(self, points: FloatArray) -> None:
        """Grow the extent to cover ``points`` ``(k, 2)`` projected onto the line."""
        t = np.array([-math.sin(self.alpha), math.cos(self.alpha)])
        s = points @ t
        self.s0, self.s1 = min(self.s0, float(s.min())), max(self.s1, float(s.max()))


@dataclass(frozen=True)
class LoopClosure:
    """A hypothesis that won: scan ``scan`` placed by a corner first seen at scan ``seen``; ``delta``
    the pose of ``scan`` relative to ``seen``'s as the winning hypothesis held it."""

    seen: int
    scan: int
    delta: tuple[float, float, float]
    jump: float  # m the main track was moved by


@dataclass
class FeatureMap:
    """The result: smoothed poses ``(T, 3)`` and covariances, the map lines, corners of the map
    ``(K, 2)`` (intersections of lines whose ends meet), the loop closures, the EM iterations run."""

    poses: FloatArray
    covariances: FloatArray
    lines: list[MapLine]
    corners: FloatArray
    closures: list[LoopClosure]
    iterations: int

    def segments(self) -> FloatArray:
        """The map's line segments ``(N, 2, 2)``."""
        if not self.lines:
            return np.zeros((0, 2, 2))
        return np.stack([line.ends() for line in self.lines])


@dataclass
class _Scan:
    segments: list[Segment]
    corners: list[Corner]
    z: FloatArray  # (n, 2) alpha, r
    r: FloatArray  # (n, 2, 2)
    ends: FloatArray  # (n, 2, 2)
    bearing: FloatArray  # (n,)


@dataclass
class _Table:
    source: list[MapLine]
    alpha: FloatArray
    r: FloatArray
    cov: FloatArray
    ends: FloatArray
    born: FloatArray


@dataclass
class _Hypothesis:
    mean: FloatArray
    cov: FloatArray
    seen: int
    log_odds: float = 0.0
    age: int = 0


@dataclass
class _Forward:
    filtered: FloatArray
    filtered_cov: FloatArray
    predicted: FloatArray
    predicted_cov: FloatArray
    jacobians: FloatArray


@dataclass
class _MapCorners:
    pos: list[FloatArray] = field(default_factory=list)
    heading: list[float] = field(default_factory=list)
    angle: list[float] = field(default_factory=list)
    born: list[float] = field(default_factory=list)
    scan: list[int] = field(default_factory=list)


def scan_features(scan: Scan, params: ExtractionParams) -> tuple[list[Segment], list[Corner]]:
    """The segments and corners of ``scan`` in the robot frame (the laser's offset applied)."""
    g = scan.geometry
    pts = scan_points(scan.ranges, g.angles, g.max_range, g.min_range)
    if any(g.offset):
        ok = ~np.isnan(pts[:, 0])
        pts[ok] = transform_points(np.asarray(g.offset, dtype=np.float64), pts[ok])
    segments = extract_segments(pts, g.angle_increment, params)
    return segments, extract_corners(segments, params)


class FeatureMapper:
    """Line-feature maps from a log's scans and odometry by EM (:func:`run` reads as the paper)."""

    def __init__(self, params: FeatureMappingParams | None = None) -> None:
        self.params = params or FeatureMappingParams()
        self._table: _Table | None = None
        self._dirty = True
        self._spawned_at = -math.inf

    # ------------------------------------------------------------------------------------------
    def run(
        self, scans: list[Scan], start: FloatArray | None = None, progress: Callable[[], object] | None = None
    ) -> FeatureMap:
        """The map and path of ``scans`` (each with its odometry), the path starting at ``start``
        (default: the first odometry pose); ``progress`` is called after each scan of the first
        pass (the one that associates)."""
        p = self.params
        odom = np.array([s.odom for s in scans], dtype=np.float64)
        steps = relative(odom[:-1], odom[1:])
        first = odom[0] if start is None else np.asarray(start, dtype=np.float64)
        feats = [self._features(s) for s in scans]
        lines: list[MapLine] = []
        closures: list[LoopClosure] = []
        poses = np.zeros((0, 3))
        covs = np.zeros((0, 3, 3))
        done = 0
        best: tuple[float, FloatArray, FloatArray, list[MapLine]] | None = None
        assoc: list[list[tuple[int, int]]] | None = None
        for it in range(max(p.iterations, 1)):
            # E-step: forward EKF (the first pass associates, starts lines and hypotheses at
            # corners; later ones keep its associations), backward RTS (Eq. 3-5)
            fwd = self._forward(feats, steps, first, lines, closures if it == 0 else None, assoc, progress)
            new, covs = rts_smooth(
                fwd.filtered, fwd.filtered_cov, fwd.predicted, fwd.predicted_cov, fwd.jacobians
            )
            moved = float(np.max(np.hypot(*(new[:, :2] - poses[:, :2]).T))) if len(poses) else math.inf
            poses, done = new, it + 1
            # M-step: the lines refitted to their points at the smoothed poses, coinciding ones merged
            lines = self._m_step(lines, feats, poses)
            assoc = [[] for _ in feats]
            for j, line in enumerate(lines):
                for t, i in line.obs:
                    assoc[t].append((i, j))
            # EM must not lower the likelihood: stop when it did, and keep the best iteration
            cost = self._cost(feats, lines, assoc, poses, steps)
            if best is not None and cost >= best[0]:
                break
            best = (cost, poses, covs, lines)
            if moved < p.converged:
                break
        assert best is not None
        _, poses, covs, lines = best
        keep = [line for line in lines if len(line.obs) >= p.min_observations]
        return FeatureMap(poses, covs, keep, _map_corners(keep, p), closures, done)

    def _cost(
        self,
        feats: list[_Scan],
        lines: list[MapLine],
        assoc: list[list[tuple[int, int]]],
        poses: FloatArray,
        steps: FloatArray,
    ) -> float:
        """Minus the log-likelihood of the scans and the odometry given the path and the map (up to
        a constant): each association's squared Mahalanobis distance (capped at the gate: an
        outlier), each odometry step's."""
        p = self.params
        total = 0.0
        for t, pairs in enumerate(assoc):
            if pairs:
                nu, _, noise = self._pair_terms(feats[t], lines, pairs, poses[t])
                d2 = np.einsum("ki,ki->k", nu, np.linalg.solve(noise, nu[..., None])[..., 0])
                total += float(np.minimum(d2, p.gate).sum())
        moved = relative(poses[:-1], poses[1:])
        for step, odo in zip(moved, steps, strict=True):
            _, q, _ = predict(np.zeros(3), np.zeros((3, 3)), odo, p.motion)
            e = relative(odo, step)
            total += float(e @ np.linalg.solve(q, e))
        return total

    # ------------------------------------------------------------------------------------------
    def _features(self, scan: Scan) -> _Scan:
        p = self.params
        segments, corners = scan_features(scan, p.extraction)
        floor = np.diag([p.line_sigma_alpha**2, p.line_sigma_r**2])
        z = np.array([[s.alpha, s.r] for s in segments]).reshape(-1, 2)
        r = np.array([s.cov + floor for s in segments]).reshape(-1, 2, 2)
        ends = np.array([[s.start, s.end] for s in segments]).reshape(-1, 2, 2)
        bearing = np.array([s.bearing for s in segments])
        return _Scan(segments, corners, z, r, ends, bearing)

    def _forward(
        self,
        feats: list[_Scan],
        steps: FloatArray,
        start: FloatArray,
        lines: list[MapLine],
        closures: list[LoopClosure] | None,
        assoc: list[list[tuple[int, int]]] | None,
        progress: Callable[[], object] | None = None,
    ) -> _Forward:
        """The EKF forward recursion over all scans against ``lines`` (the system's parameters).

        Without ``assoc``, each scan's segments are associated by string search, and those left
        over start new lines; with ``closures``, the multiple-hypothesis loop search runs too and
        appends its closures. With ``assoc`` (per scan, ``(segment, line)``: the associations of
        the last pass, the lines merged since), those pairs are used where they still pass the
        gate. The observations are recorded anew."""
        p = self.params
        n = len(feats)
        for line in lines:
            line.obs = []
        out = _Forward(
            np.zeros((n, 3)), np.zeros((n, 3, 3)), np.zeros((n, 3)), np.zeros((n, 3, 3)), np.zeros((n, 3, 3))
        )
        mean, cov = start.copy(), np.eye(3) * 1e-8
        along = 0.0
        hyps: list[_Hypothesis] = []
        corners = _MapCorners()
        cooldown = 0
        self._spawned_at = -math.inf
        for t in range(n):
            if t:
                mean, cov, jac = predict(mean, cov, steps[t - 1], p.motion)
                along += float(np.hypot(steps[t - 1, 0], steps[t - 1, 1]))
            else:
                jac = np.eye(3)
            out.predicted[t], out.predicted_cov[t], out.jacobians[t] = mean, cov, jac
            f = feats[t]
            if assoc is not None:
                pairs = self._gated(f, lines, assoc[t], mean, cov)
                if pairs:
                    mean, cov = self._update(f, lines, pairs, mean, cov)
                out.filtered[t], out.filtered_cov[t] = mean, cov
                for i, j in assoc[t]:  # kept for the M-step even where the gate left them out
                    lines[j].obs.append((t, i))
                continue
            pairs, extra = self._associate(f, lines, mean, cov, None)
            if pairs:
                mean, cov = self._update(f, lines, pairs, mean, cov)
            if closures is not None:
                for h in hyps:
                    if t:
                        h.mean, h.cov, _ = predict(h.mean, h.cov, steps[t - 1], p.motion)
                won, cooldown = self._hypotheses(f, lines, along, mean, cov, hyps, corners, cooldown)
                if won is not None:
                    jump = float(np.hypot(*(won.mean[:2] - mean[:2])))
                    residual = won.mean - mean
                    residual[2] = float(wrap_angle(residual[2]))
                    mean, cov = update(mean, cov, residual, np.eye(3), won.cov)
                    seen = corners.scan[won.seen]
                    d = relative(out.filtered[seen], won.mean)
                    closures.append(LoopClosure(seen, t, (float(d[0]), float(d[1]), float(d[2])), jump))
                    hyps.clear()
                    cooldown = p.cooldown
                    pairs, extra = self._associate(f, lines, mean, cov, None)
            out.filtered[t], out.filtered_cov[t] = mean, cov
            self._record(t, f, lines, pairs + extra, mean, cov, along)
            if closures is not None:
                self._add_corners(t, f, mean, along, corners)
            if progress is not None:
                progress()
        return out

    def _arrays(self, lines: list[MapLine]) -> _Table:
        """The lines as arrays (rebuilt when a line was added or grew since the last call)."""
        if (
            self._table is None
            or self._table.source is not lines
            or self._dirty
            or len(self._table.born) != len(lines)
        ):
            rows = np.array([(ln.alpha, ln.r, ln.s0, ln.s1, ln.born) for ln in lines]).reshape(-1, 5)
            alpha, r = rows[:, 0], rows[:, 1]
            n = np.stack([np.cos(alpha), np.sin(alpha)], axis=1)
            t = np.stack([-n[:, 1], n[:, 0]], axis=1)
            foot = r[:, None] * n
            ends = np.stack([foot + rows[:, 2:3] * t, foot + rows[:, 3:4] * t], axis=1)
            cov = np.array([ln.cov for ln in lines]).reshape(-1, 2, 2)
            self._table = _Table(lines, alpha, r, cov, ends, rows[:, 4])
            self._dirty = False
        return self._table

    def _visible(self, lines: list[MapLine], pose: FloatArray, old: float | None) -> NDArray[np.int64]:
        """Map lines within sensing range of ``pose`` (and first seen before path length ``old``)."""
        if not lines:
            return np.zeros(0, np.int64)
        table = self._arrays(lines)
        reach = self.params.extraction.max_range + self.params.overlap_margin
        a, b = table.ends[:, 0], table.ends[:, 1]
        ab = b - a
        u = np.clip(
            np.einsum("ij,ij->i", pose[:2] - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1
        )
        near = np.hypot(*(a + u[:, None] * ab - pose[:2]).T) < reach
        if old is not None:
            near &= table.born < old
        return np.flatnonzero(near)

    def _associate(
        self, f: _Scan, lines: list[MapLine], mean: FloatArray, cov: FloatArray, old: float | None
    ) -> tuple[list[tuple[int, int, float]], list[tuple[int, int, float]]]:
        """The scan's segments paired to map lines by string search: ``(segment, line, d2)`` pairs
        for the update, and segments paired to an already paired line (a wall seen in pieces)."""
        p = self.params
        if len(f.segments) == 0:
            return [], []
        cand = self._visible(lines, mean, old)
        if len(cand) == 0:
            return [], []
        table = self._arrays(lines)
        zm, hm, jm = line_measurements(mean, table.alpha[cand], table.r[cand])
        sigma = table.cov[cand]
        ends = table.ends[cand] - mean[:2]
        c, s_ = math.cos(mean[2]), math.sin(mean[2])
        local = np.stack(
            [c * ends[..., 0] + s_ * ends[..., 1], -s_ * ends[..., 0] + c * ends[..., 1]], axis=-1
        )
        mid = _clipped_middles(local, p.extraction.max_range)
        # the map's lines in the scan's angular order (the string the scan's segments are matched to)
        order = np.argsort(np.arctan2(mid[:, 1], mid[:, 0]))
        zm, hm, jm, sigma = zm[order], hm[order], jm[order], sigma[order]
        cand_k = [int(k) for k in cand[order]]
        spans_k = local[order]
        # innovations (n, m, 2) and covariances (n, m, 2, 2)
        nu = f.z[:, None, :] - zm[None, :, :]
        nu[..., 0] = wrap_angle(nu[..., 0])
        base = hm @ cov @ hm.transpose(0, 2, 1) + jm @ sigma @ jm.transpose(0, 2, 1)  # (m, 2, 2)
        s = base[None, :, :, :] + f.r[:, None, :, :]
        det = s[..., 0, 0] * s[..., 1, 1] - s[..., 0, 1] * s[..., 1, 0]
        d2 = (
            s[..., 1, 1] * nu[..., 0] ** 2
            - 2 * s[..., 0, 1] * nu[..., 0] * nu[..., 1]
            + s[..., 0, 0] * nu[..., 1] ** 2
        ) / det
        overlap = _overlaps(f.ends, spans_k, p.overlap_margin)
        ok = (d2 < p.gate) & overlap
        gain = np.where(ok, p.gate - d2, -np.inf)
        if ok.sum() > 1:
            # the pairs must agree on the heading: keep those whose angle innovations lie within
            # ``consensus_angle`` of the one with the most support (gain) among them
            delta = nu[..., 0][ok]
            support = np.where(
                np.abs(wrap_angle(delta[:, None] - delta[None, :])) < p.consensus_angle,
                gain[ok][None, :],
                0.0,
            ).sum(axis=1)
            best = delta[int(np.argmax(support))]
            ok &= np.abs(wrap_angle(nu[..., 0] - best)) < p.consensus_angle
            gain = np.where(ok, gain, -np.inf)
        pairs = [(i, cand_k[j], float(d2[i, j])) for i, j in string_match(gain)]
        paired = {i for i, _, _ in pairs}
        used = {j for _, j, _ in pairs}
        extra = []
        for i in range(len(f.segments)):
            if i in paired or not ok[i].any():
                continue
            j = int(np.argmax(gain[i]))
            if cand_k[j] in used:
                extra.append((i, cand_k[j], float(d2[i, j])))
        return pairs, extra

    def _pair_terms(
        self, f: _Scan, lines: list[MapLine], pairs: list[tuple[int, int]], pose: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """For ``(segment, line)`` pairs at ``pose``: innovations ``(k, 2)`` (angles wrapped),
        Jacobians ``H`` ``(k, 2, 3)`` and the noise ``(k, 2, 2)`` (the segment's plus the line's)."""
        seg = np.array([i for i, _ in pairs], dtype=np.int64)
        idx = np.array([j for _, j in pairs], dtype=np.int64)
        alpha = np.array([lines[j].alpha for j in idx])
        r = np.array([lines[j].r for j in idx])
        sigma = np.array([lines[j].cov for j in idx])
        z, h, jac = line_measurements(pose, alpha, r)
        nu = f.z[seg] - z
        nu[:, 0] = wrap_angle(nu[:, 0])
        return nu, h, f.r[seg] + jac @ sigma @ jac.transpose(0, 2, 1)

    def _gated(
        self, f: _Scan, lines: list[MapLine], pairs: list[tuple[int, int]], mean: FloatArray, cov: FloatArray
    ) -> list[tuple[int, int, float]]:
        """The given ``(segment, line)`` pairs with their squared Mahalanobis distances, those
        outside the gate left out."""
        if not pairs:
            return []
        nu, h, noise = self._pair_terms(f, lines, pairs, mean)
        s = h @ cov @ h.transpose(0, 2, 1) + noise
        d2 = np.einsum("ki,ki->k", nu, np.linalg.solve(s, nu[..., None])[..., 0])
        return [(i, j, float(d)) for (i, j), d in zip(pairs, d2, strict=True) if d < self.params.gate]

    def _update(
        self,
        f: _Scan,
        lines: list[MapLine],
        pairs: list[tuple[int, int, float]],
        mean: FloatArray,
        cov: FloatArray,
    ) -> tuple[FloatArray, FloatArray]:
        """The EKF update with the paired lines (their own uncertainty added to the noise)."""
        k = len(pairs)
        nu, hk, nk = self._pair_terms(f, lines, [(i, j) for i, j, _ in pairs], mean)
        residual = nu.reshape(-1)
        h = hk.reshape(2 * k, 3)
        noise = np.zeros((2 * k, 2 * k))
        for n in range(k):
            noise[2 * n : 2 * n + 2, 2 * n : 2 * n + 2] = nk[n]
        return update(mean, cov, residual, h, noise)

    def _record(
        self,
        t: int,
        f: _Scan,
        lines: list[MapLine],
        pairs: list[tuple[int, int, float]],
        mean: FloatArray,
        cov: FloatArray,
        along: float,
    ) -> None:
        """Note the observations, grow the paired lines' extents, start lines for the rest."""
        self._dirty = True
        paired = set()
        for i, j, _ in pairs:
            lines[j].obs.append((t, i))
            lines[j].extend(transform_points(mean, f.ends[i]))
            paired.add(i)
        for i in range(len(f.segments)):
            if i in paired:
                continue
            alpha_r, r_r = f.z[i]
            aw = float(wrap_angle(alpha_r + mean[2]))
            ca, sa = math.cos(aw), math.sin(aw)
            rw = r_r + mean[0] * ca + mean[1] * sa
            jx = np.array([[0.0, 0.0, 1.0], [ca, sa, -mean[0] * sa + mean[1] * ca]])
            jz = np.array([[1.0, 0.0], [-mean[0] * sa + mean[1] * ca, 1.0]])
            sigma = jx @ cov @ jx.T + jz @ f.r[i] @ jz.T
            if rw < 0:
                aw, rw = float(wrap_angle(aw + math.pi)), -rw
                flip = np.diag([1.0, -1.0])
                sigma = flip @ sigma @ flip
            line = MapLine(aw, rw, sigma, math.inf, -math.inf, along, [(t, i)])
            line.extend(transform_points(mean, f.ends[i]))
            lines.append(line)

    # ------------------------------------------------------------------------------------------
    def _log_likelihood(self, f: _Scan, pairs: list[tuple[int, int, float]]) -> float:
        """How well a pose explains the scan with the old map: a paired segment counts ``-d2 / 2``,
        an unpaired one as a pair at the gate."""
        n = len(f.segments)
        return -0.5 * (sum(d2 for _, _, d2 in pairs) + (n - len(pairs)) * self.params.gate)

    def _hypotheses(
        self,
        f: _Scan,
        lines: list[MapLine],
        along: float,
        mean: FloatArray,
        cov: FloatArray,
        hyps: list[_Hypothesis],
        corners: _MapCorners,
        cooldown: int,
    ) -> tuple[_Hypothesis | None, int]:
        """One scan of the switching model: update and score the hypotheses against the map seen
        ``loop_path`` m ago, drop those that lost, start new ones at matching corners; the winner."""
        p = self.params
        old = along - p.loop_path
        main_pairs, _ = self._associate(f, lines, mean, cov, old)
        main_ll = self._log_likelihood(f, main_pairs)
        alive: list[_Hypothesis] = []
        winner: _Hypothesis | None = None
        for h in hyps:
            pairs, _ = self._associate(f, lines, h.mean, h.cov, old)
            if pairs:
                h.mean, h.cov = self._update(f, lines, pairs, h.mean, h.cov)
            h.log_odds += self._log_likelihood(f, pairs) - main_ll
            h.age += 1
            if h.log_odds < p.lose_log_odds or h.age > p.max_age:
                continue
            confirmed = h.age >= p.confirm_scans and h.log_odds >= p.win_log_odds
            if confirmed and (winner is None or h.log_odds > winner.log_odds):
                winner = h
            alive.append(h)
        hyps[:] = alive
        if winner is not None:
            return winner, cooldown
        if cooldown > 0:
            return None, cooldown - 1
        if along - self._spawned_at < p.spawn_distance:
            return None, 0
        self._spawned_at = along
        for h in self._spawn(f, along, mean, cov, corners, hyps):
            if len(hyps) >= p.max_hypotheses:
                break
            hyps.append(h)
        return None, 0

    def _spawn(
        self,
        f: _Scan,
        along: float,
        mean: FloatArray,
        cov: FloatArray,
        corners: _MapCorners,
        hyps: list[_Hypothesis],
    ) -> list[_Hypothesis]:
        """New hypotheses: the poses that put a corner of the scan onto an old map corner of the
        same angle, within reach of the current pose."""
        p = self.params
        if not f.corners or not corners.pos:
            return []
        pos = np.array(corners.pos)
        heading = np.array(corners.heading)
        angle = np.array(corners.angle)
        old = np.array(corners.born) < along - p.loop_path
        sigma = math.sqrt(max(float(np.linalg.eigvalsh(cov[:2, :2]).max()), 0.0))
        reach = min(p.window_max, max(p.window_min, p.window_sigmas * sigma))
        turn = min(math.pi, max(p.window_angle, p.window_sigmas * math.sqrt(max(cov[2, 2], 0.0))))
        out: list[_Hypothesis] = []
        init = np.diag([p.corner_sigma_xy**2, p.corner_sigma_xy**2, p.corner_sigma_theta**2])
        for c in f.corners:
            world = transform_points(mean, c.position[None])[0]
            ok = old & (np.abs(angle - c.angle) < p.corner_angle_tol)
            ok &= np.hypot(*(pos - world).T) < reach
            for k in np.flatnonzero(ok):
                theta = float(wrap_angle(heading[k] - c.heading))
                if abs(float(wrap_angle(theta - mean[2]))) > turn:
                    continue
                cs, sn = math.cos(theta), math.sin(theta)
                xy = pos[k] - np.array(
                    [cs * c.position[0] - sn * c.position[1], sn * c.position[0] + cs * c.position[1]]
                )
                cand = np.array([xy[0], xy[1], theta])
                if any(_same(cand, q, p) for q in [mean, *(h.mean for h in hyps), *(h.mean for h in out)]):
                    continue
                out.append(_Hypothesis(cand, init.copy(), int(k)))
        return out

    def _add_corners(self, t: int, f: _Scan, mean: FloatArray, along: float, corners: _MapCorners) -> None:
        """Put the scan's corners into the map's (unless one is already there)."""
        for c in f.corners:
            world = transform_points(mean, c.position[None])[0]
            head = float(wrap_angle(c.heading + mean[2]))
            if corners.pos:
                pos = np.array(corners.pos)
                close = np.hypot(*(pos - world).T) < 0.3
                close &= np.abs(wrap_angle(np.array(corners.heading) - head)) < math.radians(15.0)
                if close.any():
                    continue
            corners.pos.append(world)
            corners.heading.append(head)
            corners.angle.append(c.angle)
            corners.born.append(along)
            corners.scan.append(t)

    # ------------------------------------------------------------------------------------------
    def _m_step(self, lines: list[MapLine], feats: list[_Scan], poses: FloatArray) -> list[MapLine]:
        """The lines refitted to their points at ``poses``, then lines that coincide merged."""
        p = self.params
        fitted = [f for line in lines if line.obs for f in self._robust_refit(line, feats, poses)]
        groups = _coincide(fitted, p)
        merged: list[MapLine] = []
        for g in np.unique(groups):
            members = [fitted[k] for k in np.flatnonzero(groups == g)]
            if len(members) == 1:
                merged.append(members[0])
                continue
            obs = [o for m in members for o in m.obs]
            line = self._refit(obs, feats, poses, min(m.born for m in members))
            if line is not None:
                merged.append(line)
        return merged

    def _robust_refit(self, line: MapLine, feats: list[_Scan], poses: FloatArray) -> list[MapLine]:
        """The line refitted to its observations' points; an observation whose points lie off the
        fit by more than ``merge_distance`` on average (a wrong association, or a pose the smoother
        moved) leaves it and starts a line of its own."""
        p = self.params
        fit = self._refit(line.obs, feats, poses, line.born)
        if fit is None:
            return []
        n = np.array([math.cos(fit.alpha), math.sin(fit.alpha)])
        off = [
            float(np.mean(np.abs(transform_points(poses[t], feats[t].segments[i].points) @ n - fit.r)))
            > p.merge_distance
            for t, i in line.obs
        ]
        if not any(off) or all(off):
            return [fit]
        good = [o for o, bad in zip(line.obs, off, strict=True) if not bad]
        out = [self._refit(good, feats, poses, line.born)]
        out += [
            self._refit([o], feats, poses, line.born) for o, bad in zip(line.obs, off, strict=True) if bad
        ]
        return [f for f in out if f is not None]

    def _refit(
        self, obs: list[tuple[int, int]], feats: list[_Scan], poses: FloatArray, born: float
    ) -> MapLine | None:
        p = self.params
        pts = np.concatenate([transform_points(poses[t], feats[t].segments[i].points) for t, i in obs])
        if len(pts) < 2:
            return None
        alpha, r, cov = fit_line(pts, p.extraction.range_sigma)
        cov = cov + np.diag([p.line_sigma_alpha**2, p.line_sigma_r**2])
        ends = np.concatenate([transform_points(poses[t], feats[t].ends[i]) for t, i in obs])
        line = MapLine(alpha, r, cov, math.inf, -math.inf, born, list(obs))
        line.extend(ends)
        return line


def _clipped_middles(ends: FloatArray, reach: float) -> FloatArray:
    """The middles ``(m, 2)`` of the parts of the segments ``ends`` ``(m, 2, 2)`` (robot frame)
    within ``reach`` of the robot (the whole segment where none of it is)."""
    a, b = ends[:, 0], ends[:, 1]
    d = b - a
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-12)
    ad, aa = np.einsum("ij,ij->i", a, d), np.einsum("ij,ij->i", a, a)
    # |a + u d| = reach: u^2 dd + 2 u (a.d) + a.a - reach^2 = 0
    disc = ad * ad - dd * (aa - reach * reach)
    root = np.sqrt(np.maximum(disc, 0.0))
    u0 = np.maximum(0.0, (-ad - root) / dd)
    u1 = np.minimum(1.0, (-ad + root) / dd)
    bad = (disc <= 0) | (u1 < u0)
    u0, u1 = np.where(bad, 0.0, u0), np.where(bad, 1.0, u1)
    return np.asarray(a + (0.5 * (u0 + u1))[:, None] * d, dtype=np.float64)


def _overlaps(scan_ends: FloatArray, map_ends: FloatArray, margin: float) -> NDArray[np.bool_]:
    """Whether each scan segment ``(n, 2, 2)`` and each map segment ``(m, 2, 2)`` (the same frame)
    overlap along the map segment's direction, within ``margin``."""
    a, b = map_ends[:, 0], map_ends[:, 1]
    d = b - a
    length = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)
    u = d / length[:, None]
    s = np.einsum("nkc,mc->nmk", scan_ends, u) - np.einsum("mc,mc->m", a, u)[None, :, None]
    lo, hi = s.min(axis=2), s.max(axis=2)
    return np.asarray((hi > -margin) & (lo < length[None, :] + margin))


def _same(a: FloatArray, b: FloatArray, p: FeatureMappingParams) -> bool:
    return bool(
        math.hypot(a[0] - b[0], a[1] - b[1]) < p.distinct_xy
        and abs(float(wrap_angle(a[2] - b[2]))) < p.distinct_theta
    )


def _coincide(lines: list[MapLine], p: FeatureMappingParams) -> NDArray[np.int64]:
    """Group labels of lines that lie on one another: nearly parallel, each one's middle close to
    the other's line, extents overlapping or within ``merge_gap``."""
    n = len(lines)
    if n == 0:
        return np.zeros(0, np.int64)
    alpha = np.array([line.alpha for line in lines])
    r = np.array([line.r for line in lines])
    ends = np.array([line.ends() for line in lines])
    mid = ends.mean(axis=1)
    normal = np.stack([np.cos(alpha), np.sin(alpha)], axis=1)
    da = np.abs(wrap_angle(alpha[:, None] - alpha[None, :]))
    parallel = np.minimum(da, np.pi - da) < p.merge_angle
    dist = np.abs(mid @ normal.T - r[None, :])  # [i, j]: i's middle from j's line
    close = (dist < p.merge_distance) & (p.merge_distance > dist.T)
    tangent = np.stack([-normal[:, 1], normal[:, 0]], axis=1)
    s = np.einsum("ikc,jc->ijk", ends, tangent)  # i's ends along j's tangent
    lo, hi = s.min(axis=2), s.max(axis=2)
    own = np.array([[line.s0, line.s1] for line in lines])
    gap = np.maximum(lo - own[None, :, 1], own[None, :, 0] - hi)
    near = gap < p.merge_gap
    ok = parallel & close & near
    np.fill_diagonal(ok, False)
    i, j = np.nonzero(np.triu(ok))
    return np.asarray(components(n, np.stack([i, j], axis=1).astype(np.int64)), dtype=np.int64)


def _map_corners(lines: list[MapLine], p: FeatureMappingParams) -> FloatArray:
    """Corners of the finished map: intersections of two lines at a clear angle, both of whose
    nearer ends are within the corner gap of it."""
    out = []
    ends = [line.ends() for line in lines]
    gap = p.extraction.corner_gap
    for a in range(len(lines)):
        for b in range(a + 1, len(lines)):
            la, lb = lines[a], lines[b]
            da = abs(float(wrap_angle(la.alpha - lb.alpha)))
            if min(da, math.pi - da) < p.extraction.corner_angle:
                continue
            det = math.cos(la.alpha) * math.sin(lb.alpha) - math.sin(la.alpha) * math.cos(lb.alpha)
            x = (la.r * math.sin(lb.alpha) - lb.r * math.sin(la.alpha)) / det
            y = (lb.r * math.cos(la.alpha) - la.r * math.cos(lb.alpha)) / det
            c = np.array([x, y])
            if min(np.hypot(*(ends[a] - c).T)) < gap and min(np.hypot(*(ends[b] - c).T)) < gap:
                out.append(c)
    return np.array(out).reshape(-1, 2)
