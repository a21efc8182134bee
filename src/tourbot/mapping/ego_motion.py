"""The robot's own motion from its scans, for recordings without odometry (Burgard et al. Sec. 2.1, 4).

The tracker needs the robot's pose at every scan: features are put in the world frame through it,
and the static filter (Fig. 6) compares occupancy grids of consecutive scans *in the world frame*.
A bag without odometry or tf (the ``leg_tracker`` bags) gives none, and a robot driving through
a room then makes every chair leg seem to walk. :class:`ScanMatchedPoses` recovers the poses with
the incremental scan-to-map matcher of the mapping part (:class:`~tourbot.mapping.incremental.
IncrementalMapper`, Eq. 1-2), the odometry prior replaced by a constant-velocity prediction with a
wider spread; the map it builds on the fly is also the static world: a feature on a cell that
earlier scans already saw occupied several times is furniture, not a person who just arrived.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose, relative
from tourbot.mapping.incremental import IncrementalMapper, MapperParams
from tourbot.mapping.scan_matching import MatchParams
from tourbot.records import Scan

__all__ = ["EgoMotionConfig", "ScanMatchedPoses"]

FloatArray = NDArray[np.float64]


def _no_odometry_mapper() -> MapperParams:
    # Without odometry the prior is a constant-velocity guess with 10 cm and 0.08 rad of spread
    # (plus the mapper's share of the motion) instead of the odometry prior's 5 cm and 0.02 rad;
    # a wider prior (25 cm was tried on negative_2.bag) lets the match jump to wrong optima.
    # Every beam and the full hill climbing at every level (not the mapper's faster defaults): a
    # pose error here is a static object seen moving, and there is no odometry to fall back on.
    # unknown_level and window as when this was measured on the leg_tracker bags (the mapping
    # defaults changed for the odometry logs' front end, issue 20)
    return MapperParams(
        match=MatchParams(sigma_xy=0.1, sigma_theta=0.08),
        match_beams=None,
        level_halvings=None,
        unknown_level=0.25,
        window=150,
    )


@dataclass(frozen=True)
class EgoMotionConfig:
    """``mapper``: the incremental mapper's parameters (the constant-velocity prior above).
    ``static_log_odds``: a feature is on the map built so far when some cell within
    ``static_radius`` (m) of it holds at least this log-odds of occupancy from earlier scans
    (2.5: three hits of the inverse sensor model's p = 0.7 with no miss, about 0.4 s at 7.5 Hz).
    ``max_speed`` (m/s) and ``max_turn_rate`` (rad/s) cap the constant-velocity prediction.
    Beams shorter than ``near_range`` (m) neither align nor enter the map: the robot's own body
    (seen at the edges of a wide field of view) would leave a trail of obstacles along its path.
    Beams ending within ``person_radius`` (m) of a person being tracked stay out of the map too.
    A matched step faster than ``plausible_speed`` (m/s) or turning faster than
    ``plausible_turn_rate`` (rad/s) is not a robot's motion: the match has jumped to a wrong
    optimum (:meth:`ScanMatchedPoses.implausible`), and the poses cannot be trusted from there on;
    so are scans that no longer fit the map: the median over the last ``score_window`` scans of the
    match's log likelihood per beam below ``min_match_score`` (-0.8: scans of a standing laser among
    walking people score -0.04 to -0.65 per beam, the scans of a museum tour matched without
    odometry, 4 s apart, that lost their way, -1.1 to -1.7)."""

    mapper: MapperParams = field(default_factory=_no_odometry_mapper)
    static_log_odds: float = 2.5
    static_radius: float = 0.1
    max_speed: float = 1.0
    near_range: float = 1.0
    max_turn_rate: float = 1.5
    person_radius: float = 0.3
    plausible_speed: float = 1.5
    plausible_turn_rate: float = 3.0
    min_match_score: float = -0.8
    score_window: int = 10


class ScanMatchedPoses:
    """Robot poses by scan-to-map matching, and the static world as the map built on the fly.

    Per scan, in this order: :meth:`match` (the pose of the scan, the map unchanged), then
    :meth:`on_map` for the features of that scan, then :meth:`integrate` (the scan enters the map).
    The first scan's pose is the origin of the world frame.
    """

    def __init__(self, config: EgoMotionConfig | None = None) -> None:
        self.config = config or EgoMotionConfig()
        self.mapper = IncrementalMapper(self.config.mapper)
        self._odom = np.zeros(3)  # the "odometry" handed to the mapper
        self._poses: list[FloatArray] = []
        self._time: float | None = None
        self._dt = 0.0
        self.last_score = 0.0  # the match's score (log likelihood of the scan on the map)
        self._scores: deque[float] = deque(maxlen=self.config.score_window)  # per beam
        res = self.config.mapper.resolution
        n = max(int(self.config.static_radius / res), 0)
        k = np.arange(-n, n + 1) * res
        self._offsets = np.stack(np.meshgrid(k, k), -1).reshape(-1, 2)

    def match(self, scan: Scan) -> FloatArray:
        """The pose of ``scan`` aligned to the map so far, from a constant-velocity prediction."""
        # The mapper predicts pose_{k-1} + (odom_k - odom_{k-1}): the "odometry" handed to it
        # makes that the previous step's motion (constant velocity), capped at what the robot can
        # do in the time between the scans (a wrong step must not be extrapolated into a worse one).
        cfg = self.config
        dt = 0.0 if self._time is None else max(scan.timestamp - self._time, 0.0)
        step = np.zeros(3)
        if len(self._poses) >= 2 and self._dt > 0.0:
            step = relative(self._poses[-2], self._poses[-1]) * min(dt / self._dt, 2.0)
        reach = math.hypot(step[0], step[1])
        if reach > cfg.max_speed * dt:
            step[:2] *= cfg.max_speed * dt / reach
        step[2] = float(np.clip(step[2], -cfg.max_turn_rate * dt, cfg.max_turn_rate * dt))
        odom = compose(self._odom, step)
        self._odom = odom
        fake = dataclasses.replace(scan, odom=(float(odom[0]), float(odom[1]), float(odom[2])))
        aligned = self.mapper.match(fake, match_weights=self._far(scan).astype(np.float64))
        self.last_score = aligned.score
        beams = int(np.count_nonzero(self._far(scan) & (np.asarray(scan.ranges) < scan.geometry.max_range)))
        if len(self._poses):  # the first scan is not matched
            self._scores.append(aligned.score / max(beams, 1))
        pose = np.asarray(aligned.pose, dtype=np.float64)
        self._dt = dt
        self._time = scan.timestamp
        self._poses = [*self._poses[-1:], pose]
        return pose

    def implausible(self) -> str | None:
        """Why the last matched step cannot be the robot's motion (too fast a step or turn for the
        time between the scans), or the recent scans no longer fit the map; None when all is well."""
        cfg = self.config
        if len(self._scores) == cfg.score_window:
            score = float(np.median(self._scores))
            if score < cfg.min_match_score:
                return (
                    f"the last {cfg.score_window} scans fit the map with a median log likelihood of "
                    f"{score:.2f} per beam (at least {cfg.min_match_score:g} is consistent)"
                )
        if len(self._poses) < 2 or self._dt <= 0.0:
            return None
        step = relative(self._poses[-2], self._poses[-1])
        speed = math.hypot(step[0], step[1]) / self._dt
        turn = abs(float(step[2])) / self._dt
        if speed > cfg.plausible_speed:
            return f"a step of {speed:.1f} m/s (at most {cfg.plausible_speed:g} m/s is plausible)"
        if turn > cfg.plausible_turn_rate:
            return f"a turn of {turn:.1f} rad/s (at most {cfg.plausible_turn_rate:g} rad/s is plausible)"
        return None

    def integrate(self, scan: Scan, pose: FloatArray, people: FloatArray | None = None) -> None:
        """Write ``scan`` into the map at ``pose`` (its :meth:`match` result), but for the beams
        that end within ``person_radius`` of one of ``people`` ``(P, 2)`` (world frame): a person
        is no part of the static world (Burgard et al. Sec. 5)."""
        keep = self._far(scan)
        if people is not None and len(people):
            g = scan.geometry
            sensor = compose(pose, np.asarray(g.offset, dtype=np.float64))
            r = np.asarray(scan.ranges, dtype=np.float64)
            a = g.angles + sensor[2]
            ends = np.stack([sensor[0] + r * np.cos(a), sensor[1] + r * np.sin(a)], -1)
            d = np.linalg.norm(ends[:, None, :] - people[None, :, :], axis=-1).min(axis=1)
            keep = keep & ~(d <= self.config.person_radius)
        self.mapper.integrate(scan, pose, keep=keep)

    def _far(self, scan: Scan) -> NDArray[np.bool_]:
        """Beams beyond ``near_range``: the nearer ones see the robot's own body, which moves along."""
        return np.asarray(np.asarray(scan.ranges, dtype=np.float64) >= self.config.near_range)

    def on_map(self, world_points: FloatArray) -> NDArray[np.bool_]:
        """Whether each point ``(M, 2)`` lies on the static map built from the earlier scans."""
        pts = np.asarray(world_points, dtype=np.float64).reshape(-1, 2)
        if pts.shape[0] == 0:
            return np.zeros(0, dtype=bool)
        around = (pts[:, None, :] + self._offsets[None, :, :]).reshape(-1, 2)
        evidence = self.mapper.evidence(around).reshape(pts.shape[0], -1).max(axis=1)
        return np.asarray(evidence >= self.config.static_log_odds)
