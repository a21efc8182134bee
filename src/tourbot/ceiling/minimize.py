"""Global localization from one image: the minimization of the merit function (Gamallo et al.,
Sec. IV-B, Alg. 3 and Eq. 6), reported as one or several pose hypotheses.

Alg. 3 as in the paper: a set of particles (poses) is spread uniformly over the free space (702 in
the paper's experiment); each iteration evaluates M(P) (Alg. 2, Eq. 5), keeps the best
``particles`` (200) and adds offspring with Gaussian noise: 5 from each of the 15 % best and 1 from
each of the next 25 % (Sec. IV-B.2); ``iterations`` (N_iter = 6) rounds. The pose is the particle
of least merit (Eq. 6).

Beyond the paper, two steps (each can be switched off in :class:`LocalizerConfig` so that the
benchmark measures the paper's algorithm too):

- ``proposals``: poses computed from two detections and two map lights. A detection's ray meets
  the height of a candidate light at a point of the robot's frame; two such points and two lights
  of the same separation fix (x, y, heading) exactly. These poses join the uniform ones at the
  start, so the search starts next to the answer instead of 0.8 m (702 particles over a hall)
  away from it.
- ``refine``: Gauss-Newton on the pixel errors of the associated lights, from the best particles,
  with the base's swing (roll, pitch) estimated too when it explains the image clearly better
  (merit below ``swing_gain`` times the merit without it).

Symmetric layouts (Sec. IV-B, Fig. 10(j)): the final particles are grouped into hypotheses (poses
farther apart than ``separation_m`` or ``separation_rad``); every hypothesis whose N_P equals the
best one's and whose merit is within ``ambiguity_ratio`` of it is reported, so a symmetric ceiling
yields several hypotheses, never one confident wrong pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.ceiling.merit import Merit, associate, merit, merit_fast
from tourbot.ceiling.rig import CeilingCamera
from tourbot.geometry import wrap_angle
from tourbot.maps.grid import OccupancyGrid

__all__ = ["CeilingLocalizer", "Hypothesis", "Localization", "LocalizerConfig"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LocalizerConfig:
    """Alg. 3's settings (the paper's values as defaults) and the two steps beyond it."""

    particles: int = 200
    initial_particles: int = 702
    iterations: int = 6
    best_fraction: float = 0.15
    best_offspring: int = 5
    next_fraction: float = 0.25
    next_offspring: int = 1
    threshold: float = 25.0
    sigma_xy: float = 0.4
    sigma_theta: float = 0.15
    shrink: float = 0.6
    proposals: bool = True
    proposal_detections: int = 5
    proposal_tolerance: float = 0.15
    max_proposals: int = 600
    refine: bool = True
    refine_steps: int = 8
    swing_prior_deg: float = 10.0
    swing_gain: float = 0.8
    separation_m: float = 1.0
    separation_rad: float = 0.5
    ambiguity_ratio: float = 1.5
    max_hypotheses: int = 5

    def __post_init__(self) -> None:
        if self.particles < 1 or self.initial_particles < 1 or self.iterations < 0:
            raise ValueError("LocalizerConfig needs particles >= 1, initial_particles >= 1, iterations >= 0")
        if not 0 <= self.best_fraction + self.next_fraction <= 1:
            raise ValueError("LocalizerConfig needs best_fraction + next_fraction in [0, 1]")
        if self.threshold <= 0:
            raise ValueError("LocalizerConfig needs threshold > 0")


@dataclass(frozen=True)
class Hypothesis:
    """A pose (x, y, theta), its merit M(P), its number of associated lights N_P and the base's
    estimated (roll, pitch) swing."""

    pose: tuple[float, float, float]
    merit: float
    matched: int
    swing: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class Localization:
    """The hypotheses of one image, best first, and how many merit evaluations were made."""

    hypotheses: tuple[Hypothesis, ...]
    evaluations: int
    detections: int

    @property
    def best(self) -> Hypothesis | None:
        return self.hypotheses[0] if self.hypotheses else None

    @property
    def ambiguous(self) -> bool:
        return len(self.hypotheses) > 1


class CeilingLocalizer:
    """Global localization of one image against the site's ceiling lights."""

    def __init__(
        self,
        camera: CeilingCamera,
        lights: ArrayLike,
        free_space: OccupancyGrid | FloatArray,
        config: LocalizerConfig | None = None,
    ) -> None:
        self.camera = camera
        self.lights = np.asarray(lights, dtype=np.float64).reshape(-1, 3)
        if len(self.lights) == 0:
            raise ValueError("CeilingLocalizer needs at least one ceiling light")
        self.config = config or LocalizerConfig()
        if isinstance(free_space, OccupancyGrid):
            self._free = free_space.free_cell_centres()
            self._grid: OccupancyGrid | None = free_space
        else:
            self._free = np.asarray(free_space, dtype=np.float64).reshape(-1, 2)
            self._grid = None
        if len(self._free) == 0:
            raise ValueError("CeilingLocalizer needs free space to spread particles over")
        d = self.lights[:, None, :2] - self.lights[None, :, :2]
        self._pair_dist = np.hypot(d[..., 0], d[..., 1])

    # -- Alg. 3 ---------------------------------------------------------------------------------

    def locate(self, detected: ArrayLike, rng: np.random.Generator) -> Localization:
        """The pose hypotheses of one image's detected lights (Alg. 3, Eq. 6)."""
        cfg = self.config
        det = np.asarray(detected, dtype=np.float64).reshape(-1, 2)
        if len(det) == 0:
            return Localization((), 0, 0)
        pool = self._uniform(cfg.initial_particles, rng)
        if cfg.proposals:
            pool = np.concatenate([self.proposals(det), pool])
        m = self._merit(det, pool)
        evaluations = len(pool)
        order = _rank(m.value, m.n)[: cfg.particles]
        parts, value, n = pool[order], m.value[order], m.n[order]
        sx, st = cfg.sigma_xy, cfg.sigma_theta
        for _ in range(cfg.iterations):
            kids = self._offspring(parts, sx, st, rng)
            km = self._merit(det, kids)
            evaluations += len(kids)
            allp = np.concatenate([parts, kids])
            allv = np.concatenate([value, km.value])
            alln = np.concatenate([n, km.n])
            order = _rank(allv, alln)[: cfg.particles]
            parts, value, n = allp[order], allv[order], alln[order]
            sx, st = sx * cfg.shrink, st * cfg.shrink
        hyps = self._hypotheses(parts, value, n)
        if cfg.refine:
            refined = []
            for h in hyps:
                x, rm = self.polish(det, np.array(h.pose))
                evaluations += 2 + 8 * cfg.refine_steps
                better = rm.n[0] >= h.matched and rm.value[0] <= h.merit
                swing = (float(x[3]), float(x[4]))
                refined.append(
                    Hypothesis(_tuple(x), float(rm.value[0]), int(rm.n[0]), swing) if better else h
                )
            hyps = self._keep(sorted(refined, key=lambda h: h.merit))
        return Localization(tuple(hyps), evaluations, len(det))

    def _merit(self, det: FloatArray, poses: FloatArray) -> _Scores:
        n, _, value = merit_fast(self.camera, self.lights, det, poses, self.config.threshold)
        return _Scores(n, value)

    def _uniform(self, n: int, rng: np.random.Generator) -> FloatArray:
        """Sec. IV-B.1: particles spread uniformly over the free space."""
        idx = rng.integers(0, len(self._free), n)
        jitter = rng.uniform(-0.5, 0.5, (n, 2)) * (self._grid.resolution if self._grid is not None else 0.0)
        return np.column_stack([self._free[idx] + jitter, rng.uniform(-math.pi, math.pi, n)])

    def _offspring(self, parts: FloatArray, sx: float, st: float, rng: np.random.Generator) -> FloatArray:
        """Sec. IV-B.2: 5 noisy copies of each of the 15 % best, 1 of each of the next 25 %."""
        cfg = self.config
        k1 = max(1, round(cfg.best_fraction * len(parts)))
        k2 = round(cfg.next_fraction * len(parts))
        parents = np.concatenate(
            [
                np.repeat(parts[:k1], cfg.best_offspring, axis=0),
                np.repeat(parts[k1 : k1 + k2], cfg.next_offspring, axis=0),
            ]
        )
        noise = rng.standard_normal(parents.shape) * np.array([sx, sx, st])
        kids = parents + noise
        kids[:, 2] = wrap_angle(kids[:, 2])
        return kids

    # -- beyond the paper -----------------------------------------------------------------------

    def ceiling_points(self, det: FloatArray) -> FloatArray:
        """Per detection and map light, where the detection's ray meets that light's height:
        ``(J, I, 2)`` in the robot frame (NaN where the ray does not rise)."""
        rot, t = self.camera.mount()
        rays = self.camera.model.unproject(det) @ rot.T
        dz = self.lights[None, :, 2] - t[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(rays[:, 2:3] > 1e-6, dz / rays[:, 2:3], np.nan)
        return np.stack([t[0] + s * rays[:, 0:1], t[1] + s * rays[:, 1:2]], axis=-1)

    def proposals(self, det: FloatArray) -> FloatArray:
        """Poses from pairs of detections matched to pairs of map lights of the same separation."""
        cfg = self.config
        # the detections nearest the image centre are the most precise on the floor
        cu, cv = self.camera.model.centre()
        order = np.argsort(np.hypot(det[:, 0] - cu, det[:, 1] - cv))[: cfg.proposal_detections]
        q = self.ceiling_points(det[order])
        poses = []
        i_n = len(self.lights)
        ii, jj = np.meshgrid(np.arange(i_n), np.arange(i_n), indexing="ij")
        off = ii != jj
        ii, jj = ii[off], jj[off]
        for a in range(len(order)):
            for b in range(a + 1, len(order)):
                qa, qb = q[a, ii], q[b, jj]
                dq = qb - qa
                sep = np.hypot(dq[:, 0], dq[:, 1])
                ok = np.abs(sep - self._pair_dist[ii, jj]) <= cfg.proposal_tolerance * np.maximum(sep, 1.0)
                if not ok.any():
                    continue
                la, lb = self.lights[ii[ok], :2], self.lights[jj[ok], :2]
                dl = lb - la
                th = np.arctan2(dl[:, 1], dl[:, 0]) - np.arctan2(dq[ok, 1], dq[ok, 0])
                c, s = np.cos(th), np.sin(th)
                qa_ok = qa[ok]
                x = la[:, 0] - (c * qa_ok[:, 0] - s * qa_ok[:, 1])
                y = la[:, 1] - (s * qa_ok[:, 0] + c * qa_ok[:, 1])
                poses.append(np.column_stack([x, y, wrap_angle(th)]))
        if not poses:
            return np.zeros((0, 3))
        out = np.concatenate(poses)
        out = out[self._in_free(out)]
        return out[: cfg.max_proposals]

    def _in_free(self, poses: FloatArray) -> NDArray[np.bool_]:
        if self._grid is None:
            return np.ones(len(poses), dtype=bool)
        cells = self._grid.world_to_cell(poses[:, :2])
        inside = self._grid.inside(cells)
        free = np.zeros(len(poses), dtype=bool)
        free[inside] = self._grid.free()[cells[inside, 0], cells[inside, 1]]
        return free

    def polish(self, det: FloatArray, pose: FloatArray) -> tuple[FloatArray, Merit]:
        """:meth:`refine` without and with the swing; the swing is kept only when it explains the
        image clearly better (merit below ``swing_gain`` times; a model selection). Returns
        ``(x, y, theta, roll, pitch)`` and its merit."""
        cfg = self.config
        flat = self.refine(det, pose, swing=False)
        fm = merit(self.camera, self.lights, det, flat[None, :3], cfg.threshold)
        tilted = self.refine(det, flat[:3], swing=True)
        tm = merit(self.camera, self.lights, det, tilted[None, :3], cfg.threshold, (tilted[3], tilted[4]))
        if tm.n[0] >= fm.n[0] and tm.value[0] < cfg.swing_gain * fm.value[0]:
            return tilted, tm
        return flat, fm

    def refine(self, det: FloatArray, pose: FloatArray, swing: bool = True) -> FloatArray:
        """``(x, y, theta, roll, pitch)`` from ``pose`` by Gauss-Newton on the pixel errors of the
        associated lights (numeric Jacobian); with ``swing=False`` roll and pitch stay 0.

        Beyond the paper, whose main complaint is the camera's swing on floor bumps (Sec. VI): the
        base's roll and pitch are estimated with the pose (a Gaussian prior of ``swing_prior_deg``
        on each), so that a tilted camera does not pull the position by (light height) x tilt.
        """
        cfg = self.config
        x = np.concatenate([pose.astype(np.float64), [0.0, 0.0]])
        steps = np.array([1e-3, 1e-3, 1e-4, 1e-4, 1e-4])
        prior = 1.0 / math.radians(cfg.swing_prior_deg) if swing and cfg.swing_prior_deg > 0 else 0.0
        for _ in range(cfg.refine_steps):
            proj0, seen0 = self.camera.project_lights(x[None, :3], self.lights, (x[3], x[4]))
            match, _ = associate(proj0, seen0, det, cfg.threshold)
            j = np.flatnonzero(match[0] >= 0)
            if len(j) < 3:
                break
            i = match[0, j]
            r0 = (proj0[0, i] - det[j]).reshape(-1)
            # x, y and heading perturbed in one call; roll and pitch (a swing each) only when estimated
            probe = x[None, :3] + np.diag(steps[:3])
            pk, _ = self.camera.project_lights(probe, self.lights[i], (x[3], x[4]))
            cols = [(pk[k] - proj0[0, i]).reshape(-1) / steps[k] for k in range(3)]
            for k in (3, 4) if swing else ():
                xs = x.copy()
                xs[k] += steps[k]
                ps, _ = self.camera.project_lights(x[None, :3], self.lights[i], (xs[3], xs[4]))
                cols.append((ps[0] - proj0[0, i]).reshape(-1) / steps[k])
            if not swing:
                cols += [np.zeros(len(r0)), np.zeros(len(r0))]
            jac = np.stack(cols, axis=1)
            if swing and prior > 0:
                jac = np.vstack([jac, np.array([[0, 0, 0, prior, 0], [0, 0, 0, 0, prior]], dtype=np.float64)])
                r0 = np.concatenate([r0, prior * x[3:5]])
            delta, *_ = np.linalg.lstsq(jac, -r0, rcond=None)
            x = x + delta
            if np.abs(delta[:2]).max() < 1e-4 and np.abs(delta[2:]).max() < 1e-5:
                break
        x[2] = float(wrap_angle(x[2]))
        return x

    # -- hypotheses -----------------------------------------------------------------------------

    def _hypotheses(self, parts: FloatArray, value: FloatArray, n: NDArray[np.int64]) -> list[Hypothesis]:
        """Final particles grouped into separate poses, best first."""
        cfg = self.config
        out: list[Hypothesis] = []
        for k in range(len(parts)):
            if not np.isfinite(value[k]):
                break
            if any(_near(parts[k], np.array(h.pose), cfg.separation_m, cfg.separation_rad) for h in out):
                continue
            out.append(Hypothesis(_tuple(parts[k]), float(value[k]), int(n[k])))
            if len(out) >= 4 * cfg.max_hypotheses:
                break
        return self._keep(out)

    def _keep(self, hyps: list[Hypothesis]) -> list[Hypothesis]:
        """Those as good as the best: the same N_P and a merit within ``ambiguity_ratio``."""
        if not hyps:
            return []
        cfg = self.config
        best = hyps[0]
        kept = [
            h for h in hyps if h.matched >= best.matched and h.merit <= cfg.ambiguity_ratio * best.merit + 1.0
        ]
        merged: list[Hypothesis] = []
        for h in kept:
            if not any(
                _near(np.array(h.pose), np.array(g.pose), cfg.separation_m, cfg.separation_rad)
                for g in merged
            ):
                merged.append(h)
        return merged[: cfg.max_hypotheses]


@dataclass(frozen=True)
class _Scores:
    n: NDArray[np.int64]
    value: FloatArray


def _rank(value: FloatArray, n: NDArray[np.int64]) -> NDArray[np.int64]:
    """Particles ordered by merit, lower first (Eq. 6); ties broken by more matches."""
    return np.lexsort((-n, value)).astype(np.int64)


def _near(a: FloatArray, b: FloatArray, dm: float, dr: float) -> bool:
    dth = abs(float(wrap_angle(a[2] - b[2])))
    return bool(math.hypot(a[0] - b[0], a[1] - b[1]) < dm and dth < dr)


def _tuple(p: FloatArray) -> tuple[float, float, float]:
    return float(p[0]), float(p[1]), float(p[2])
