"""Mapping of populated places with people filtered out (Burgard et al., Sec. 5, Eq. 10-12).

The people tracker (:class:`tourbot.people.sjpdaf.PeopleTracker`) follows the visitors around the
robot. Its sample sets give the probability that a beam ending at ``(x, y)`` is reflected by a
person (Eq. 10-11), from histograms of each person's samples over 15 x 15 cm bins:

    P(hit_xy | X) = 1 - prod_i (1 - P(hit_xy | x_i))

``P(hit_xy | x_i)`` is the fraction of person ``i``'s samples whose bin lies within a body radius
of the beam's bin (the histogram, normalized, summed over the person's extent), times how sure the
tracker is that the track is a person (1 once confirmed). During alignment each beam is weighted
by ``1 - P(hit_b | X)`` (Eq. 12); beams ending on the scan's own person features (below) count as
``P(hit) = 1``. A scan is aligned against the map of the scans before it with the people known at
once; the map that is returned gets it a few scans later (below).

When the map is built, the beams ending in a person's bounding box are left out. A scan is
written ``scans_around`` scans late, so that the tracker's delay is covered: a track counts as a
person in scan ``t`` when it is confirmed by scan ``t + scans_around`` (its position in scan ``t``
is used, so a visitor standing still is removed from the scans before the confirmation too), or
when it had been detected a few times by scan ``t`` (a tentative track). With
``PeopleFilterParams.window`` its boxes in a few scans before and after count too (the paper's
setting: "several previous and next scans").
Besides the tracks, the person features of the scan itself count (a person walks several metres
between the scans of a sparse log, and no track can follow): those the tracker's static filter
sees moving, and those standing where the map so far has seen free floor (the difference of the
scan and the map, Sec. 4, Fig. 6, against the whole map instead of the previous scan). A beam is
a person's only if it does not end beyond the person (a wall behind a visitor stays), and a
person's beam still clears the free space in front of the person.

Two modes (:meth:`PeopleFilterParams.mode`): ``paper`` is Sec. 5 alone; ``checked``, the default
everywhere (the dataclass, ``tourbot slam``, the benchmarks), adds the rules beyond the paper
(free sectors, far blobs, and the checks of the finished map). The rule that leaves more beams out
of the returned map (far blobs) is for that map only: a scan is aligned with the tracks and person
features alone (Eq. 12), and these are judged against a map written without it (``evidence
map``), so that what the map-only rule leaves out does not make the alignment take more real
structure for people (on the real Intel log, without a crowd, it did: 0.051 m relative error with
the far blobs against 0.033 m without). The passes over the finished map
(:mod:`tourbot.mapping.confirmation`, :mod:`tourbot.mapping.consistency`) act on the returned map
alone.
"""

from __future__ import annotations

import collections
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose, invert, transform_points
from tourbot.mapping.blobs import BlobParams, person_blobs
from tourbot.mapping.confirmation import ConfirmationParams, confirmed_beams, continues_structure
from tourbot.mapping.consistency import ConsistencyParams, clear_specks
from tourbot.mapping.incremental import IncrementalMapper, MapperParams
from tourbot.maps.grid import OccupancyGrid
from tourbot.people.sjpdaf import PeopleTracker, SJPDAFConfig
from tourbot.records import Scan

__all__ = [
    "DEFAULT_MODE",
    "FILTER_MODES",
    "GIVE_BACK",
    "MAP_CHECK",
    "AlignmentParams",
    "FarBlobParams",
    "PeopleFilterParams",
    "PeopleFilteredMapper",
    "PeopleMappingConfig",
    "PersonBeamParams",
    "beam_endpoints",
    "hit_probability",
    "in_boxes",
    "person_beams",
]

FloatArray = NDArray[np.float64]
# The checks of the finished map in the default mode (``checked``), beyond the paper. Specks
# (:mod:`tourbot.mapping.consistency`): a ring at least 40 % seen free and groups of components up
# to 6 cells, since the beams given back keep static cells that the filter had cost (chosen on
# crowd seeds 30-35); specks of at most 2 cells that beams of one scan hit from beyond 6 m only
# cleared with a ring at least 75 % seen free and at least 20 % behind them, groups of such specks
# hit by at most 2 scans with 20 % behind them (seeds 50-55); specks that one scan hit from beyond
# 4 m (the leg detector's reach) judged so also when their ring holds such specks too (visitors
# standing together; seeds 70-75).
MAP_CHECK = ConsistencyParams(
    ring_free=0.4,
    group_member_cells=6,
    far_range=6.0,
    far_scans=1,
    far_cells=2,
    far_ring_free=0.75,
    far_behind_free=0.2,
    far_group_scans=2,
    mutual_range=4.0,
)
# The give-back (:mod:`tourbot.mapping.confirmation`): a left-out beam's hit returns when kept
# beams of 4 other scans end in its cell's neighbourhood, or when its end lies in a line of
# structure the map holds (occupied cells within 2 cells on two sides at least 90 degrees apart;
# seeds 70-75).
GIVE_BACK = ConfirmationParams(line_radius=2, line_angle=90.0)
DEFAULT_MODE = "checked"
FILTER_MODES = (DEFAULT_MODE, "paper")


