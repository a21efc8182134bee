"""How well a people tracker did: CLEAR-MOT (Bernardin and Stiefelhagen 2008) and IDF1 (Ristani et
al. 2016), by ``motmetrics``.

Per frame, the ground-truth people and the tracker's hypotheses are matched within
``match_distance`` metres (a pair farther apart is no match); MOTA counts misses, false positives
and identity switches against the number of true objects, MOTP is the mean distance (m) of the
matched pairs, IDF1 the F1 score of identity-preserving matches over the whole run.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["MOT_METRICS", "Frame", "clear_mot"]

MOT_METRICS = ("mota", "motp", "num_switches", "idf1", "precision", "recall")


@dataclass(frozen=True)
class Frame:
    """One frame: the ids ``(G,)`` and positions ``(G, 2)`` of the true people, and those ``(H,)``,
    ``(H, 2)`` of the hypotheses."""

    truth_ids: ArrayLike
    truth: ArrayLike
    hypothesis_ids: ArrayLike
    hypotheses: ArrayLike


def clear_mot(frames: Iterable[Frame], match_distance: float) -> dict[str, float]:
    """CLEAR-MOT (``mota``, ``motp`` in metres, ``num_switches``), ``idf1``, ``precision`` and
    ``recall`` over ``frames``."""
    import motmetrics as mm

    acc = mm.MOTAccumulator(auto_id=True)
    for f in frames:
        gt = np.asarray(f.truth, dtype=np.float64).reshape(-1, 2)
        h = np.asarray(f.hypotheses, dtype=np.float64).reshape(-1, 2)
        dist = np.linalg.norm(gt[:, None, :] - h[None, :, :], axis=-1)
        dist[dist > match_distance] = np.nan
        acc.update(
            np.asarray(f.truth_ids, dtype=np.int64).tolist(),
            np.asarray(f.hypothesis_ids, dtype=np.int64).tolist(),
            dist,
        )
    summary = mm.metrics.create().compute(acc, metrics=list(MOT_METRICS), name="run")
    return {n: float(summary[n].iloc[0]) for n in MOT_METRICS}
