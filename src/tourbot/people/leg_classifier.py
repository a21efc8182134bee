"""P(leg) of a scan segment from its shape: geometric features and a logistic model learnt from
annotated scans.

Burgard et al. (Sec. 4, Fig. 5 middle) give each feature "a probability of being a leg"; the width
and local-minimum rule of :mod:`tourbot.people.legs` proposes the candidates, and this module
scores them by shape, after Arras et al. (2007, "Using boosted features for the detection of
people in 2D range data"), whose geometric features of a segment are the ones used here: number of
points, width, range, residuals of a line and of a circle fitted to the points, the circle's
radius, the boundary length against the width, the range jumps to the neighbouring beams, how far
the segment bulges towards the laser, and how densely the beams sample it.

The features are a numba kernel (:func:`segment_features`) with a plain-numpy reference
(:func:`segment_features_reference`). The model is a logistic regression on the standardised
features and their squares, fitted by Newton's method with a small ridge penalty
(:func:`fit_logistic`); its parameters live in a small JSON file built by ``tourbot train-legs``
from annotated ``leg_tracker`` bags. The package ships one (:data:`DEFAULT_MODEL`); a model
trained on one's own laser is loaded with :meth:`LegModel.load` and given to the detector through
:class:`tourbot.people.legs.LegConfig` (``--leg-model`` of ``tourbot track`` and ``tourbot slam``).
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
    "LegModel",
    "LegModelError",
    "candidate_features",
    "default_model",
    "fit_logistic",
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
# where the people happened to walk than about legs (a model trained where people walked near
# the laser learns "near is a leg" and misses the legs of another recording), and the width
# against the beam spacing ("density") carries what the number of points says about the shape.
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


def _expand(z: FloatArray) -> FloatArray:
    """Standardised features, their squares and a constant: the logistic model's inputs."""
    return np.concatenate([z, z * z, np.ones((z.shape[0], 1))], axis=1)


@dataclass(frozen=True)
class LegModel:
    """A logistic model of P(leg | segment features): ``mean``/``scale`` standardise the features
    named in ``MODEL_FEATURES``,
    ``weights`` apply to [z, z^2, 1]. ``trained_on`` names the data it was fitted to."""

    mean: tuple[float, ...]
    scale: tuple[float, ...]
    weights: tuple[float, ...]
    trained_on: str = ""

    def probability(self, features: FloatArray) -> FloatArray:
        """P(leg) of each row of ``features`` ``(S, len(FEATURE_NAMES))``."""
        if features.shape[0] == 0:
            return np.zeros(0)
        z = (features[:, _MODEL_COLUMNS] - np.asarray(self.mean)) / np.asarray(self.scale)
        z = np.clip(z, -8.0, 8.0)  # a segment unlike any seen in training is not extrapolated wildly
        logit = _expand(z) @ np.asarray(self.weights)
        return 1.0 / (1.0 + np.exp(-np.clip(logit, -50.0, 50.0)))

    def save(self, path: Path) -> None:
        """Write the model as JSON, whole or not at all (:func:`tourbot.io.output.write_text_whole`)."""
        doc = {
            "features": list(MODEL_FEATURES),
            "mean": list(self.mean),
            "scale": list(self.scale),
            "weights": list(self.weights),
            "trained_on": self.trained_on,
        }
        write_text_whole(path, json.dumps(doc, indent=1) + "\n")

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
        n = len(MODEL_FEATURES)
        sizes = {"mean": n, "scale": n, "weights": 2 * n + 1}  # weights of [z, z^2, 1]
        values: dict[str, tuple[float, ...]] = {}
        for name, size in sizes.items():
            raw = doc.get(name)
            if not isinstance(raw, list) or not all(
                isinstance(v, int | float) and not isinstance(v, bool) for v in raw
            ):
                raise LegModelError(f"expected a list of {size} numbers", path=path, field=name)
            if len(raw) != size:
                raise LegModelError(f"expected {size} numbers, found {len(raw)}", path=path, field=name)
            if not all(math.isfinite(v) for v in raw):
                raise LegModelError("numbers must be finite", path=path, field=name)
            values[name] = tuple(float(v) for v in raw)
        if any(v <= 0.0 for v in values["scale"]):
            raise LegModelError("scales must be positive", path=path, field="scale")
        return LegModel(values["mean"], values["scale"], values["weights"], str(doc.get("trained_on", "")))


def fit_logistic(
    features: FloatArray,
    labels: NDArray[np.bool_],
    *,
    ridge: float = 1.0,
    iterations: int = 50,
    trained_on: str = "",
) -> LegModel:
    """Fit a :class:`LegModel` to ``features`` ``(S, len(FEATURE_NAMES))`` by Newton's method
    (iteratively reweighted least squares) on the penalised log likelihood; positives and
    negatives weighted to count equally."""
    x = np.asarray(features, dtype=np.float64)[:, _MODEL_COLUMNS]
    y = np.asarray(labels, dtype=np.float64)
    mean = x.mean(axis=0)
    scale = x.std(axis=0)
    scale[scale < 1e-9] = 1.0
    a = _expand(np.clip((x - mean) / scale, -8.0, 8.0))
    npos = max(float(y.sum()), 1.0)
    nneg = max(float(len(y) - y.sum()), 1.0)
    sw = np.where(y > 0.5, 0.5 / npos, 0.5 / nneg) * len(y)
    w = np.zeros(a.shape[1])
    penalty = ridge * np.eye(a.shape[1])
    penalty[-1, -1] = 0.0  # the intercept is not penalised
    for _ in range(iterations):
        p = 1.0 / (1.0 + np.exp(-np.clip(a @ w, -50.0, 50.0)))
        grad = a.T @ (sw * (p - y)) + penalty @ w
        hess = (a * (sw * p * (1.0 - p))[:, None]).T @ a + penalty
        delta = np.linalg.solve(hess, grad)
        w -= delta
        if float(np.abs(delta).max()) < 1e-8:
            break
    return LegModel(tuple(mean.tolist()), tuple(scale.tolist()), tuple(w.tolist()), trained_on)
