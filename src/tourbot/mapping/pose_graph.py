"""A 2D pose graph and its optimisation with GTSAM (graph SLAM back end).

Nodes are robot poses; an edge ``(i, j)`` says that pose ``j`` seen from pose ``i`` is ``delta``,
with an information matrix (the inverse covariance, in the ``x, y, theta`` order of the edge's
frame). The poses that best explain every edge minimise

    sum_edges rho( e_ij^T Omega_ij e_ij ),   e_ij = delta_ij^-1 (+) (x_i^-1 (+) x_j)

(Lu and Milios 1997; Grisetti et al., "A tutorial on graph-based SLAM", 2010, Eq. 11). Loop-closure
edges get dynamic covariance scaling (DCS: Agarwal, Tipaldi, Spinello, Stachniss and Burgard,
"Robust map optimization using dynamic covariance scaling", ICRA 2013): a loop edge of squared
whitened error ``chi2`` has its information scaled by ``s^2``, ``s = min(1, 2 Phi / (Phi + chi2))``,
the closed-form optimum of the switch variable of switchable constraints (Sunderhauf and Protzel
2012) with its prior of weight ``Phi``; its cost is bounded (it tends to ``Phi`` as ``chi2``
grows: the edge is switched off), so a wrong closure cannot drag a whole building out of shape,
where a Cauchy kernel's cost keeps growing (logarithmically) and a stretch of slack edges still
bends to it (measured on Freiburg 079, ``docs/results/loopclosure.md``); the optimiser is
GTSAM's Levenberg-Marquardt on the sparse factor graph (Dellaert and Kaess 2017). Odometry and
scan-matching edges keep the plain quadratic cost. :func:`edge_errors` recomputes the whitened
errors in numpy, to judge edges after an optimisation (the geometric consistency check of loop
closures).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tourbot.errors import TourbotError
from tourbot.geometry import relative

__all__ = ["Edge", "OptimizerParams", "PoseGraph", "PoseGraphError", "edge_errors"]

FloatArray = NDArray[np.float64]


class PoseGraphError(TourbotError):
    """A pose graph that cannot be optimised (no nodes, an edge to a missing node, a bad matrix)."""


@dataclass(frozen=True)
class OptimizerParams:
    """DCS's ``Phi`` for loop-closure edges (``dcs_phi``, in squared whitened units; 1, the value
    Agarwal et al. 2013 recommend and use for all their data sets) and the Levenberg-Marquardt
    stopping rules."""

    dcs_phi: float = 1.0
    max_iterations: int = 100
    relative_tolerance: float = 1e-6


@dataclass(frozen=True)
class Edge:
    """Pose ``j`` measured in the frame of pose ``i``; ``robust``: a loop closure."""

    i: int
    j: int
    delta: tuple[float, float, float]
    information: FloatArray
    robust: bool = False


@dataclass
class PoseGraph:
    """Nodes (their current poses, ``(N, 3)``) and edges; :meth:`optimize` moves the nodes."""

    poses: list[FloatArray] = field(default_factory=list)
    edges: list[Edge] = field(default_factory=list)

    def add_node(self, pose: FloatArray) -> int:
        self.poses.append(np.asarray(pose, dtype=np.float64).copy())
        return len(self.poses) - 1

    def add_edge(
        self, i: int, j: int, delta: FloatArray, information: FloatArray, *, robust: bool = False
    ) -> Edge:
        n = len(self.poses)
        if not (0 <= i < n and 0 <= j < n):
            raise PoseGraphError(f"edge {i} -> {j} between nodes that do not exist (the graph has {n})")
        info = np.asarray(information, dtype=np.float64).reshape(3, 3)
        if not np.all(np.linalg.eigvalsh(0.5 * (info + info.T)) > 0):
            raise PoseGraphError(f"edge {i} -> {j}: the information matrix is not positive definite")
        d = np.asarray(delta, dtype=np.float64)
        edge = Edge(i, j, (float(d[0]), float(d[1]), float(d[2])), info, robust)
        self.edges.append(edge)
        return edge

    def array(self) -> FloatArray:
        return np.asarray(self.poses, dtype=np.float64).reshape(-1, 3)

    def optimize(self, params: OptimizerParams | None = None, fixed: int = 0) -> FloatArray:
        """Optimise the node poses (node ``fixed`` held where it is); returns them ``(N, 3)``."""
        import gtsam

        p = params or OptimizerParams()
        if not self.poses:
            raise PoseGraphError("the pose graph has no nodes")
        graph = gtsam.NonlinearFactorGraph()
        initial = gtsam.Values()
        for k, pose in enumerate(self.poses):
            initial.insert(k, gtsam.Pose2(float(pose[0]), float(pose[1]), float(pose[2])))
        anchor = self.poses[fixed]
        graph.add(
            gtsam.PriorFactorPose2(
                fixed,
                gtsam.Pose2(float(anchor[0]), float(anchor[1]), float(anchor[2])),
                gtsam.noiseModel.Isotropic.Sigma(3, 1e-6),
            )
        )
        m = gtsam.noiseModel.mEstimator
        kernel = m.DCS.Create(p.dcs_phi)
        for e in self.edges:
            gauss = gtsam.noiseModel.Gaussian.Information(e.information)
            noise = gtsam.noiseModel.Robust.Create(kernel, gauss) if e.robust else gauss
            graph.add(gtsam.BetweenFactorPose2(e.i, e.j, gtsam.Pose2(*e.delta), noise))
        lm = gtsam.LevenbergMarquardtParams()
        lm.setMaxIterations(p.max_iterations)
        lm.setRelativeErrorTol(p.relative_tolerance)
        result = gtsam.LevenbergMarquardtOptimizer(graph, initial, lm).optimize()
        out = np.empty((len(self.poses), 3))
        for k in range(len(self.poses)):
            q = result.atPose2(k)
            out[k] = (q.x(), q.y(), q.theta())
        self.poses = list(out)
        return out


def edge_errors(poses: FloatArray, edges: list[Edge]) -> FloatArray:
    """Each edge's squared whitened error ``e^T Omega e`` at ``poses`` ``(N, 3)``, ``(E,)``."""
    if not edges:
        return np.zeros(0)
    i = np.array([e.i for e in edges])
    j = np.array([e.j for e in edges])
    delta = np.array([e.delta for e in edges])
    info = np.stack([e.information for e in edges])
    err = relative(delta, relative(poses[i], poses[j]))
    return np.einsum("ea,eab,eb->e", err, info, err)
