"""Where each laser of a robot with several sits on it, from the scans themselves (no tf).

A robot with lasers on several sides (the ``leg_tracker`` bag ``negative_2.bag`` has a left, a
rear and a right one, 270 degrees each, and no tf) sees the same room from each. Two scans of two
lasers taken at nearly the same time see the same walls, so the pose of one laser in the frame of
the other is the pose at which its scan fits the other's: found over a whole window (every
heading, metres of shift) by the branch-and-bound correlative search of the loop closures
(:mod:`tourbot.mapping.correlative`, Olson 2009; Hess et al. 2016) and refined by hill climbing.
Several pairs of scans give several estimates: their spread says whether the robot stood still
enough (or the scans were near enough in time) for the estimate to hold, and with three lasers or
more the estimates must close (the mount of C found through B equals the one found directly).

The mounts are given in the frame of one laser (the *reference*, whose offset stays zero): the
robot's frame is then that laser's frame, as for a robot with a single laser.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tourbot.errors import TourbotError
from tourbot.geometry import compose, relative, wrap_angle
from tourbot.mapping.correlative import SearchWindow, Submap, refine, search
from tourbot.records import Scan

__all__ = [
    "MountConfig",
    "MountError",
    "MountEstimate",
    "bag_lasers",
    "estimate_mounts",
    "mount_lasers",
    "scan_points",
]

FloatArray = NDArray[np.float64]


class MountError(TourbotError):
    """The lasers' mounts cannot be told from the scans (they do not fit each other, or disagree)."""


@dataclass(frozen=True)
class MountConfig:
    """``pairs``: how many scan pairs (each of the other laser's first scans with the reference
    laser's scan nearest in time) estimate a mount; ``max_dt`` (s) how far apart in time the two
    scans of a pair may be. The search spans ``window`` (m either way, every heading) at
    ``resolution`` (m) with a likelihood grid of ``sigma`` (m). Beams shorter than ``near_range``
    (m) see the robot's own body and are left out. An estimate holds when its pairs agree within
    ``max_spread`` (m, rad: the median distance to their median) and, with three lasers or more,
    each mount found through another laser closes within ``max_closure`` (m, rad)."""

    pairs: int = 8
    max_dt: float = 0.1
    window: float = 2.0
    resolution: float = 0.05
    sigma: float = 0.05
    near_range: float = 0.3
    min_score: float = 0.15
    max_spread: tuple[float, float] = (0.05, 0.02)
    max_closure: tuple[float, float] = (0.08, 0.03)


@dataclass(frozen=True)
class MountEstimate:
    """Each laser's pose ``(x, y, theta)`` in the reference laser's frame (the reference's is 0),
    with the spread of its pairs (m, rad) and the worst closure over the triangles of lasers."""

    reference: str
    mounts: dict[str, tuple[float, float, float]]
    spread: dict[str, tuple[float, float]]
    closure: tuple[float, float]

    def describe(self) -> str:
        parts = [
            f"{name} at ({m[0]:.2f} m, {m[1]:.2f} m, {math.degrees(m[2]):.0f} deg)"
            for name, m in self.mounts.items()
            if name != self.reference
        ]
        text = f"laser mounts from the scans, in the frame of {self.reference}: {', '.join(parts)}"
        if len(self.mounts) >= 3:
            text += f"; closure {self.closure[0] * 100:.1f} cm, {math.degrees(self.closure[1]):.1f} deg"
        return text


def scan_points(scan: Scan, near_range: float = 0.0) -> FloatArray:
    """The scan's returns beyond ``near_range`` as points ``(N, 2)`` in the laser's own frame."""
    r = np.asarray(scan.ranges, dtype=np.float64)
    g = scan.geometry
    ok = (r < g.max_range) & (r > max(g.min_range, near_range))
    a = g.angles[ok]
    return np.stack([r[ok] * np.cos(a), r[ok] * np.sin(a)], axis=-1)


def _pair_mount(ref: Scan, other: Scan, cfg: MountConfig) -> tuple[FloatArray, float] | None:
    """The pose of ``other``'s laser in ``ref``'s laser frame at which its scan fits ``ref``'s."""
    ref_pts = scan_points(ref, cfg.near_range)
    pts = scan_points(other, cfg.near_range)
    if len(ref_pts) < 20 or len(pts) < 20:
        return None
    submap = Submap(ref_pts, cfg.resolution, cfg.sigma)
    found = search(submap, pts, np.zeros(3), SearchWindow(cfg.window, math.pi), cfg.min_score)
    if found is None:
        return None
    return refine(submap, pts, found.pose), found.score


def _robust(estimates: FloatArray) -> tuple[FloatArray, tuple[float, float]]:
    """The median pose of ``(K, 3)`` estimates and their median distance to it (m, rad)."""
    mid = np.median(estimates[:, :2], axis=0)
    heading = float(np.median(wrap_angle(estimates[:, 2] - estimates[0, 2])) + estimates[0, 2])
    centre = np.array([mid[0], mid[1], float(wrap_angle(heading))])
    d_xy = np.hypot(estimates[:, 0] - centre[0], estimates[:, 1] - centre[1])
    d_th = np.abs(wrap_angle(estimates[:, 2] - centre[2]))
    return centre, (float(np.median(d_xy)), float(np.median(d_th)))