@dataclass(frozen=True)
class AlignmentParams:
    """How the people weigh the beams of a scan in its alignment (Eq. 10-12; bins of 15 cm as in
    Burgard et al. Sec. 5).

    ``bin_size``: the side of the histogram bins of each person's samples (m). ``body_radius``: a
    beam ending this close to a person's samples may be reflected by them (m); a tentative track
    counts with its probability of existence (:attr:`~tourbot.people.sjpdaf.Track.existence`).
    ``align_features``: beams ending on the scan's person features get no weight in alignment
    (Eq. 12 with ``P(hit) = 1``): in a sparse log the walking visitors have no track.
    """

    bin_size: float = 0.15
    body_radius: float = 0.3
    align_features: bool = True


@dataclass(frozen=True)
class PersonBeamParams:
    """Which beams of a scan its people take out of the map when the scan is written (Sec. 5).

    ``box_half_size``: half the side of a tracked person's bounding box (m: legs up to a stride
    apart). ``scans_around``: how many scans later a scan is written, and so how late a track may
    be confirmed and still count in it; a track not confirmed by then counts when it had
    ``tentative_hits`` detections (None: never; 2 is an existence share of 2/3 in alignment).
    Person features of the scan itself count (in a box of ``feature_half_size``, m) when their
    P(moving) is at least ``feature_moving`` or the map so far has a log-odds at most
    ``feature_free`` around them (seen free before). ``beyond``: a beam ending farther than this
    (m) behind a person's centre passed the person and is kept. ``window``: a counted track's boxes
    at its positions in the ``window`` scans before and after also count in a scan (the paper's
    "several previous and next scans", to cope with the tracker's delay; the scans after are those
    still waiting, so at most ``scans_around``; 0: the scan's own). ``static_evidence``: a beam in a
    box is kept when it ends in a cell the map already holds as occupied with at least this
    log-odds (a wall seen before a visitor stood in front of it). ``keep_free_space``: a person's
    beam still marks the cells in front of the person free.
    """

    box_half_size: float = 0.3
    scans_around: int = 3
    window: int = 0
    tentative_hits: int | None = 2
    feature_half_size: float = 0.25
    feature_moving: float = 0.8
    feature_free: float = -0.3
    beyond: float = 0.2
    static_evidence: float = 3.0
    keep_free_space: bool = True


@dataclass(frozen=True)
class FarBlobParams:
    """Beyond the paper: the beams on a person-sized blob beyond the leg detector's reach
    (:mod:`tourbot.mapping.blobs`, ``shape``) are left out of the map (not of alignment) like a
    person's, unless the map so far has a log-odds of ``evidence`` or more in the 3 x 3 cells
    around their end (something static seen there before), and fewer than ``repeats`` blobs were
    left out there before: a pole seen from afar is a blob in scan after scan at one spot, and is
    mapped from its ``repeats + 1``-th scan on."""

    shape: BlobParams = field(default_factory=BlobParams)
    evidence: float = 0.5
    repeats: int = 3


