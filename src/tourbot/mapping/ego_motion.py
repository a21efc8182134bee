"""The robot's own motion from its scans, for recordings without odometry (Burgard et al. Sec. 2.1, 4).

The tracker needs the robot's pose at every scan: features are put in the world frame through it,
and the static filter (Fig. 6) compares occupancy grids of consecutive scans *in the world frame*.
A bag without odometry or tf (the ``leg_tracker`` bags) gives none, and a robot driving through
a room then makes every chair leg seem to walk. :class:`ScanMatchedPoses` recovers the poses with
the incremental scan-to-map matcher of the mapping part (:class:`~tourbot.mapping.incremental.
IncrementalMapper`, Eq. 1-2), the odometry prior replaced by a constant-velocity prediction with a
wider spread; the map it builds on the fly is also the static world: a feature on a cell that
earlier scans already saw occupied several times is furniture, not a person who just arrived.

A robot with several lasers and no odometry (``negative_2.bag``: left, rear and right, 270 degrees
each, no tf) is matched on one map from all of them: the scans of one frame (one of each laser, a
few hundredths of a second apart) align together as one scan all around the robot, each moved by
its laser's mount (:mod:`tourbot.mapping.mounts`) and the robot's motion over the time between
them. Whether each laser alone, and all lasers but one, find the same path
(:func:`laser_agreement`: on one rigid robot they must) is the check that says how far the path
can be trusted.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose, interpolate_poses, invert, relative
from tourbot.mapping.incremental import IncrementalMapper, MapperParams
from tourbot.mapping.scan_matching import MatchParams
from tourbot.records import Scan

__all__ = [
    "EgoMotionConfig",
    "LaserPath",
    "ScanMatchedPoses",
    "laser_agreement",
    "path_disagreement",
    "path_length",
]

FloatArray = NDArray[np.float64]


def _no_odometry_mapper() -> MapperParams:
    # Without odometry the prior is a constant-velocity guess with 10 cm and 0.08 rad of spread
    # (plus the mapper's share of the motion) instead of the odometry prior's 5 cm and 0.02 rad;
    # a wider prior (25 cm was tried on negative_2.bag) lets the match jump to wrong optima.
    # Every beam and the full hill climbing at every level (not the mapper's faster defaults): a
    # pose error here is a static object seen moving, and there is no odometry to fall back on.
    # unknown_level and window as when this was measured on the leg_tracker bags (the mapping
    # defaults changed for the odometry logs' front end, issue 20). The match is climbed again from
    # the prediction on the two finer levels and the better fit on the finest map kept: on the
    # parallel shelves of negative_2.bag the coarsest level (0.25 m) pulled a scan one aisle over,
    # steps of 4-6 m/s, which the finest map scores far worse than the prediction.
    return MapperParams(
        match=MatchParams(sigma_xy=0.1, sigma_theta=0.08),
        match_beams=None,
        level_halvings=None,
        unknown_level=0.25,
        window=150,
        prior_restart=1,
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
    so are scans that no longer fit the map: the median over the last ``score_window`` scans (with
    several lasers: frames, all their returns together) of the log likelihood per beam on the map
    below ``min_match_score`` (-0.8: scans of a standing laser among walking people score -0.04 to
    -0.65 per beam, the scans of a museum tour matched without odometry, 4 s apart, that lost their
    way, -1.1 to -1.7; measured when the score still held the prior's term, which made it slightly
    lower)."""

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

    ``companions``: the scans of the robot's other lasers, each with its mount on the robot as its
    geometry's offset (:func:`tourbot.mapping.mounts.mount_lasers`). Those taken since the last
    scan given to :meth:`match` join it in one frame: their returns, each moved to the robot's
    frame at the time of that scan (the mount, and the robot's motion at its last velocity over the
    time between the two scans), align with it as one scan all around the robot, and
    :meth:`integrate` writes each at its own time (but for the beams on the people). One robot
    path and one map from all lasers: lasers that see different sides of the robot, matched one
    by one, would each fit mostly its own earlier scans and drift apart by centimetres.
    """

    def __init__(self, config: EgoMotionConfig | None = None, companions: Sequence[Scan] = ()) -> None:
        self.config = config or EgoMotionConfig()
        self.mapper = IncrementalMapper(self.config.mapper)
        self._odom = np.zeros(3)  # the "odometry" handed to the mapper
        self._poses: list[FloatArray] = []  # the last two matched poses
        self._time: float | None = None
        self._dt = 0.0
        self.last_score = 0.0  # the match's score (log likelihood of the frame on the map)
        self._scores: deque[float] = deque(maxlen=self.config.score_window)  # frames, per beam
        self._fits: dict[str, tuple[float, int]] = {}  # per laser: sum of the fits per beam, frames
        self.times: list[float] = []  # of every matched scan, parallel to ``mapper.poses``
        self._companions = sorted(companions, key=lambda s: s.timestamp)
        self._next_companion = 0
        self._frame: list[tuple[Scan, FloatArray]] = []  # the last match's scans, each's shift
        res = self.config.mapper.resolution
        n = max(int(self.config.static_radius / res), 0)
        k = np.arange(-n, n + 1) * res
        self._offsets = np.stack(np.meshgrid(k, k), -1).reshape(-1, 2)

    def match(self, scan: Scan) -> FloatArray:
        """The robot's pose at ``scan`` (with the companion scans taken since the last one) aligned
        to the map so far, from a constant-velocity prediction; the map is unchanged."""
        # The mapper predicts pose_{k-1} + (odom_k - odom_{k-1}): the "odometry" handed to it
        # makes that the previous step's motion (constant velocity), capped at what the robot can
        # do in the time between the scans (a wrong step must not be extrapolated into a worse one).
        cfg = self.config
        dt = 0.0 if self._time is None else max(scan.timestamp - self._time, 0.0)
        velocity = np.zeros(3)  # the last step's, per second, in the robot's frame
        if len(self._poses) >= 2 and self._dt > 0.0:
            velocity = relative(self._poses[-2], self._poses[-1]) / self._dt
        speed = math.hypot(velocity[0], velocity[1])
        if speed > cfg.max_speed:
            velocity[:2] *= cfg.max_speed / speed
        velocity[2] = float(np.clip(velocity[2], -cfg.max_turn_rate, cfg.max_turn_rate))
        step = velocity * min(dt, 2.0 * self._dt) if self._dt > 0.0 else np.zeros(3)
        self._odom = compose(self._odom, step)
        frame = [(scan, np.zeros(3))]
        while (
            self._next_companion < len(self._companions)
            and self._companions[self._next_companion].timestamp <= scan.timestamp
        ):
            other = self._companions[self._next_companion]
            self._next_companion += 1
            frame.append((other, velocity * (other.timestamp - scan.timestamp)))
        parts = [self._returns(s, shift) for s, shift in frame]
        aligned = self.mapper.match_points(
            np.concatenate(parts), np.ones(sum(len(p) for p in parts)), self._odom
        )
        pose = np.asarray(aligned.pose, dtype=np.float64)
        self.last_score = aligned.score
        if self.times:  # the first scan is not matched
            scores = [self.mapper.score_points(pts, pose) for pts in parts]
            self._scores.append(sum(scores) / max(sum(len(pts) for pts in parts), 1))
            for (s, _), pts, fit in zip(frame, parts, scores, strict=True):
                total, n = self._fits.get(s.sensor, (0.0, 0))
                self._fits[s.sensor] = (total + fit / max(len(pts), 1), n + 1)
        self._frame = frame
        self._dt = dt
        self._time = scan.timestamp
        self._poses = [*self._poses[-1:], pose]
        self.times.append(scan.timestamp)
        return pose

    def _returns(self, scan: Scan, shift: FloatArray) -> FloatArray:
        """The endpoints ``(N, 2)`` of the beams of ``scan`` that align it, in the robot's frame
        at the frame's time (``shift``: the robot's pose at the scan's time in that frame)."""
        g = scan.geometry
        r = np.asarray(scan.ranges, dtype=np.float64)
        ok = (
            self._far(scan) & (r < g.max_range) & (r > g.min_range) & (r < self.config.mapper.max_match_range)
        )
        laser = compose(shift, np.asarray(g.offset, dtype=np.float64))
        a = g.angles[ok] + laser[2]
        return np.stack([laser[0] + r[ok] * np.cos(a), laser[1] + r[ok] * np.sin(a)], axis=-1)

    def mean_fit(self) -> dict[str, float]:
        """Per laser, the mean over the matched frames of the log likelihood per beam of its scan
        on the map built so far (higher is better; the map's self-consistency)."""
        return {name: total / n for name, (total, n) in self._fits.items()}

    def path(self) -> tuple[FloatArray, FloatArray]:
        """The times ``(N,)`` and matched robot poses ``(N, 3)`` of every scan given to :meth:`match`."""
        return np.array(self.times, dtype=np.float64), np.array(self.mapper.poses, dtype=np.float64).reshape(
            -1, 3
        )

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
        dt = self._dt
        step = relative(self._poses[-2], self._poses[-1])
        speed = math.hypot(step[0], step[1]) / dt
        turn = abs(float(step[2])) / dt
        if speed > cfg.plausible_speed:
            return f"a step of {speed:.1f} m/s (at most {cfg.plausible_speed:g} m/s is plausible)"
        if turn > cfg.plausible_turn_rate:
            return f"a turn of {turn:.1f} rad/s (at most {cfg.plausible_turn_rate:g} rad/s is plausible)"
        return None

    def integrate(self, scan: Scan, pose: FloatArray, people: FloatArray | None = None) -> None:
        """Write ``scan`` into the map at ``pose`` (its :meth:`match` result), with the companion
        scans of its frame each at its own time, but for the beams that end within
        ``person_radius`` of one of ``people`` ``(P, 2)`` (world frame): a person is no part of the
        static world (Burgard et al. Sec. 5)."""
        frame = self._frame if self._frame and self._frame[0][0] is scan else [(scan, np.zeros(3))]
        for s, shift in frame:
            at = compose(np.asarray(pose, dtype=np.float64), shift)
            keep = self._far(s)
            if people is not None and len(people):
                g = s.geometry
                sensor = compose(at, np.asarray(g.offset, dtype=np.float64))
                r = np.asarray(s.ranges, dtype=np.float64)
                a = g.angles + sensor[2]
                ends = np.stack([sensor[0] + r * np.cos(a), sensor[1] + r * np.sin(a)], -1)
                d = np.linalg.norm(ends[:, None, :] - people[None, :, :], axis=-1).min(axis=1)
                keep = keep & ~(d <= self.config.person_radius)
            self.mapper.integrate(s, at, keep=keep)

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


