"""P(leg) of a scan segment from its shape: geometric features and boosted trees learnt from
annotated scans.

Burgard et al. (Sec. 4, Fig. 5 middle) give each feature "a probability of being a leg"; the width
and local-minimum rule of :mod:`tourbot.people.legs` proposes the candidates, and this module
scores them by shape, after Arras et al. (2007, "Using boosted features for the detection of
people in 2D range data"), whose geometric features of a segment are the ones used here: number of
points, width, range, residuals of a line and of a circle fitted to the points, the circle's
radius, the boundary length against the width, the range jumps to the neighbouring beams, how far
the segment bulges towards the laser, and how densely the beams sample it.

The features are a numba kernel (:func:`segment_features`) with a plain-numpy reference
(:func:`segment_features_reference`). The model (:class:`LegModel`) is boosted regression trees
(gradient boosting of the logistic loss, :func:`fit_boosted`) on the features in metric units
(``MODEL_FEATURES``: widths, fit residuals, radius, range jumps, bulge, spread, the nearest other
candidate, and the share of the expected beams, which does not grow with the beam count); the
number of points and the range are left out (the one depends on the laser's resolution, the
other on where people happened to walk in the recordings). Its trees live in a small JSON file
built by ``tourbot train-legs`` from annotated ``leg_tracker`` bags (each scan also seen as a
coarser, noisier laser would see it, :func:`tourbot.people.leg_training.thinned`). The package
ships one (:data:`DEFAULT_MODEL`); a model trained on one's own laser is loaded with
:meth:`LegModel.load` and given to the detector through :class:`tourbot.people.legs.LegConfig`
(``--leg-model`` of ``tourbot track`` and ``tourbot slam``).
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
from numpy.typing import NDArray

from tourbot.errors import InputError
from tourbot.io.output import write_text_whole

__all__ = [
    "DEFAULT_MODEL",
    "FEATURE_NAMES",
    "MODEL_FEATURES",
    "BoostConfig",
    "LegModel",
    "LegModelError",
    "candidate_features",
    "default_model",
    "fit_boosted",
    "segment_features",
    "segment_features_reference",
]

DEFAULT_MODEL = Path(__file__).with_name("leg_model.json")

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

FEATURE_NAMES = (
    "points",
    "width",
    "range",
    "line_rms",
    "circle_rms",
    "radius",
    "boundary_ratio",
    "jump_far",
    "jump_near",
    "bulge",
    "density",
    "spread",
    "neighbour",
)
SHAPE_FEATURES = 12  # the first twelve come from the segment alone
# The model leaves out the range and the number of points: in annotated data they say more about
# where the people happened to walk and the laser's resolution than about legs (a model trained
# where people walked near the laser learns "near is a leg" and misses the legs of another
# recording), and the width against the beam spacing ("density") carries what the number of
# points says about the shape.
MODEL_FEATURES = tuple(n for n in FEATURE_NAMES if n not in ("points", "range"))
_MODEL_COLUMNS = np.array([FEATURE_NAMES.index(n) for n in MODEL_FEATURES])
NEIGHBOUR_CAP = 1.0  # m: the nearest other candidate, "none" beyond this
JUMP_CAP = 1.0  # m: a neighbour farther behind than this (or no reading) is "far"
RADIUS_CAP = 1.0  # m: the circle through a straight segment has an infinite radius


def _circle_fit(x: FloatArray, y: FloatArray) -> tuple[float, float]:
    """Kasa's algebraic circle fit: (radius, RMS of the distances to the circle). The points are
    centred on their mean first, which keeps the normal equations well conditioned."""
    n = x.shape[0]
    if n < 3:
        return float(np.hypot(x[-1] - x[0], y[-1] - y[0]) / 2.0), 0.0
    x = x - x.mean()
    y = y - y.mean()
    a = np.stack([x, y, np.ones(n)], -1)
    b = -(x * x + y * y)
    m = a.T @ a
    if abs(np.linalg.det(m)) < 1e-18:
        return RADIUS_CAP, 0.0
    d, e, f = np.linalg.solve(m, a.T @ b)
    cx, cy = -d / 2.0, -e / 2.0
    rad2 = cx * cx + cy * cy - f
    if rad2 <= 0.0:
        return RADIUS_CAP, 0.0
    rad = math.sqrt(rad2)
    res = np.hypot(x - cx, y - cy) - rad
    return min(rad, RADIUS_CAP), float(np.sqrt(np.mean(res * res)))


def segment_features_reference(
    r: FloatArray,
    angles: FloatArray,
    valid: NDArray[np.bool_],
    first: IntArray,
    last: IntArray,
) -> FloatArray:
    """Plain-numpy features ``(S, len(FEATURE_NAMES))`` of the segments ``first[s]..last[s]``."""
    B = r.shape[0]
    step = float(abs(angles[1] - angles[0])) if B > 1 else 0.0
    out = np.zeros((first.shape[0], SHAPE_FEATURES))
    for s, (i, j) in enumerate(zip(first.tolist(), last.tolist(), strict=True)):
        rr = r[i : j + 1]
        x = rr * np.cos(angles[i : j + 1])
        y = rr * np.sin(angles[i : j + 1])
        n = j - i + 1
        width = float(np.hypot(x[-1] - x[0], y[-1] - y[0]))
        mean_r = float(rr.mean())
        cx, cy = x.mean(), y.mean()
        cov = np.cov(np.stack([x - cx, y - cy]), bias=True) if n > 1 else np.zeros((2, 2))
        line_rms = float(math.sqrt(max(np.linalg.eigvalsh(cov)[0], 0.0)))
        radius, circle_rms = _circle_fit(x, y)
        boundary = float(np.hypot(np.diff(x), np.diff(y)).sum())
        left = r[i - 1] - mean_r if i > 0 and valid[i - 1] else JUMP_CAP
        right = r[j + 1] - mean_r if j < B - 1 and valid[j + 1] else JUMP_CAP
        left, right = min(left, JUMP_CAP), min(right, JUMP_CAP)
        # Bulge: how much nearer to the laser the middle point is than the chord between the ends.
        k = n // 2
        ux, uy = x[-1] - x[0], y[-1] - y[0]
        chord = math.hypot(ux, uy)
        if chord > 0.0:
            cross = (ux * (y[k] - y[0]) - uy * (x[k] - x[0])) / chord
            # the sign that points towards the laser (the origin)
            to_origin = ux * (0.0 - y[0]) - uy * (0.0 - x[0])
            bulge = cross if to_origin >= 0.0 else -cross
        else:
            bulge = 0.0
        expected = width / max(mean_r * step, 1e-6) + 1.0
        spread = float(np.sqrt(np.mean((x - cx) ** 2 + (y - cy) ** 2)))
        out[s] = (
            math.log(n),
            width,
            mean_r,
            line_rms,
            circle_rms,
            radius,
            boundary / max(width, 1e-6),
            max(left, right),
            min(left, right),
            bulge,
            n / expected,
            spread,
        )
    return out


@numba.njit(cache=True)
def _features_kernel(
    r: FloatArray,
    angles: FloatArray,
    valid: NDArray[np.bool_],
    first: IntArray,
    last: IntArray,
    jump_cap: float,
    radius_cap: float,
) -> FloatArray:
    B = r.shape[0]
    step = abs(angles[1] - angles[0]) if B > 1 else 0.0
    S = first.shape[0]
    out = np.zeros((S, 12))  # SHAPE_FEATURES
    for s in range(S):
        i = first[s]
        j = last[s]
        n = j - i + 1
        sx = sy = sr = 0.0
        for k in range(i, j + 1):
            sx += r[k] * math.cos(angles[k])
            sy += r[k] * math.sin(angles[k])
            sr += r[k]
        cx = sx / n
        cy = sy / n
        mean_r = sr / n
        # second moments about the centroid, boundary length
        cxx = cxy = cyy = 0.0
        boundary = 0.0
        px = py = 0.0
        for k in range(i, j + 1):
            x = r[k] * math.cos(angles[k])
            y = r[k] * math.sin(angles[k])
            dx = x - cx
            dy = y - cy
            cxx += dx * dx
            cxy += dx * dy
            cyy += dy * dy
            if k > i:
                boundary += math.hypot(x - px, y - py)
            px = x
            py = y
        cxx /= n
        cxy /= n
        cyy /= n
        tr = cxx + cyy
        det = cxx * cyy - cxy * cxy
        disc = math.sqrt(max(tr * tr / 4.0 - det, 0.0))
        line_rms = math.sqrt(max(tr / 2.0 - disc, 0.0))
        x0 = r[i] * math.cos(angles[i])
        y0 = r[i] * math.sin(angles[i])
        x1 = r[j] * math.cos(angles[j])
        y1 = r[j] * math.sin(angles[j])
        width = math.hypot(x1 - x0, y1 - y0)
        # Kasa circle fit, about the centroid: normal equations of [x y 1] [D E F]^T = -(x^2 + y^2)
        radius = width / 2.0
        circle_rms = 0.0
        if n >= 3:
            m = np.zeros((3, 3))
            v = np.zeros(3)
            for k in range(i, j + 1):
                x = r[k] * math.cos(angles[k]) - cx
                y = r[k] * math.sin(angles[k]) - cy
                row = (x, y, 1.0)
                rhs = -(x * x + y * y)
                for a in range(3):
                    v[a] += row[a] * rhs
                    for b in range(3):
                        m[a, b] += row[a] * row[b]
            if abs(np.linalg.det(m)) < 1e-18:
                radius = radius_cap
            else:
                sol = np.linalg.solve(m, v)
                ccx = -sol[0] / 2.0
                ccy = -sol[1] / 2.0
                rad2 = ccx * ccx + ccy * ccy - sol[2]
                if rad2 <= 0.0:
                    radius = radius_cap
                else:
                    rad = math.sqrt(rad2)
                    acc = 0.0
                    for k in range(i, j + 1):
                        x = r[k] * math.cos(angles[k]) - cx
                        y = r[k] * math.sin(angles[k]) - cy
                        e = math.hypot(x - ccx, y - ccy) - rad
                        acc += e * e
                    circle_rms = math.sqrt(acc / n)
                    radius = min(rad, radius_cap)
        left = r[i - 1] - mean_r if i > 0 and valid[i - 1] else jump_cap
        right = r[j + 1] - mean_r if j < B - 1 and valid[j + 1] else jump_cap
        left = min(left, jump_cap)
        right = min(right, jump_cap)
        kk = i + n // 2
        xm = r[kk] * math.cos(angles[kk])
        ym = r[kk] * math.sin(angles[kk])
        ux = x1 - x0
        uy = y1 - y0
        chord = math.hypot(ux, uy)
        bulge = 0.0
        if chord > 0.0:
            cross = (ux * (ym - y0) - uy * (xm - x0)) / chord
            to_origin = ux * (0.0 - y0) - uy * (0.0 - x0)
            bulge = cross if to_origin >= 0.0 else -cross
        expected = width / max(mean_r * step, 1e-6) + 1.0
        out[s, 0] = math.log(n)
        out[s, 1] = width
        out[s, 2] = mean_r
        out[s, 3] = line_rms
        out[s, 4] = circle_rms
        out[s, 5] = radius
        out[s, 6] = boundary / max(width, 1e-6)
        out[s, 7] = max(left, right)
        out[s, 8] = min(left, right)
        out[s, 9] = bulge
        out[s, 10] = n / expected
        out[s, 11] = math.sqrt(tr)
    return out


def segment_features(
    r: FloatArray, angles: FloatArray, valid: NDArray[np.bool_], first: IntArray, last: IntArray
) -> FloatArray:
    """Features ``(S, len(FEATURE_NAMES))`` of the segments ``first[s]..last[s]`` of a scan
    (numba kernel of :func:`segment_features_reference`)."""
    return _features_kernel(
        np.ascontiguousarray(r, dtype=np.float64),
        np.ascontiguousarray(angles, dtype=np.float64),
        np.ascontiguousarray(valid, dtype=np.bool_),
        np.ascontiguousarray(first, dtype=np.int64),
        np.ascontiguousarray(last, dtype=np.int64),
        JUMP_CAP,
        RADIUS_CAP,
    )


def candidate_features(
    r: FloatArray,
    angles: FloatArray,
    valid: NDArray[np.bool_],
    first: IntArray,
    last: IntArray,
    points: FloatArray,
) -> FloatArray:
    """All features of the leg candidates of one scan: each segment's shape
    (:func:`segment_features`) and the distance to the nearest other candidate at ``points``
    (a person has two legs; a lone thin thing is more often a chair or table leg)."""
    shape = segment_features(r, angles, valid, first, last)
    near = np.full(points.shape[0], NEIGHBOUR_CAP)
    if points.shape[0] > 1:
        d = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=-1)
        np.fill_diagonal(d, np.inf)
        near = np.minimum(d.min(axis=1), NEIGHBOUR_CAP)
    return np.concatenate([shape, near[:, None]], axis=1)


class LegModelError(InputError):
    """A leg model file that cannot be read: the message names the file and the field."""


@functools.cache
def default_model() -> LegModel | None:
    """The shipped model (``leg_model.json`` beside this module), or None when there is none."""
    return LegModel.load(DEFAULT_MODEL) if DEFAULT_MODEL.exists() else None


MAX_DEPTH = 8  # deeper trees than this in a model file are refused (2^depth leaves per tree)


@dataclass(frozen=True)
class LegModel:
    """Boosted regression trees for P(leg | segment features), after Arras et al. (2007), whose
    detector boosts the same geometric features (here gradient boosting of the logistic loss, the
    successor of their AdaBoost). Every tree is complete, of ``depth`` levels: for tree ``t`` the
    internal node ``n`` (heap order, children ``2n + 1`` and ``2n + 2``) sends a segment right when
    its feature ``split_feature[t][n]`` (an index into ``MODEL_FEATURES``) is above
    ``split_value[t][n]``; the leaf reached adds ``leaf_value[t][leaf]`` to the log odds, which
    start at ``bias``. ``trained_on`` names the data it was fitted to."""

    depth: int
    bias: float
    split_feature: tuple[tuple[int, ...], ...]
    split_value: tuple[tuple[float, ...], ...]
    leaf_value: tuple[tuple[float, ...], ...]
    trained_on: str = ""

    def log_odds(self, features: FloatArray) -> FloatArray:
        """The model's log odds of a leg for each row of ``features`` ``(S, len(FEATURE_NAMES))``."""
        x = np.asarray(features, dtype=np.float64)[:, _MODEL_COLUMNS]
        S = x.shape[0]
        out = np.full(S, self.bias)
        if S == 0 or not self.leaf_value:
            return out
        feat = np.asarray(self.split_feature, dtype=np.int64)  # (T, 2^d - 1)
        value = np.asarray(self.split_value, dtype=np.float64)
        leaves = np.asarray(self.leaf_value, dtype=np.float64)  # (T, 2^d)
        T = feat.shape[0]
        trees = np.arange(T)[None, :]
        node = np.zeros((S, T), dtype=np.int64)
        rows = np.arange(S)[:, None]
        for _ in range(self.depth):
            right = x[rows, feat[trees, node]] > value[trees, node]
            node = 2 * node + 1 + right
        out += leaves[trees, node - (2**self.depth - 1)].sum(axis=1)
        return out

    def probability(self, features: FloatArray) -> FloatArray:
        """P(leg) of each row of ``features`` ``(S, len(FEATURE_NAMES))``."""
        return 1.0 / (1.0 + np.exp(-np.clip(self.log_odds(features), -50.0, 50.0)))

    def save(self, path: Path) -> None:
        """Write the model as JSON, whole or not at all (:func:`tourbot.io.output.write_text_whole`)."""
        doc = {
            "kind": "boosted-trees",
            "features": list(MODEL_FEATURES),
            "depth": self.depth,
            "bias": self.bias,
            "split_feature": [list(t) for t in self.split_feature],
            "split_value": [list(t) for t in self.split_value],
            "leaf_value": [list(t) for t in self.leaf_value],
            "trained_on": self.trained_on,
        }
        write_text_whole(path, json.dumps(doc) + "\n")

    @staticmethod
    def load(path: Path) -> LegModel:
        """The model saved in ``path``; :class:`LegModelError` (file, line or field) when the file
        is missing, is not JSON, was built for other features or has numbers of the wrong count."""
        try:
            text = Path(path).read_text(encoding="utf-8")
        except FileNotFoundError:
            raise LegModelError("no such leg model file", path=path) from None
        except (OSError, UnicodeDecodeError) as exc:
            raise LegModelError(f"cannot read the leg model: {exc}", path=path) from None
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as exc:
            raise LegModelError(f"not JSON: {exc.msg}", path=path, line=exc.lineno) from None
        if not isinstance(doc, dict):
            raise LegModelError("not a leg model (a JSON object is expected)", path=path)
        features = doc.get("features")
        if not isinstance(features, list) or tuple(features) != MODEL_FEATURES:
            raise LegModelError(
                f"leg model built for other features: {features} (expected {list(MODEL_FEATURES)})",
                path=path,
                field="features",
            )
        if doc.get("kind") != "boosted-trees":
            raise LegModelError(
                f"not a boosted-trees leg model: kind {doc.get('kind')!r} (retrain: tourbot train-legs)",
                path=path,
                field="kind",
            )
        depth = doc.get("depth")
        if not isinstance(depth, int) or isinstance(depth, bool) or not 1 <= depth <= MAX_DEPTH:
            raise LegModelError(f"expected an integer from 1 to {MAX_DEPTH}", path=path, field="depth")
        bias = doc.get("bias")
        if not isinstance(bias, int | float) or isinstance(bias, bool) or not math.isfinite(bias):
            raise LegModelError("expected a finite number", path=path, field="bias")
        sizes = {"split_feature": 2**depth - 1, "split_value": 2**depth - 1, "leaf_value": 2**depth}
        tables: dict[str, list[list[float]]] = {}
        for name, size in sizes.items():
            raw = doc.get(name)
            if not isinstance(raw, list) or not all(
                isinstance(t, list) and len(t) == size and all(_is_number(v) for v in t) for t in raw
            ):
                raise LegModelError(f"expected a list of trees of {size} numbers each", path=path, field=name)
            if not all(math.isfinite(v) for t in raw for v in t):
                raise LegModelError("numbers must be finite", path=path, field=name)
            tables[name] = raw
        if not len(tables["split_feature"]) == len(tables["split_value"]) == len(tables["leaf_value"]):
            raise LegModelError("split_feature, split_value and leaf_value differ in trees", path=path)
        n = len(MODEL_FEATURES)
        if not all(float(v).is_integer() and 0 <= v < n for t in tables["split_feature"] for v in t):
            raise LegModelError(
                f"feature indices must be integers from 0 to {n - 1}", path=path, field="split_feature"
            )
        return LegModel(
            depth,
            float(bias),
            tuple(tuple(int(v) for v in t) for t in tables["split_feature"]),
            tuple(tuple(float(v) for v in t) for t in tables["split_value"]),
            tuple(tuple(float(v) for v in t) for t in tables["leaf_value"]),
            str(doc.get("trained_on", "")),
        )