@dataclass(frozen=True)
class PeopleFilterParams:
    """Parameters of people filtering, in groups: ``alignment`` (Eq. 10-12), ``beams`` (the map
    that is written, Sec. 5), and the rules beyond the paper (on by default, off in
    :meth:`paper`):

    - ``free_sectors``: the map also clears the cells between neighbouring beams that the laser
      saw past on both sides (:mod:`tourbot.mapping.free_space`), so that a visitor hit once at a
      distance is cleared by the later scans that saw the floor around the spot, although none of
      their beams crossed its cell;
    - ``far_blobs`` (:class:`FarBlobParams`; None: off);
    - ``confirmation`` (``GIVE_BACK``; None: none): the left-out beams whose ends kept beams of
      several other scans confirm, or that continue a line of structure the map holds
      (:mod:`tourbot.mapping.confirmation`), get their hits back in the finished map;
    - ``consistency`` (``MAP_CHECK``; None: no check): then the finished map is checked against
      itself (:mod:`tourbot.mapping.consistency`): small occupied specks, alone or in groups a few
      decimetres across (visitors standing together), with free floor around them and behind them
      along the beams that hit them are cleared.
    """

    alignment: AlignmentParams = field(default_factory=AlignmentParams)
    beams: PersonBeamParams = field(default_factory=PersonBeamParams)
    free_sectors: bool = True
    far_blobs: FarBlobParams | None = field(default_factory=FarBlobParams)
    confirmation: ConfirmationParams | None = GIVE_BACK
    consistency: ConsistencyParams | None = MAP_CHECK

    @classmethod
    def paper(cls) -> PeopleFilterParams:
        """Burgard et al. Sec. 5 alone: tracks and person features, none of the rules beyond it."""
        return cls(free_sectors=False, far_blobs=None, consistency=None, confirmation=None)

    @classmethod
    def mode(cls, name: str) -> PeopleFilterParams:
        """The parameters of a named mode: ``checked`` (the default: the paper's filter, free
        sectors, far blobs, and the finished map checked, ``GIVE_BACK`` then ``MAP_CHECK``) or
        ``paper`` (:meth:`paper`)."""
        if name not in FILTER_MODES:
            raise ValueError(f"unknown people filter mode {name!r} (one of {', '.join(FILTER_MODES)})")
        return cls.paper() if name == "paper" else cls()


def hit_probability(
    sample_sets: Iterable[FloatArray],
    points: FloatArray,
    params: AlignmentParams | None = None,
    existence: Iterable[float] | None = None,
) -> FloatArray:
    """``P(hit_xy | X)`` at world ``points`` ``(B, 2)`` from the people's samples (Eq. 10-11).

    ``existence`` (one per sample set, default 1) scales each person's ``P(hit_xy | x_i)``.
    """
    p = params or AlignmentParams()
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    miss = np.ones(len(pts))
    reach = (p.body_radius / p.bin_size) ** 2
    pbins = np.floor(pts / p.bin_size)
    sets = list(sample_sets)
    probs = [1.0] * len(sets) if existence is None else list(existence)
    for samples, prob in zip(sets, probs, strict=True):
        s = np.asarray(samples, dtype=np.float64)
        if s.size == 0 or prob <= 0.0:
            continue
        sbins = np.floor(s[:, :2] / p.bin_size)
        lo = sbins.min(axis=0) - p.body_radius / p.bin_size - 1
        hi = sbins.max(axis=0) + p.body_radius / p.bin_size + 1
        near = np.all((pbins >= lo) & (pbins <= hi), axis=1)
        if not near.any():
            continue
        d2 = ((pbins[near, None, :] - sbins[None, :, :]) ** 2).sum(axis=2)
        miss[near] *= 1.0 - prob * (d2 <= reach).mean(axis=1)
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
    return person_beams(np.asarray(points), None, c, np.full(len(c), half_size), np.inf)


def person_beams(
    points: FloatArray,
    origin: FloatArray | None,
    centres: FloatArray,
    half_sizes: FloatArray,
    beyond: float,
) -> NDArray[np.bool_]:
    """Which beam endpoints ``(B, 2)`` a person reflected: in a person's box (``centres`` ``(K, 2)``,
    ``half_sizes`` ``(K,)``) and, seen from the laser at ``origin``, not more than ``beyond`` farther
    away than the person's centre (such a beam passed the person: a wall behind a visitor)."""
    c = np.asarray(centres, dtype=np.float64).reshape(-1, 2)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(c) == 0:
        return np.zeros(len(pts), dtype=bool)
    inside = np.all(np.abs(pts[:, None, :] - c[None, :, :]) <= np.asarray(half_sizes)[None, :, None], axis=2)
    if origin is not None and np.isfinite(beyond):
        o = np.asarray(origin, dtype=np.float64)[:2]
        reach = np.linalg.norm(c - o, axis=1) + beyond
        inside &= np.linalg.norm(pts - o, axis=1)[:, None] <= reach[None, :]
    return np.asarray(np.any(inside, axis=1))


