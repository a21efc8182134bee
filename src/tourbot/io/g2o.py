"""Reading 2D pose graphs in the g2o text format (``VERTEX_SE2`` and ``EDGE_SE2`` lines).

``VERTEX_SE2 id x y theta`` gives a node's initial pose; ``EDGE_SE2 i j dx dy dtheta`` the measured
pose of ``j`` in the frame of ``i`` followed by the upper triangle of its 3 x 3 information matrix
(``I11 I12 I13 I22 I23 I33``). Files without vertices (some benchmarks) are initialised by chaining
the edges ``i -> i + 1``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose
from tourbot.io.errors import LogFormatError

__all__ = ["G2oGraph", "read_g2o"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class G2oGraph:
    """Nodes ``0..N-1`` with initial poses ``(N, 3)`` and edges ``(E, 2)`` with their measurements
    ``(E, 3)`` and information matrices ``(E, 3, 3)``."""

    poses: FloatArray
    edges: NDArray[np.int64]
    measurements: FloatArray
    information: FloatArray


def read_g2o(path: str | Path) -> G2oGraph:
    """Read a 2D g2o pose graph; a malformed line raises :class:`LogFormatError` naming it."""
    p = Path(path)
    vertices: dict[int, tuple[float, float, float]] = {}
    edges: list[tuple[int, int]] = []
    meas: list[tuple[float, float, float]] = []
    info: list[FloatArray] = []
    with p.open() as fh:
        for lineno, line in enumerate(fh, 1):
            tok = line.split()
            if not tok or tok[0].startswith("#"):
                continue
            try:
                if tok[0] == "VERTEX_SE2":
                    vertices[int(tok[1])] = (float(tok[2]), float(tok[3]), float(tok[4]))
                elif tok[0] == "EDGE_SE2":
                    if len(tok) < 12:
                        raise LogFormatError(
                            f"EDGE_SE2 needs 11 values, got {len(tok) - 1}", path=p, line=lineno
                        )
                    edges.append((int(tok[1]), int(tok[2])))
                    meas.append((float(tok[3]), float(tok[4]), float(tok[5])))
                    u = [float(t) for t in tok[6:12]]
                    info.append(np.array([[u[0], u[1], u[2]], [u[1], u[3], u[4]], [u[2], u[4], u[5]]]))
                else:
                    raise LogFormatError(f"unknown record {tok[0][:20]!r}", path=p, line=lineno)
            except (ValueError, IndexError) as exc:
                raise LogFormatError(f"bad number in {tok[0]} ({exc})", path=p, line=lineno) from None
    if not edges:
        raise LogFormatError("no EDGE_SE2 lines: not a 2D pose graph", path=p)
    e = np.asarray(edges, dtype=np.int64)
    m = np.asarray(meas, dtype=np.float64)
    n = int(max(e.max(), max(vertices, default=0))) + 1
    poses = np.full((n, 3), np.nan)
    for k, v in vertices.items():
        poses[k] = v
    if np.isnan(poses).any():  # chain the odometry edges i -> i + 1 where a vertex is missing
        poses[0] = poses[0] if np.isfinite(poses[0]).all() else 0.0
        step = {int(i): k for k, (i, j) in enumerate(e) if j == i + 1}
        for i in range(n - 1):
            if np.isnan(poses[i + 1]).any():
                if i not in step:
                    raise LogFormatError(f"node {i + 1} has no vertex and no edge from node {i}", path=p)
                poses[i + 1] = compose(poses[i], m[step[i]])
    return G2oGraph(poses, e, m, np.asarray(info))