def _is_number(v: object) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


@dataclass(frozen=True, slots=True)
class BoostConfig:
    """Gradient boosting of :class:`LegModel`: ``rounds`` trees of ``depth`` levels, each shrunk by
    ``learning_rate``; splits are searched among ``bins`` quantiles of each feature; a node with
    fewer than ``min_leaf`` samples is not split; ``l2`` regularises the leaf values (Newton steps
    of the logistic loss, as in XGBoost). Positives and negatives weigh the same in all.
    300 trees of 4 levels at 0.1 were chosen over 150 of 3 at 0.2 on held-out recordings (best
    precision at recall 0.9, leave one recording out: better on 4 of 6, within 0.01 on the other
    two; mean 0.63 against 0.54)."""

    rounds: int = 300
    depth: int = 4
    learning_rate: float = 0.1
    bins: int = 32
    min_leaf: int = 20
    l2: float = 1.0


def fit_boosted(
    features: FloatArray,
    labels: NDArray[np.bool_],
    config: BoostConfig | None = None,
    *,
    trained_on: str = "",
) -> LegModel:
    """Fit a :class:`LegModel` to ``features`` ``(S, len(FEATURE_NAMES))`` and ``labels``."""
    cfg = config or BoostConfig()
    x = np.asarray(features, dtype=np.float64)[:, _MODEL_COLUMNS]
    y = np.asarray(labels, dtype=np.float64)
    S, F = x.shape
    npos = max(float(y.sum()), 1.0)
    nneg = max(float(S - y.sum()), 1.0)
    weight = np.where(y > 0.5, 0.5 / npos, 0.5 / nneg) * S
    bias = 0.0
    qs = np.linspace(0.0, 1.0, cfg.bins + 1)[1:-1]
    edges = [np.unique(np.quantile(x[:, f], qs)) if S else np.zeros(0) for f in range(F)]
    binned = (
        np.stack([np.searchsorted(edges[f], x[:, f]) for f in range(F)], 1) if S else np.zeros((0, F), int)
    )
    score = np.full(S, bias)
    feats: list[tuple[int, ...]] = []
    values: list[tuple[float, ...]] = []
    leaves: list[tuple[float, ...]] = []
    internal = 2**cfg.depth - 1
    for _ in range(cfg.rounds):
        p = 1.0 / (1.0 + np.exp(-score))
        g = weight * (p - y)
        h = weight * p * (1.0 - p)
        tf = np.zeros(internal, dtype=np.int64)
        tv = np.full(internal, np.finfo(np.float64).max)  # no split: every segment goes left
        tl = np.zeros(internal + 1)
        node = np.zeros(S, dtype=np.int64)
        for n in range(internal):
            idx = np.flatnonzero(node == n)
            best = _best_split(binned[idx], g[idx], h[idx], edges, cfg) if idx.size >= cfg.min_leaf else None
            if best is not None:
                tf[n], tv[n] = best
            go = x[idx, tf[n]] > tv[n]
            node[idx] = 2 * n + 1 + go
        leaf = node - internal
        gs = np.bincount(leaf, weights=g, minlength=internal + 1)
        hs = np.bincount(leaf, weights=h, minlength=internal + 1)
        tl = -cfg.learning_rate * gs / (hs + cfg.l2)
        score += tl[leaf]
        feats.append(tuple(tf.tolist()))
        values.append(tuple(tv.tolist()))
        leaves.append(tuple(tl.tolist()))
    return LegModel(cfg.depth, bias, tuple(feats), tuple(values), tuple(leaves), trained_on)


def _best_split(
    binned: NDArray[np.int64], g: FloatArray, h: FloatArray, edges: list[FloatArray], cfg: BoostConfig
) -> tuple[int, float] | None:
    """The (feature, value) split of one node with the largest gain of the second-order logistic
    loss, or None when no split gains."""
    G, H = float(g.sum()), float(h.sum())
    base = G * G / (H + cfg.l2)
    best_gain, best = 1e-12, None
    for f, e in enumerate(edges):
        if e.size == 0:
            continue
        gl = np.cumsum(np.bincount(binned[:, f], weights=g, minlength=e.size + 1))[:-1]
        hl = np.cumsum(np.bincount(binned[:, f], weights=h, minlength=e.size + 1))[:-1]
        gain = gl**2 / (hl + cfg.l2) + (G - gl) ** 2 / (H - hl + cfg.l2) - base
        t = int(np.argmax(gain))
        if gain[t] > best_gain:
            best_gain, best = float(gain[t]), (f, float(e[t]))
    return best