@dataclass
class _Pending:
    """A scan waiting to be written, with what the tracker saw in it."""

    scan: Scan
    pose: FloatArray
    index: int
    track_ids: list[int]
    track_hits: list[int]  # detections of each track so far
    track_positions: FloatArray  # (K, 2)
    features: FloatArray  # (F, 2) person features of this scan
    moving: FloatArray  # (F,) their P(moving)

    def moved_to(self, pose: FloatArray) -> _Pending:
        """The same scan at an aligned ``pose``: what was seen from the predicted pose moves along."""
        correction = compose(pose, invert(self.pose))

        def move(points: FloatArray) -> FloatArray:
            return transform_points(correction, points) if len(points) else points

        return replace(
            self, pose=pose, track_positions=move(self.track_positions), features=move(self.features)
        )


@dataclass(frozen=True)
class PeopleMappingConfig:
    """Every parameter of people-filtered mapping, in one typed home: the incremental scan-matching
    mapper (:class:`~tourbot.mapping.incremental.MapperParams`, Eq. 1-2), the people tracker
    (:class:`~tourbot.people.sjpdaf.SJPDAFConfig`, Sec. 4) and the filter
    (:class:`PeopleFilterParams`, Sec. 5), each with its documented defaults."""

    mapper: MapperParams = field(default_factory=MapperParams)
    tracker: SJPDAFConfig = field(default_factory=SJPDAFConfig)
    filter: PeopleFilterParams = field(default_factory=PeopleFilterParams)


