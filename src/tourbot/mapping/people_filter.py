"""Mapping of populated places with people filtered out (Burgard et al., Sec. 5, Eq. 10-12).

The people tracker (:class:`tourbot.people.sjpdaf.PeopleTracker`) follows the visitors around the
robot. Its sample sets give the probability that a beam ending at ``(x, y)`` is reflected by a
person (Eq. 10-11), from histograms of each person's samples over 15 x 15 cm bins:

    P(hit_xy | X) = 1 - prod_i (1 - P(hit_xy | x_i))

``P(hit_xy | x_i)`` is the fraction of person ``i``'s samples whose bin lies within a body radius
of the beam's bin (the histogram, normalized, summed over the person's extent). During alignment
each beam is weighted by ``1 - P(hit_b | X)`` (Eq. 12). When the map is built, the beams ending in
a tracked person's bounding box are left out, with the boxes of a few scans before and after
(a person is tracked only after being seen a few times, and legs swing).
"""

from __future__ import annotations

import collections
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose
from tourbot.mapping.incremental import IncrementalMapper, MapperParams
from tourbot.people.sjpdaf import PeopleTracker
from tourbot.records import Scan

__all__ = ["PeopleFilterParams", "PeopleFilteredMapper", "beam_endpoints", "hit_probability", "in_boxes"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PeopleFilterParams:
    """Parameters of people filtering (bins of 15 cm as in Burgard et al. Sec. 5).

    ``body_radius``: a beam ending this close to a person's position may be reflected by them.
    ``box_half_size``: half the side of a person's bounding box for leaving beams out of the map.
    ``scans_around``: the boxes of this many scans before and after also remove beams.
    ``static_evidence``: a beam in a box is kept when it ends in a cell the map already holds as
    occupied with at least this log-odds (a wall seen before a visitor stood in front of it; beams
    left out never build such evidence, so a visitor standing still cannot).
    """

    bin_size: float = 0.15
    body_radius: float = 0.3
    box_half_size: float = 0.45
    scans_around: int = 3
    confirmed_only: bool = True
    static_evidence: float = 3.0


def hit_probability(
    sample_sets: Iterable[FloatArray], points: FloatArray, params: PeopleFilterParams | None = None
) -> FloatArray:
    """``P(hit_xy | X)`` at world ``points`` ``(B, 2)`` from the people's samples (Eq. 10-11)."""
    p = params or PeopleFilterParams()
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    miss = np.ones(len(pts))
    reach = (p.body_radius / p.bin_size) ** 2
    pbins = np.floor(pts / p.bin_size)
    for samples in sample_sets:
        s = np.asarray(samples, dtype=np.float64)
        if s.size == 0:
            continue
        sbins = np.floor(s[:, :2] / p.bin_size)
        lo = sbins.min(axis=0) - p.body_radius / p.bin_size - 1
        hi = sbins.max(axis=0) + p.body_radius / p.bin_size + 1
        near = np.all((pbins >= lo) & (pbins <= hi), axis=1)
        if not near.any():
            continue
        d2 = ((pbins[near, None, :] - sbins[None, :, :]) ** 2).sum(axis=2)
        miss[near] *= 1.0 - (d2 <= reach).mean(axis=1)
    return 1.0 - miss


def beam_endpoints(scan: Scan, pose: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
    """World endpoints ``(B, 2)`` of ``scan``'s beams at robot ``pose``, and which beams returned."""
    g = scan.geometry
    r = np.asarray(scan.ranges, dtype=np.float64)
    laser = compose(pose, g.offset)
    th = laser[2] + g.angles
    hit = (r < g.max_range) & (r > g.min_range)
    pts = np.stack([laser[0] + r * np.cos(th), laser[1] + r * np.sin(th)], axis=1)
    return pts, hit


def in_boxes(points: FloatArray, centres: FloatArray, half_size: float) -> NDArray[np.bool_]:
    """Which ``points`` ``(B, 2)`` fall in an axis-aligned box of ``half_size`` around any centre."""
    c = np.asarray(centres, dtype=np.float64).reshape(-1, 2)
    if len(c) == 0:
        return np.zeros(len(points), dtype=bool)
    d = np.abs(np.asarray(points)[:, None, :] - c[None, :, :])
    return np.asarray(np.any(np.all(d <= half_size, axis=2), axis=1))


@dataclass
class _Pending:
    scan: Scan
    pose: FloatArray
    index: int


@dataclass
class PeopleFilteredMapper:
    """Incremental mapping with the people tracker in the loop (Sec. 5)."""

    mapper: IncrementalMapper
    tracker: PeopleTracker
    params: PeopleFilterParams = field(default_factory=PeopleFilterParams)
    removed_beams: int = 0

    def __post_init__(self) -> None:
        self._people: dict[int, FloatArray] = {}  # scan index -> tracked people's positions (K, 2)
        self._pending: collections.deque[_Pending] = collections.deque()
        self._index = 0

    @classmethod
    def create(
        cls,
        mapper_params: MapperParams | None = None,
        tracker: PeopleTracker | None = None,
        params: PeopleFilterParams | None = None,
        start: FloatArray | None = None,
        seed: int = 0,
    ) -> PeopleFilteredMapper:
        return cls(
            mapper=IncrementalMapper(mapper_params, start=start),
            tracker=tracker or PeopleTracker(rng=np.random.default_rng(seed)),
            params=params or PeopleFilterParams(),
        )

    def add_scan(self, scan: Scan, pose: FloatArray | None = None) -> FloatArray:
        """Track people, align the scan with people-weighted beams (Eq. 12), map it a few scans later.

        With ``pose`` given (mapping with known poses), the scan is not aligned but mapped there.
        Returns the scan's pose.
        """
        p = self.params
        predicted = self.mapper.predict(scan) if pose is None else np.asarray(pose, dtype=np.float64)
        tracks = self.tracker.update(scan, predicted)
        keep_ids = {t.id for t in tracks if t.confirmed or not p.confirmed_only}
        if pose is None:
            samples = [s for i, s in self.tracker.sample_sets().items() if i in keep_ids]
            pts, _ = beam_endpoints(scan, predicted)
            h = hit_probability(samples, pts, p)
            at = np.asarray(self.mapper.match(scan, match_weights=1.0 - h).pose)
        else:
            at = predicted
        people = [t.position for t in tracks if t.id in keep_ids]
        self._people[self._index] = np.asarray(people, dtype=np.float64).reshape(-1, 2)
        self._pending.append(_Pending(scan, at, self._index))
        self._index += 1
        while self._pending and self._pending[0].index + p.scans_around < self._index:
            self._write(self._pending.popleft())
        return at

    def finish(self) -> None:
        """Write the scans still waiting for the people seen after them."""
        while self._pending:
            self._write(self._pending.popleft())

    def _write(self, item: _Pending) -> None:
        p = self.params
        k = item.index
        around = [
            self._people[j] for j in range(k - p.scans_around, k + p.scans_around + 1) if j in self._people
        ]
        centres = np.concatenate(around) if around else np.zeros((0, 2))
        pts, hit = beam_endpoints(item.scan, item.pose)
        person = hit & in_boxes(pts, centres, p.box_half_size)
        if person.any():
            person[person] = self.mapper.evidence(pts[person]) < p.static_evidence
        self.removed_beams += int(person.sum())
        self.mapper.integrate(item.scan, item.pose, keep=~person)
        self._people.pop(k - p.scans_around, None)