@dataclass(frozen=True)
class LaserPath:
    """The path of some of the robot's lasers matched without the others (``lasers``), against the
    path of all of them on one map: its length (m), the robot's position off the shared path
    (median and worst, m, the world frames aligned at the first scan), the worst heading off it
    (rad), how many of its scans failed the check and its mean fit per beam
    (:meth:`ScanMatchedPoses.mean_fit`, over its lasers)."""

    lasers: tuple[str, ...]
    length: float
    median_off: float
    max_off: float
    max_heading_off: float
    implausible: int
    fit: float


def path_length(poses: FloatArray) -> float:
    """The length (m) of a path of poses ``(N, 3)``."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    return float(np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1).sum())


def path_disagreement(
    times: FloatArray, poses: FloatArray, ref_times: FloatArray, ref_poses: FloatArray
) -> tuple[float, float, float]:
    """How far the robot path ``poses`` at ``times`` is from ``ref_poses`` (interpolated at the
    same times), both of the same robot frame, each world frame aligned on the first pose: the
    median and the largest distance (m) and the largest heading difference (rad). Two lasers on
    one rigid robot, each matched alone, give the same path when both are right."""
    ref = interpolate_poses(np.asarray(ref_times), np.asarray(ref_poses), np.asarray(times))
    p = np.asarray(poses, dtype=np.float64)
    align = compose(ref[0], invert(p[0]))
    err = relative(ref, compose(np.broadcast_to(align, p.shape), p))
    off = np.hypot(err[:, 0], err[:, 1])
    return float(np.median(off)), float(off.max()), float(np.abs(err[:, 2]).max())


def laser_agreement(
    streams: Mapping[str, Sequence[Scan]],
    shared: tuple[FloatArray, FloatArray],
    config: EgoMotionConfig | None = None,
) -> list[LaserPath]:
    """The rigid-body check of a robot's lasers (each with its mount on the robot as its geometry's
    offset; the first laser of ``streams`` is the one whose scans time the path): each laser matched
    alone and, with three lasers or more, all but one on one map, each path set against the
    ``shared`` path ``(times, poses)`` of all of them. Lasers on one robot that are matched right
    give one path; a laser alone that is far off it was wrong, and subsets that agree with each
    other say the shared path does not hang on any one laser."""
    names = list(streams)
    subsets: list[tuple[str, ...]] = [(n,) for n in names]
    if len(names) >= 3:
        subsets += [tuple(n for n in names if n != left_out) for left_out in names]
    out: list[LaserPath] = []
    for lasers in subsets:
        ego = ScanMatchedPoses(config, companions=[s for n in lasers[1:] for s in streams[n]])
        bad = 0
        for scan in streams[lasers[0]]:
            pose = ego.match(scan)
            bad += ego.implausible() is not None
            ego.integrate(scan, pose)
        times, poses = ego.path()
        median, worst, heading = path_disagreement(times, poses, *shared)
        fit = float(np.mean(list(ego.mean_fit().values()))) if ego.mean_fit() else float("nan")
        out.append(LaserPath(lasers, path_length(poses), median, worst, heading, bad, fit))
    return out