@dataclass
class PeopleFilteredMapper:
    """Incremental mapping with the people tracker in the loop (Sec. 5)."""

    mapper: IncrementalMapper
    tracker: PeopleTracker
    params: PeopleFilterParams = field(default_factory=PeopleFilterParams)
    removed_beams: int = 0
    left_out: list[NDArray[np.bool_]] = field(default_factory=list)  # per scan written: beams left out
    cleared_cells: int = 0  # cells the consistency check of the last grid() cleared
    restored_beams: int = 0  # left-out beams the last grid() gave back (other scans confirm them)

    def __post_init__(self) -> None:
        self._confirmed: set[int] = set()  # ids of every track confirmed so far
        self._pending: collections.deque[_Pending] = collections.deque()
        self._written: collections.deque[_Pending] = collections.deque(maxlen=self.params.beams.window)
        self._index = 0
        self._blob_spots: dict[tuple[int, int], int] = {}  # far blobs left out, by map cell
        self._origins: list[FloatArray] = []  # per scan written: the laser position of each kept end
        self._ends: list[FloatArray] = []  # per scan written: the world ends of the kept beams
        self._written_index: list[int] = []  # per scan written: its index
        self._left_origins: list[FloatArray] = []  # per scan written: laser position of each left-out end
        self._left_ends: list[FloatArray] = []  # per scan written: the world ends of the left-out beams
        # the map that alignment-time judgements read, when the map-only rules make the returned
        # map differ from it (written from the first aligned scan on; None: the returned map)
        self._evidence_map: IncrementalMapper | None = None

    @classmethod
    def create(
        cls,
        config: PeopleMappingConfig | None = None,
        *,
        tracker: PeopleTracker | None = None,
        start: FloatArray | None = None,
        seed: int = 0,
    ) -> PeopleFilteredMapper:
        """The mapper of ``config``, starting at ``start``; the tracker is built from
        ``config.tracker`` and seeded with ``seed`` unless one is given."""
        config = config or PeopleMappingConfig()
        mapper_params = config.mapper
        if config.filter.free_sectors:
            mapper_params = replace(mapper_params, free_sectors=True)
        return cls(
            mapper=IncrementalMapper(mapper_params, start=start),
            tracker=tracker or PeopleTracker(config.tracker, rng=np.random.default_rng(seed)),
            params=config.filter,
        )

    def add_scan(self, scan: Scan, pose: FloatArray | None = None) -> FloatArray:
        """Track people, align the scan with people-weighted beams (Eq. 12), map it a few scans later.

        With ``pose`` given (mapping with known poses), the scan is not aligned but mapped there.
        Returns the scan's pose.
        """
        p = self.params
        predicted = self.mapper.predict(scan) if pose is None else np.asarray(pose, dtype=np.float64)
        tracks = self.tracker.update(scan, predicted)
        self._confirmed.update(t.id for t in tracks if t.confirmed)
        item = _Pending(
            scan,
            predicted,
            self._index,
            [t.id for t in tracks],
            [t.hits for t in tracks],
            np.asarray([t.position for t in tracks], dtype=np.float64).reshape(-1, 2),
            self.tracker.last_features.points.copy(),
            np.asarray(self.tracker.last_moving, dtype=np.float64).copy(),
        )
        if pose is None:
            if self._evidence_map is None and self._map_only_rules():
                self._evidence_map = IncrementalMapper(self.mapper.params)
            sets = self.tracker.sample_sets()
            existence = [1.0 if t.confirmed else t.existence for t in tracks]
            pts, _ = beam_endpoints(scan, predicted)
            h = hit_probability([sets[t.id] for t in tracks], pts, p.alignment, existence)
            if p.alignment.align_features:
                h = np.maximum(h, self._person_beams(item, tracks=False))
            item = item.moved_to(np.asarray(self.mapper.match(scan, match_weights=1.0 - h).pose))
            # the next scan aligns against this one at once, with the people known now
            self._integrate(item, self._person_beams(item), "alignment")
        self._pending.append(item)
        self._index += 1
        while self._pending and self._pending[0].index + p.beams.scans_around < self._index:
            self._write(self._pending.popleft())
        return item.pose

    def finish(self) -> None:
        """Write the scans still waiting for the people seen after them."""
        while self._pending:
            self._write(self._pending.popleft())

    def grid(self) -> OccupancyGrid:
        """The map of the scans written so far (call :meth:`finish` first for all of them): with
        ``params.confirmation``, the left-out beams that other scans' kept beams confirm given
        their hits back; then, with ``params.consistency``, the specks it contradicts cleared."""
        p = self.params
        origins = np.concatenate([np.zeros((0, 2)), *self._origins])
        ends = np.concatenate([np.zeros((0, 2)), *self._ends])
        scans = np.asarray(self._written_index, dtype=np.int64)
        kept_scans = np.repeat(scans, [len(e) for e in self._ends])
        beam_scans = kept_scans
        if p.confirmation is None:
            grid = self.mapper.grid()
        else:
            left = np.concatenate([np.zeros((0, 2)), *self._left_ends])
            left_scans = np.repeat(scans, [len(e) for e in self._left_ends])
            back = confirmed_beams(
                left, left_scans, ends, kept_scans, self.mapper.params.resolution, p.confirmation
            )
            c = p.confirmation
            if c.line_radius is not None:  # ends in a line of structure the map holds
                held = self.mapper.grid()
                back |= continues_structure(
                    held.occupied(), held.world_to_cell(left), c.line_radius, c.line_angle
                )
            self.restored_beams = int(back.sum())
            grid = self.mapper.grid(extra_hits=left[back])
            left_origins = np.concatenate([np.zeros((0, 2)), *self._left_origins])
            origins = np.concatenate([origins, left_origins[back]])
            ends = np.concatenate([ends, left[back]])
            beam_scans = np.concatenate([kept_scans, left_scans[back]])
        if p.consistency is None:
            return grid
        grid, self.cleared_cells = clear_specks(grid, origins, ends, p.consistency, beam_scans)
        return grid

    def _map_only_rules(self) -> bool:
        """Whether rules for the returned map only are on (far blobs)."""
        return self.params.far_blobs is not None

    def _evidence(self, points: FloatArray, into: Literal["map", "alignment"]) -> FloatArray:
        """Log-odds at world ``points`` of the map the judgements ``into`` a map read: the returned
        map, or for alignment the evidence map (the returned map without the map-only rules)."""
        source = self._evidence_map if into == "alignment" and self._evidence_map is not None else self.mapper
        return source.evidence(points)

    def _people(
        self, item: _Pending, tracks: bool = True, into: Literal["map", "alignment"] = "alignment"
    ) -> tuple[FloatArray, FloatArray]:
        """Centres ``(K, 2)`` and box half sizes of the people in a waiting scan (the person
        features only, without ``tracks``), judged against the map ``into`` reads."""
        p = self.params.beams
        centres = np.zeros((0, 2))
        if tracks:
            # the scan's own tracks, and those of the scans within the window (before and after)
            near = [o for o in (*self._written, *self._pending) if 0 < abs(o.index - item.index) <= p.window]
            centres = np.concatenate([self._track_centres(o) for o in (item, *near)])
        features = item.features
        if len(features):
            seen_free = self._evidence_around(features, into) <= p.feature_free
            features = features[(item.moving >= p.feature_moving) | seen_free]
        half = np.r_[np.full(len(centres), p.box_half_size), np.full(len(features), p.feature_half_size)]
        return np.concatenate([centres, features]), half

    def _track_centres(self, item: _Pending) -> FloatArray:
        """Positions ``(K, 2)`` in a waiting scan of the tracks that count as people."""
        hits_needed = self.params.beams.tentative_hits
        tentative = hits_needed if hits_needed is not None else np.inf
        tracked = [
            i in self._confirmed or hits >= tentative
            for i, hits in zip(item.track_ids, item.track_hits, strict=True)
        ]
        return item.track_positions[np.asarray(tracked, dtype=bool).reshape(-1)]

    def _evidence_around(self, points: FloatArray, into: Literal["map", "alignment"] = "map") -> FloatArray:
        """The largest log-odds of the map so far (the one ``into`` reads) in the 3 x 3 cells
        around each point."""
        res = self.mapper.params.resolution
        offsets = res * np.array([[dx, dy] for dx in (-1, 0, 1) for dy in (-1, 0, 1)], dtype=np.float64)
        around = (points[:, None, :] + offsets[None, :, :]).reshape(-1, 2)
        return np.asarray(self._evidence(around, into).reshape(len(points), -1).max(axis=1))

    def _person_beams(
        self, item: _Pending, tracks: bool = True, into: Literal["map", "alignment"] = "alignment"
    ) -> NDArray[np.bool_]:
        """The beams of a scan that ended on a person, with the tracks confirmed so far (``into``:
        for the map that is returned, with the map-only rules, or for alignment and the evidence
        map, with the tracks and person features only)."""
        centres, half = self._people(item, tracks, into)
        pts, hit = beam_endpoints(item.scan, item.pose)
        laser = compose(item.pose, item.scan.geometry.offset)
        beams = self.params.beams
        person = hit & person_beams(pts, laser, centres, half, beams.beyond)
        if person.any():
            person[person] = self._evidence(pts[person], into) < beams.static_evidence
        far = self.params.far_blobs
        if into == "map" and far is not None:
            blob = hit & ~person & person_blobs(item.scan, far.shape)
            if blob.any():  # nothing seen occupied around it yet: not a pole or an exhibit's edge
                blob[blob] = self._evidence_around(pts[blob]) < far.evidence
            if blob.any():
                blob[blob] = self._new_spots(pts[blob], self._blob_spots, far.repeats)
            person |= blob
        return person

    def _new_spots(
        self, points: FloatArray, spots: dict[tuple[int, int], int], repeats: int
    ) -> NDArray[np.bool_]:
        """Which ends of one scan lie where fewer than ``repeats`` ends were left out before (in the
        3 x 3 cells around, counted in ``spots``); counts them. A blob seen again and again at one
        spot is static; every end counts (the far blobs: a beam or two each)."""
        res = self.mapper.params.resolution
        cells = np.floor(points / res).astype(np.int64)
        new = np.zeros(len(cells), dtype=bool)
        for k, (cx, cy) in enumerate(cells.tolist()):
            around = [spots.get((cx + dx, cy + dy), 0) for dx in (-1, 0, 1) for dy in (-1, 0, 1)]
            new[k] = sum(around) < repeats
        for cx, cy in cells[new].tolist():
            spots[(cx, cy)] = spots.get((cx, cy), 0) + 1
        return new

    def _write(self, item: _Pending) -> None:
        person = self._person_beams(item, into="map")
        self.removed_beams += int(person.sum())
        self.left_out.append(person)
        if self.params.consistency is not None or self.params.confirmation is not None:
            pts, hit = beam_endpoints(item.scan, item.pose)
            kept = pts[hit & ~person]
            laser = compose(item.pose, item.scan.geometry.offset)[:2]
            self._ends.append(kept)
            self._origins.append(np.repeat(laser[None, :], len(kept), axis=0))
            self._written_index.append(item.index)
            if self.params.confirmation is not None:
                left = pts[hit & person]
                self._left_ends.append(left)
                self._left_origins.append(np.repeat(laser[None, :], len(left), axis=0))
        self._integrate(item, person, "map")
        if self._evidence_map is not None:
            aligned = self._person_beams(item, into="alignment")
            self._integrate(item, aligned, "map", self._evidence_map)
        self._written.append(item)

    def _integrate(
        self,
        item: _Pending,
        person: NDArray[np.bool_],
        into: Literal["map", "alignment"],
        mapper: IncrementalMapper | None = None,
    ) -> None:
        target = self.mapper if mapper is None else mapper
        if self.params.beams.keep_free_space:
            target.integrate(item.scan, item.pose, free_only=person, into=into)
        else:
            target.integrate(item.scan, item.pose, keep=~person, into=into)
