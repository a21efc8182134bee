"""Graph SLAM: the incremental scan matcher as front end, loop closures, a pose graph optimised.

The incremental mapper (Burgard et al. Sec. 2.1, :mod:`tourbot.mapping.incremental`) aligns each
scan to the map of the last scans; it is locally accurate but drifts, and a building's loops do not
close. Here each scan becomes a node of a pose graph (:mod:`tourbot.mapping.pose_graph`), linked to
the previous one by the front end's aligned motion (scan matching, which already fused the
odometry as its prior: a second, odometry edge would count the wheels twice and bend the graph
by their bias, as measured on Intel) or, where the scan could not be aligned, by the raw
odometry, whose covariance grows with the motion. A scan-matching edge's covariance is the
alignment's own: the inverse curvature of the front end's objective at the aligned pose (map
likelihood and odometry prior; Censi, "An accurate closed-form estimate of ICP's covariance",
ICRA 2007; :func:`tourbot.mapping.scan_matching.curvature`), scaled by ``sm_scale``. It says
which way a match is uncertain: in a corridor, tight across and loose along, so that a loop's
correction goes along the corridors where the front end could not see its motion, not across
rooms where it could. A step of the front end that departs from the odometry by more than the
front end's own odometry prior allows (beyond its 99.9 % chi-square quantile) is no scan-matching
edge: back in a place it mapped long before, the front end aligns the scan with that old, drifted
part of its map (ACES: scans 0.5-1 m off, where the odometry was within 0.1 m), an implicit loop
closure that a tight sequential edge would freeze into the chain. Its edge is the odometry's,
loosened by the disagreement (its covariance plus the outer product of the difference between
the two steps), so that either may turn out right. Consecutive runs of scans form
*submaps* (their endpoints at the graph's poses, in the frame of the submap's first node). Every
few scans, the finished submaps the robot may be back in (the current graph pose, within a window
that grows with the path length between submap and scan through the graph) are searched for the
scan with the branch-and-bound correlative matcher (:mod:`tourbot.mapping.correlative`); a match
whose score passes the threshold is refined and attached to the submap node nearest the scan (scans
the front end fitted poorly are left out of the submaps and never anchor a closure: they may sit
askew in them); its covariance is a floor (how far a submap drawn at the graph's poses may be
off) plus the match's own, the inverse curvature of the matching objective on the submap around
the refined pose, within the searched window (the cost surface around the best match, Olson,
"Real-time correlative scan matching", ICRA 2009): a scan matched in a corridor pins the
corridor's cross-section, not where along it the robot is. A match alone is no closure: repeated
structure (a corridor, twin rooms) is matched with conviction somewhere else. It waits until another
match of the same pass agrees with it, and is refused if it contradicts a closure already accepted
in that pass (pairwise consistency, Olson, "Recognizing places using spectrally clustered local
matches", RAS 2009: two closures and the graph's two short chains between their scans and between
their anchors form a cycle that must close). Geometric consistency with the whole graph then decides
whether an agreeing group stays: optimised with GTSAM with the group's edges under the plain
quadratic cost, the total squared whitened error may grow by a chi-square quantile at most (no
optimisation is needed when the edges already fit the current poses that well); an accepted closure
keeps dynamic covariance scaling (DCS, :mod:`tourbot.mapping.pose_graph`) from then on, so that a
wrong one that slipped through cannot wreck the map.

People filtering (Sec. 5) stays in: with a :class:`~tourbot.mapping.people_filter.
PeopleFilteredMapper` as front end, the beams it leaves out as people are left out of the submaps,
the loop queries and the final map, which is drawn from every scan at the optimised poses.

Online use (a robot mapping while it tours): :meth:`GraphSlam.add_scan` per scan, :attr:`poses`
and :meth:`grid` at any time; offline: the same over a log, then :meth:`finish`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose, relative, transform_points, wrap_angle
from tourbot.mapping.correlative import Match, SearchWindow, Submap, refine, search
from tourbot.mapping.incremental import IncrementalMapper, MapperParams
from tourbot.mapping.people_filter import PeopleFilteredMapper, beam_endpoints
from tourbot.mapping.pose_graph import OptimizerParams, PoseGraph, edge_errors
from tourbot.mapping.scan_matching import curvature
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import Scan

__all__ = ["Closure", "GraphSlam", "GraphSlamParams"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class GraphSlamParams:
    """Parameters of graph SLAM (front end, submaps, loop closure, optimisation).

    A scan-matching edge's covariance is ``sm_scale`` times the inverse of the alignment's
    information (:attr:`~tourbot.mapping.incremental.MapperStep.information`): 3, the median
    squared Mahalanobis error of the front end's steps against the reference over its median
    for 3 degrees of freedom, 2.8-4.8 on the four logs (ACES 2.9, Intel 2.8, FHW 4.8, Freiburg
    079 2.9; leaving one log out, 2.9-3.4), as the curvature ignores that neighbouring beams
    and the map's own errors are not independent. The odometry edge (a scan that could not be
    aligned) has standard deviations ``odom_sigma_xy + odom_k_xy * |translation|`` (m) and
    ``odom_sigma_theta + odom_k_theta * |rotation|`` (rad); it also replaces a step whose
    departure from the odometry exceeds the chi-square quantile ``sm_gate`` (of 3 degrees of
    freedom, under the front end's odometry prior), loosened by that departure. A submap holds
    ``submap_scans`` scans. Every ``query_every``-th scan is searched in the finished submaps at least
    ``recent_path`` m back along the path whose centre is within reach of its pose; the window's
    half-widths grow from ``window_linear`` m and ``window_angular`` rad by ``window_k_linear`` m
    and ``window_k_angular`` rad per metre of path between the submap and the scan through the graph
    (an accepted closure counts ``closure_length`` m), capped at ``max_linear`` and ``max_angular``.
    ``min_score``: a match's mean likelihood (0-1) to be proposed; ``loop_sigma_*``: the loop
    edge's covariance floor (standard deviations), to which ``sm_scale`` times the match's
    inverse curvature is added; ``submap_quality``: scans whose fit quality (alignment objective
    over ``-sm_score_scale``) exceeds it stay out of the submaps. Two closures agree when their
    cycle closes within ``group_xy + group_k_xy * L`` m and ``group_theta + group_k_theta * L``
    rad (``L``: the path length of the cycle's two chains); closures are of one pass when their
    scans and their anchors are each within ``group_path`` m of path (the last ``group_recent``
    accepted ones are compared). ``gate``: the chi-square probability of the graph's consistency
    check (the total squared whitened error may grow by that quantile of ``3 * n`` degrees of
    freedom for a group of ``n``). ``recent_path`` (30 m) and the agreement's tolerances were
    chosen on Intel, ACES and FHW and checked on Freiburg 079 (``docs/results/loopclosure.md``).
    """

    mapper: MapperParams = field(default_factory=MapperParams)
    sm_scale: float = 3.0
    sm_gate: float = 0.999
    sm_score_scale: float = 40.0
    odom_sigma_xy: float = 0.1
    odom_k_xy: float = 0.3
    odom_sigma_theta: float = 0.1
    odom_k_theta: float = 0.3
    submap_scans: int = 30
    query_every: int = 3
    recent_path: float = 30.0
    loop_resolution: float = 0.05
    loop_sigma: float = 0.05
    loop_max_range: float = 15.0
    loop_points: int = 200
    min_score: float = 0.55
    window_linear: float = 1.0
    window_k_linear: float = 0.05
    max_linear: float = 6.0
    window_angular: float = 0.15
    window_k_angular: float = 0.005
    max_angular: float = 0.6
    loop_sigma_xy: float = 0.1
    closure_length: float = 1.0
    loop_sigma_theta: float = 0.02
    submap_quality: float = 5.0
    gate: float = 0.999
    group_path: float = 10.0
    group_recent: int = 10
    group_xy: float = 0.2
    group_k_xy: float = 0.01
    group_theta: float = 0.03
    group_k_theta: float = 0.001
    optimizer: OptimizerParams = field(default_factory=OptimizerParams)


@dataclass(frozen=True)
class Closure:
    """An accepted loop closure: scan ``node`` seen in the submap anchored at node ``anchor``;
    ``information``: its edge's (in the scan's frame; None: the floor ``loop_sigma_*`` alone)."""

    anchor: int
    node: int
    delta: tuple[float, float, float]
    score: float
    information: FloatArray | None = field(default=None, compare=False)


@dataclass
class _Submap:
    first: int
    last: int
    grid: Submap
    poses: list[FloatArray]  # the graph's poses of its nodes when it was built


class GraphSlam:
    """Builds a pose graph from scans and odometry, one scan at a time, and closes its loops."""

    def __init__(
        self,
        params: GraphSlamParams | None = None,
        start: FloatArray | None = None,
        people: PeopleFilteredMapper | None = None,
    ) -> None:
        self.params = params or GraphSlamParams()
        self.people = people
        self.front = (
            people.mapper if people is not None else IncrementalMapper(self.params.mapper, start=start)
        )
        self.graph = PoseGraph()
        self.closures: list[Closure] = []
        self.rejected = 0  # closures proposed and then rejected by the consistency gate
        self.proposed = 0
        self._quality: list[float] = []  # how poorly each scan fitted the front end's map (>= 1)
        self.jumps = 0  # aligned steps that departed from the odometry: odometry edges instead
        self.contradicted = 0  # matches refused for contradicting an accepted closure of the pass
        self._pending: list[Closure] = []  # verified matches waiting for one that agrees
        self._scans: list[Scan] = []
        self._front_poses: list[FloatArray] = []
        self._odom: list[FloatArray] = []
        self._along: list[float] = [0.0]  # path length travelled (front end) up to each node
        self._submaps: list[_Submap] = []
        self._processed = 0  # nodes whose people masks are known and that have been handled

    # ------------------------------------------------------------------------------------------
    @property
    def poses(self) -> FloatArray:
        """The graph's current pose of every scan so far, ``(N, 3)``."""
        return self.graph.array()

    def add_scan(self, scan: Scan) -> FloatArray:
        """Align ``scan`` (front end), add its node and edges; try loop closures; its pose now."""
        quality = 1.0
        if self.people is not None:
            front = np.asarray(self.people.add_scan(scan), dtype=np.float64)
        else:
            front = np.asarray(self.front.add_scan(scan).pose, dtype=np.float64)
        done = self.front.last
        assert done is not None
        matched = done.score != 0.0  # too few beams to align: the odometry's prediction
        if self.people is None:
            quality = max(1.0, -done.score / self.params.sm_score_scale)
        odom = np.asarray(scan.odom, dtype=np.float64)
        n = len(self._scans)
        if n == 0:
            self.graph.add_node(front)
        else:
            prev = self.graph.poses[-1]
            step = relative(self._front_poses[-1], front)
            odo = relative(self._odom[-1], odom)
            if matched and not self._departs(step, odo):
                info = _in_frame(done.information, float(front[2])) / self.params.sm_scale
                self.graph.add_node(compose(prev, step))
                self.graph.add_edge(n - 1, n, step, info)
            else:
                info = self._odometry_information(odo)
                if matched:  # the scan snapped away from the odometry: which was right is open
                    self.jumps += 1
                    d = relative(odo, step)
                    info = np.asarray(np.linalg.inv(np.linalg.inv(info) + np.outer(d, d)), dtype=np.float64)
                self.graph.add_node(compose(prev, odo))
                self.graph.add_edge(n - 1, n, odo, info)
            self._along.append(self._along[-1] + float(np.hypot(step[0], step[1])))
        self._scans.append(scan)
        self._quality.append(quality)
        self._front_poses.append(front)
        self._odom.append(odom)
        self._process(final=False)
        return self.graph.poses[-1].copy()

    def finish(self) -> FloatArray:
        """Handle the scans still waiting (people filter) and optimise a last time; the poses."""
        if self.people is not None:
            self.people.finish()
        self._process(final=True)
        if len(self.graph.poses) > 1:
            self.graph.optimize(self.params.optimizer)
        return self.poses

    def left_out(self, index: int) -> NDArray[np.bool_]:
        """The beams of scan ``index`` left out as people (none without the people filter)."""
        if self.people is not None and index < len(self.people.left_out):
            return np.asarray(self.people.left_out[index], dtype=bool)
        return np.zeros(self._scans[index].geometry.num_beams, bool)

    def grid(self) -> OccupancyGrid:
        """The map of every scan so far at the graph's poses (people's beams left out)."""
        first = self.graph.poses[0] if self.graph.poses else None
        out = IncrementalMapper(self.params.mapper, start=first)
        keep_free = self.people is not None and self.people.params.beams.keep_free_space
        for k, (scan, pose) in enumerate(zip(self._scans, self.graph.poses, strict=True)):
            person = self.left_out(k)
            if keep_free:
                out.integrate(scan, pose, free_only=person, into="map")
            else:
                out.integrate(scan, pose, keep=~person, into="map")
        return out.grid()

    # ------------------------------------------------------------------------------------------
    def _departs(self, step: FloatArray, odo: FloatArray) -> bool:
        """Whether the front end's ``step`` departs from the odometry's ``odo`` by more than the
        front end's own odometry prior allows (its squared whitened difference beyond the
        chi-square quantile ``sm_gate`` of 3 degrees of freedom): a scan snapped onto an old,
        drifted part of the map it aligns against, an implicit loop closure, not a motion."""
        from scipy.stats import chi2

        m = self.params.mapper.match
        trans = float(np.hypot(odo[0], odo[1]))
        rot = abs(float(wrap_angle(odo[2])))
        sxy = m.sigma_xy + m.k_xy * trans
        sth = m.sigma_theta + m.k_theta * rot + m.k_theta_xy * trans
        d = relative(odo, step)
        whitened = (d[0] ** 2 + d[1] ** 2) / sxy**2 + float(wrap_angle(d[2])) ** 2 / sth**2
        return bool(whitened > chi2.ppf(self.params.sm_gate, 3))

    def _odometry_information(self, step: FloatArray) -> FloatArray:
        p = self.params
        trans = float(np.hypot(step[0], step[1]))
        rot = abs(float(wrap_angle(step[2])))
        sxy, sth = p.odom_sigma_xy + p.odom_k_xy * trans, p.odom_sigma_theta + p.odom_k_theta * rot
        return np.diag([1.0 / sxy**2, 1.0 / sxy**2, 1.0 / sth**2])

    def _loop_information(
        self, sub: _Submap, pts: FloatArray, pose: FloatArray, window: SearchWindow
    ) -> FloatArray:
        """The information of a loop edge (in the frame of the scan at ``pose``, the submap's
        frame): the inverse of the floor ``loop_sigma_*`` plus ``sm_scale`` times the inverse of
        the match's curvature on the submap (the window, as a uniform prior over it, bounding it
        where the submap does not)."""
        p = self.params
        grid = sub.grid
        origin = np.array([grid.origin[0], grid.origin[1], 0.0])
        res = grid.resolution
        reach = max(float(np.median(np.hypot(pts[:, 0], pts[:, 1]))), res)
        weight = p.mapper.match.beam_weight
        info = curvature(
            grid.grid, res, pose - origin, pts, np.full(len(pts), weight), p.mapper.match.eps,
            np.array([res, res, res / reach]),
        )  # fmt: skip
        info = info + np.diag([3.0 / window.linear**2, 3.0 / window.linear**2, 3.0 / window.angular**2])
        floor = np.diag([p.loop_sigma_xy**2, p.loop_sigma_xy**2, p.loop_sigma_theta**2])
        cov = floor + p.sm_scale * _in_frame(
            np.asarray(np.linalg.inv(info), dtype=np.float64), float(pose[2])
        )
        return np.asarray(np.linalg.inv(cov), dtype=np.float64)

    def _ready(self) -> int:
        """How many nodes have known people masks."""
        if self.people is None:
            return len(self._scans)
        return min(len(self.people.left_out), len(self._scans))

    def _process(self, *, final: bool) -> None:
        p = self.params
        ready = self._ready()
        while self._processed < ready:
            k = self._processed
            self._processed += 1
            first = self._submaps[-1].last + 1 if self._submaps else 0
            if k - first + 1 >= p.submap_scans:
                self._submaps.append(self._build_submap(first, k))
            if k % p.query_every == 0:
                self._query(k)
        if final:
            first = self._submaps[-1].last + 1 if self._submaps else 0
            if first < len(self._scans):
                self._submaps.append(self._build_submap(first, len(self._scans) - 1))

    def _points(self, k: int, cap: float) -> FloatArray:
        """Scan ``k``'s returned beams not left out, within ``cap`` m, in the robot frame."""
        scan = self._scans[k]
        pts, hit = beam_endpoints(scan, np.zeros(3))
        r = np.asarray(scan.ranges, dtype=np.float64)
        return pts[hit & ~self.left_out(k) & (r < cap)]

    def _build_submap(self, first: int, last: int) -> _Submap:
        anchor = self.graph.poses[first]
        # a scan the front end fitted poorly may sit askew in the submap: left out of its picture
        pts = [
            transform_points(
                relative(anchor, self.graph.poses[k]), self._points(k, self.params.mapper.max_match_range)
            )
            for k in range(first, last + 1)
            if self._quality[k] <= self.params.submap_quality
        ]
        allp = np.concatenate([np.zeros((0, 2)), *pts])
        if len(allp) == 0:
            allp = np.zeros((1, 2))
        grid = Submap(allp, self.params.loop_resolution, self.params.loop_sigma)
        return _Submap(first, last, grid, [q.copy() for q in self.graph.poses[first : last + 1]])

    def _query(self, k: int) -> bool:
        """Search scan ``k`` in the finished submaps it may be back in; True when a closure was added."""
        p = self.params
        pts = self._points(k, p.loop_max_range)
        if len(pts) < 20:
            return False
        if len(pts) > p.loop_points:
            pts = pts[np.linspace(0, len(pts) - 1, p.loop_points).astype(np.int64)]
        apart = self._graph_distances(k)
        pose_k = self.graph.poses[k]
        best: tuple[Match, _Submap, SearchWindow] | None = None
        for sub in self._submaps:
            if self._along[k] - self._along[sub.last] < p.recent_path:
                continue
            since = float(apart[sub.first : sub.last + 1].min())
            linear = min(p.max_linear, p.window_linear + p.window_k_linear * since)
            angular = min(p.max_angular, p.window_angular + p.window_k_angular * since)
            anchor = self.graph.poses[sub.first]
            guess = relative(anchor, pose_k)
            if math.hypot(*(guess[:2] - sub.grid.centre)) > sub.grid.radius + linear:
                continue
            window = SearchWindow(linear, angular)
            m = search(sub.grid, pts, guess, window, p.min_score)
            if m is None or (best is not None and m.score <= best[0].score):
                continue
            best = (m, sub, window)
        if best is None:
            return False
        m, sub, window = best
        found = refine(sub.grid, pts, m.pose)
        info = self._loop_information(sub, pts, found, window)
        # the edge goes to the submap's node nearest the scan: the submap's inside as it was
        # built, seen from that node, so that the graph moving the anchor later bends it less
        inside = [relative(sub.poses[0], q) for q in sub.poses]
        far = [
            math.inf if self._quality[sub.first + i] > p.submap_quality else math.hypot(*(q[:2] - found[:2]))
            for i, q in enumerate(inside)
        ]
        near = int(np.argmin(far)) if min(far) < math.inf else 0
        return self.propose_closure(sub.first + near, k, relative(inside[near], found), m.score, info)

    def _graph_distances(self, k: int) -> FloatArray:
        """Path length (m) from node ``k`` to every node through the graph, loop edges counting
        ``closure_length``: how far the relative pose of two nodes has been chained, which sets
        how uncertain it is."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import dijkstra

        n = len(self.graph.poses)
        along = np.asarray(self._along[:n])
        i = np.array([e.i for e in self.graph.edges], dtype=np.int64)
        j = np.array([e.j for e in self.graph.edges], dtype=np.int64)
        robust = np.array([e.robust for e in self.graph.edges], dtype=bool)
        w = np.where(robust, self.params.closure_length, np.abs(along[j] - along[i]) + 1e-6)
        m = coo_matrix((w, (i, j)), shape=(n, n)).tocsr()
        return np.asarray(dijkstra(m, directed=False, indices=k), dtype=np.float64)

    def propose_closure(
        self, anchor: int, node: int, delta: FloatArray, score: float, information: FloatArray | None = None
    ) -> bool:
        """A verified match of scan ``node`` in the submap at node ``anchor``: kept as a candidate
        until another candidate (or an accepted closure) of the same pass agrees with it
        (:meth:`_agree`); a group that agrees is then added if the graph can take it
        (:meth:`add_closures`). True when this candidate's closure was added. ``information``:
        the edge's (in the scan's frame; the floor ``loop_sigma_*`` alone when not given)."""
        p = self.params
        self.proposed += 1
        d = np.asarray(delta, dtype=np.float64)
        cand = Closure(anchor, node, (float(d[0]), float(d[1]), float(d[2])), float(score), information)
        along = self._along
        self._pending = [c for c in self._pending if along[node] - along[c.node] <= p.group_path]

        def near(c: Closure) -> bool:
            return (
                along[node] - along[c.node] <= p.group_path
                and abs(along[c.anchor] - along[anchor]) <= p.group_path
            )

        accepted = [c for c in self.closures[-p.group_recent :] if near(c)]
        if not all(self._agree(c, cand) for c in accepted):
            self.contradicted += 1  # it contradicts a closure of the same pass
            return False
        agree = accepted + [c for c in self._pending if near(c) and self._agree(c, cand)]
        if not agree:
            self._pending.append(cand)
            return False
        group = [cand, *(c for c in agree if c in self._pending)]
        self._pending = [c for c in self._pending if c not in group]
        return self.add_closures(group)

    def _agree(self, a: Closure, b: Closure) -> bool:
        """Pairwise consistency (Olson 2009): two closures of one pass agree when the cycle they
        make with the graph's two short chains between their scans and between their anchors
        closes within ``group_xy + group_k_xy * L`` m and ``group_theta + group_k_theta * L`` rad,
        ``L`` the two chains' path length: a place that only looks like the one it is matched
        to (a corridor, a twin room) is matched with offsets that differ from scan to scan."""
        p = self.params
        x = self.graph.poses
        # scan b in anchor a's frame: through closure a then the chain a.node -> b.node, or
        # through the chain a.anchor -> b.anchor then closure b
        one = compose(np.asarray(a.delta), relative(x[a.node], x[b.node]))
        two = compose(relative(x[a.anchor], x[b.anchor]), np.asarray(b.delta))
        err = relative(one, two)
        length = abs(self._along[b.node] - self._along[a.node]) + abs(
            self._along[b.anchor] - self._along[a.anchor]
        )
        return bool(
            math.hypot(err[0], err[1]) <= p.group_xy + p.group_k_xy * length
            and abs(float(wrap_angle(err[2]))) <= p.group_theta + p.group_k_theta * length
        )

    def add_closures(self, group: list[Closure]) -> bool:
        """Add the loop edges of ``group`` if the graph can take them: optimised with them (plain
        quadratic cost), the total squared whitened error may grow by at most the chi-square
        quantile ``gate`` of ``3 * len(group)`` degrees of freedom (a group that contradicts the
        chain's uncertainty is rejected); accepted edges keep dynamic covariance scaling from then
        on. When the new edges' own error at the current poses is already within the gate, the
        growth is too (the current poses bound the optimum) and no optimisation is run."""
        from scipy.stats import chi2

        p = self.params
        limit = float(chi2.ppf(p.gate, 3 * len(group)))
        floor = np.diag([p.loop_sigma_xy**-2, p.loop_sigma_xy**-2, p.loop_sigma_theta**-2])
        edges = [
            self.graph.add_edge(
                c.anchor, c.node, np.asarray(c.delta), floor if c.information is None else c.information
            )
            for c in group
        ]
        current = self.graph.array()
        own = float(edge_errors(current, edges).sum())
        if own > limit:
            before = [q.copy() for q in self.graph.poses]
            cost_before = float(edge_errors(current, self.graph.edges[: -len(edges)]).sum())
            poses = self.graph.optimize(p.optimizer)
            grown = float(edge_errors(poses, self.graph.edges).sum()) - cost_before
            if grown > limit:
                del self.graph.edges[-len(edges) :]
                self.graph.poses = before
                self.rejected += len(group)
                return False
        del self.graph.edges[-len(edges) :]
        self.graph.edges.extend(replace(e, robust=True) for e in edges)
        self.closures.extend(group)
        return True


def _in_frame(matrix: FloatArray, heading: float) -> FloatArray:
    """A ``(3, 3)`` information or covariance of a pose in the world's ``x, y, theta`` expressed
    in the pose's own frame (its heading ``heading``): the frame of a pose-graph edge's error."""
    c, s = math.cos(heading), math.sin(heading)
    a = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    return np.asarray(a @ matrix @ a.T, dtype=np.float64)