def _between(
    a: Sequence[Scan], b: Sequence[Scan], cfg: MountConfig
) -> tuple[FloatArray, tuple[float, float]]:
    """The pose of laser ``b`` in laser ``a``'s frame from the first nearly simultaneous pairs."""
    times = np.array([s.timestamp for s in a])
    found: list[FloatArray] = []
    for scan in b:
        if len(found) >= cfg.pairs or not len(times):
            break
        k = int(np.argmin(np.abs(times - scan.timestamp)))
        if abs(times[k] - scan.timestamp) > cfg.max_dt:
            continue
        pair = _pair_mount(a[k], scan, cfg)
        if pair is not None:
            found.append(pair[0])
    if len(found) < max(3, cfg.pairs // 2):
        raise MountError(
            f"only {len(found)} scans of {b[0].sensor if b else '?'} fit a scan of "
            f"{a[0].sensor if a else '?'} taken within {cfg.max_dt:g} s"
        )
    return _robust(np.array(found))


def estimate_mounts(
    streams: Mapping[str, Sequence[Scan]], reference: str, config: MountConfig | None = None
) -> MountEstimate:
    """The pose of every laser of ``streams`` (laser name -> its scans in time order) in the frame
    of the ``reference`` laser, from nearly simultaneous scans; a :class:`MountError` when the scans
    do not fit each other, the pairs disagree (the robot moved too much between them) or, with
    three lasers or more, the mounts do not close."""
    cfg = config or MountConfig()
    if reference not in streams:
        raise MountError(f"no laser {reference!r} among {', '.join(streams)}")
    mounts: dict[str, tuple[float, float, float]] = {reference: (0.0, 0.0, 0.0)}
    spread: dict[str, tuple[float, float]] = {reference: (0.0, 0.0)}
    direct: dict[str, FloatArray] = {}
    for name, scans in streams.items():
        if name == reference:
            continue
        pose, sp = _between(streams[reference], scans, cfg)
        if sp[0] > cfg.max_spread[0] or sp[1] > cfg.max_spread[1]:
            raise MountError(
                f"the scans of {name} place it on the robot {sp[0] * 100:.1f} cm and "
                f"{math.degrees(sp[1]):.1f} deg apart (at most {cfg.max_spread[0] * 100:g} cm and "
                f"{math.degrees(cfg.max_spread[1]):g} deg): the robot moved between the scans"
            )
        direct[name] = pose
        mounts[name] = (float(pose[0]), float(pose[1]), float(pose[2]))
        spread[name] = sp
    closure = (0.0, 0.0)
    others = [n for n in streams if n != reference]
    for i, b in enumerate(others):
        for c in others[i + 1 :]:
            through, _ = _between(streams[b], streams[c], cfg)
            err = relative(direct[c], compose(direct[b], through))
            closure = (
                max(closure[0], float(math.hypot(err[0], err[1]))),
                max(closure[1], abs(float(err[2]))),
            )
    if closure[0] > cfg.max_closure[0] or closure[1] > cfg.max_closure[1]:
        raise MountError(
            f"the lasers' mounts do not close: {closure[0] * 100:.1f} cm and "
            f"{math.degrees(closure[1]):.1f} deg off (at most {cfg.max_closure[0] * 100:g} cm and "
            f"{math.degrees(cfg.max_closure[1]):g} deg)"
        )
    return MountEstimate(reference, mounts, spread, closure)


def mount_lasers(
    streams: Mapping[str, Sequence[Scan]], tracked: str, config: MountConfig | None = None
) -> tuple[dict[str, list[Scan]], str]:
    """The scans of every laser with its mount on the robot as its geometry's offset, and how the
    mounts were found. Lasers whose bag gave their mounts (a ``base_link`` -> laser transform on
    ``/tf``: an offset other than zero) keep them; when every offset is zero (no tf: three lasers
    cannot all sit at one point) they are estimated from the scans (:func:`estimate_mounts`) in the
    frame of the ``tracked`` laser, which is then the robot's frame."""
    offsets = {name: scans[0].geometry.offset for name, scans in streams.items() if scans}
    if len(offsets) != len(streams):
        empty = [name for name, scans in streams.items() if not scans]
        raise MountError(f"no scans on {', '.join(empty)}")
    if any(o != (0.0, 0.0, 0.0) for o in offsets.values()):
        return {name: list(scans) for name, scans in streams.items()}, "laser mounts from the bag's tf"
    estimate = estimate_mounts(streams, tracked, config)
    out: dict[str, list[Scan]] = {}
    for name, scans in streams.items():
        fixed = {g: replace(g, offset=estimate.mounts[name]) for g in {s.geometry for s in scans}}
        out[name] = [replace(s, geometry=fixed[s.geometry]) for s in scans]
    return out, estimate.describe()


def bag_lasers(
    bag: Path, tracked: str, config: MountConfig | None = None
) -> tuple[dict[str, list[Scan]], str]:
    """Every laser of a ROS ``bag`` (the ``tracked`` topic first, the others in name order), each
    scan with its laser's mount (:func:`mount_lasers`), and how the mounts were found."""
    from tourbot.io.rosbag import bag_topics, read_bag

    topics = sorted(
        t for t, (kind, _) in bag_topics(bag).items() if kind.endswith("LaserScan") and t != tracked
    )
    streams = {t: list(read_bag(bag, scan_topic=t).scans) for t in [tracked, *topics]}
    if len(streams) == 1:
        return streams, "one laser"
    return mount_lasers(streams, tracked, config)
