"""People tracking with sample-based joint probabilistic data association filters (SJPDAF).

Burgard et al., Sec. 4 (after Schulz et al. 2001): one particle filter per person, the features of
each scan (people's legs) shared out among the persons by the joint association probabilities
``beta_ji`` (Eq. 6-7) computed from the samples (Eq. 8), the samples weighted by them (Eq. 9) and
resampled. Around it: features from the scan (:mod:`tourbot.people.legs`), static look-alikes
removed by the difference of occupancy grids and the map (:mod:`tourbot.people.static_filter`), an
occlusion map that keeps hidden people's tracks alive (:mod:`tourbot.people.occlusion`), tracks
that start, are confirmed and end by rule. Tracks are in the world frame, through the robot's pose
estimate given with every scan, or, for a recording without odometry, through a
:class:`ScanPoseSource` handed to the tracker (scan matching, :mod:`tourbot.mapping.ego_motion`,
whose map built on the fly is then the static world).
Leg detections that stay fixed in the laser frame while the robot moves are its own body
(:class:`~tourbot.people.static_filter.RobotBodyMask`).

:meth:`PeopleTracker.update` reads as the algorithm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose
from tourbot.maps.grid import OccupancyGrid
from tourbot.people.association import cluster_betas, pair_likelihoods, sample_weights
from tourbot.people.legs import LegConfig, LegFeatures, PersonFeatures, detect_legs, group_legs
from tourbot.people.motion import WalkingModel, predict_samples
from tourbot.people.occlusion import OcclusionConfig, occlusion_probability, points_in_sensor_frame
from tourbot.people.static_filter import RobotBodyMask, StaticConfig, StaticFilter
from tourbot.records import Scan
from tourbot.sampling import systematic_resample_rows

__all__ = ["PeopleTracker", "SJPDAFConfig", "ScanPoseSource", "Track"]

FloatArray = NDArray[np.float64]


class ScanPoseSource(Protocol):
    """Where the robot's poses come from when the recording has none (no odometry, no tf).

    Per scan the tracker calls, in this order: :meth:`match` (the pose of the scan), :meth:`on_map`
    for the legs of that scan (points on the static world built so far stand still), then
    :meth:`integrate` (the scan joins that world, but for the beams ending on ``people``).
    :class:`tourbot.mapping.ego_motion.ScanMatchedPoses` is one (scan-to-map matching).
    """

    def match(self, scan: Scan) -> FloatArray:
        """The pose ``(3,)`` of ``scan`` in the world frame."""
        ...

    def on_map(self, world_points: FloatArray) -> NDArray[np.bool_]:
        """Whether each point ``(M, 2)`` lies on the static world built from the earlier scans."""
        ...

    def integrate(self, scan: Scan, pose: FloatArray, people: FloatArray | None = None) -> None:
        """Add ``scan`` taken at ``pose`` to the static world, but for beams ending on ``people``."""
        ...


@dataclass(frozen=True, slots=True)
class SJPDAFConfig:
    """Every parameter of the people tracker, with its typed home and default.

    Filter (Burgard et al. Sec. 4; Schulz et al. 2001): ``num_samples`` per person;
    ``measurement_std`` the spread of a two-leg person feature around the person (m), and
    ``single_leg_std`` that of a lone leg (the person's centre is up to a stride's half away);
    ``detection_probability`` P_D of a visible person; ``clutter_density`` gamma of Eq. 7, false
    alarms per square metre; ``gate_sigmas`` / ``max_gate``: a feature can be caused by a person only
    within this many standard deviations (of samples and measurement together), and never beyond
    ``max_gate`` metres, which keeps the joint events few with 20-50 people; ``max_events`` caps the
    joint events of one cluster (the weakest pairs are pruned first).

    Track rules, on evidence (after the persistent existence of Schulz et al.'s sample-based
    JPDAF, with the occlusion map, the map difference and the static-feature filter of Burgard et
    al. Sec. 4 as the evidence): a feature no person explains (sum of its betas below
    ``birth_threshold``) with P(person) >= ``birth_probability`` starts a tentative track unless
    its cell was seen occupied before: P(moving) of the static filter >= ``birth_moving`` (with a
    map and ``birth_off_map``: anywhere off the map, which is the static world). Every track holds
    the log odds of its existence: ``existence_prior`` at birth, plus what its features said, scan
    by scan (shared out by the betas): ``free_evidence`` for a feature on a cell seen free before
    (P(moving) >= ``free_moving``, or off a given map), ``hidden_evidence`` for one on a cell
    hidden before (P(moving) about 0.5: a person walking away from the laser stands where their
    own body hid the floor), ``still_evidence`` for one on a cell seen occupied before while the
    track is tentative (a fixed object fades out; a confirmed visitor standing at an exhibit loses
    nothing), ``static_evidence`` for one on the static world built so far (the map of the
    scan-matched poses), ``shape_weight`` times the
    feature's log odds of P(person) (a leg pair's shape; capped at ``shape_cap``: furniture keeps
    its shape scan after scan), and ``miss_evidence`` for a scan without a detection while the
    person is visible; an occluded person (its predicted position behind a nearer return, the
    occlusion map) is not missed. The accumulated evidence is kept within
    [``min_evidence``, ``max_evidence``]. A track is confirmed once P(exists) reaches
    ``confirm_existence``, and ends below ``end_existence``: a visitor who walked to an exhibit and
    stands there keeps the evidence of the walk (standing adds nothing and takes nothing), a group
    walking with the robot stands on floor the laser saw free, and a chair seen from a still or a
    moving robot never was seen free. A track ends too when its samples spread beyond
    ``max_position_std`` (an occluded person lost for good), or leave ``max_range`` of the robot,
    or after ``max_unseen`` seconds without a detection, occluded or not (the occlusion map keeps a
    hidden person's track alive for a while, Fig. 7, but a track coasting longer drifts off the
    person and is a false alarm). The evidence values were chosen on the simulated scenes of the
    tests and the annotated positive bags, not on ``negative_2.bag``.
    With a ``pose_source`` (scan-matched poses) and ``map_without_people``, beams ending on a
    tracked person (tentative or confirmed) are left out of the map built on the fly.
    Two tracks nearer than ``merge_distance`` are one person: the younger ends (a person seen as
    two separate legs may start two). ``max_unseen`` (1.5 s) and ``merge_distance`` (0.35 m) were
    chosen on simulated crowds of 20 (crowd seeds 100-105, not
    those of the benchmark).
    """

    num_samples: int = 200
    measurement_std: float = 0.08
    single_leg_std: float = 0.15
    detection_probability: float = 0.9
    clutter_density: float = 0.02
    gate_sigmas: float = 4.0
    max_gate: float = 1.2
    max_events: int = 5000
    birth_threshold: float = 0.5
    birth_probability: float = 0.3
    birth_moving: float = 0.45
    free_moving: float = 0.6
    birth_off_map: bool = True
    birth_position_std: float = 0.08
    birth_velocity_std: float = 0.5
    existence_prior: float = 0.2
    free_evidence: float = 1.0
    hidden_evidence: float = 0.4
    still_evidence: float = -0.6
    static_evidence: float = -1.5
    shape_weight: float = 0.5
    shape_cap: float = 1.0
    miss_evidence: float = -1.0
    min_evidence: float = -4.0
    max_evidence: float = 8.0
    confirm_existence: float = 0.95
    end_existence: float = 0.1
    max_position_std: float = 1.0
    max_unseen: float = 1.5
    map_without_people: bool = True
    max_range: float = 8.0
    merge_distance: float = 0.35
    max_dt: float = 1.0
    walking: WalkingModel = field(default_factory=WalkingModel)
    legs: LegConfig = field(default_factory=LegConfig)
    occlusion: OcclusionConfig = field(default_factory=OcclusionConfig)
    static: StaticConfig = field(default_factory=StaticConfig)


@dataclass(frozen=True, slots=True)
class Track:
    """A person's track: the mean of its samples (Burgard et al. Sec. 4, Fig. 7), in the world frame.

    ``covariance`` is the ``(4, 4)`` sample covariance of ``(x, y, vx, vy)``; ``occluded`` says the
    person is currently hidden from the laser (its samples spreading out); ``existence`` is the
    probability that the track is a person (see :class:`SJPDAFConfig`).
    """

    id: int
    position: tuple[float, float]
    velocity: tuple[float, float]
    covariance: FloatArray
    confirmed: bool
    occluded: bool = False
    hits: int = 0
    age: int = 0
    existence: float = 0.0


@dataclass
class _TrackState:
    id: int
    evidence: float  # log odds of existence gathered from the scans, beyond the prior
    shape: float = 0.0  # the log odds of P(person) of the features, averaged over the hits
    hits: int = 0
    age: int = 0
    confirmed: bool = False
    occluded: bool = False
    unseen: float = 0.0  # seconds since the last detection

    def log_odds(self, config: SJPDAFConfig) -> float:
        prior = math.log(config.existence_prior / (1.0 - config.existence_prior))
        return prior + config.shape_weight * self.shape + self.evidence


@dataclass
class _Association:
    """What the correction step of one scan found: gated pairs, their betas, each person's beta_0."""

    pair_track: NDArray[np.int64]
    pair_feature: NDArray[np.int64]
    likelihood: FloatArray
    pair_beta: FloatArray
    beta0: FloatArray
    miss: FloatArray


class PeopleTracker:
    """The SJPDAF people tracker: feed scans with the robot's pose estimate, read the tracks."""

    def __init__(
        self,
        config: SJPDAFConfig | None = None,
        *,
        grid_map: OccupancyGrid | None = None,
        rng: np.random.Generator | None = None,
        pose_source: ScanPoseSource | None = None,
    ) -> None:
        self.config = config or SJPDAFConfig()
        self.rng = rng or np.random.default_rng(0)
        self.static = StaticFilter(self.config.static, grid_map)
        self.body = RobotBodyMask(self.config.static)
        self.pose_source = pose_source
        self.last_pose = np.zeros(3)
        self._samples = np.zeros((0, self.config.num_samples, 4))
        self._states: list[_TrackState] = []
        self._next_id = 1
        self._time: float | None = None
        self.last_legs = LegFeatures(np.zeros((0, 2)), np.zeros(0), np.zeros(0))
        self.last_features = PersonFeatures(np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2), dtype=np.int64))
        self.last_moving = np.zeros(0)  # P(moving) of each of ``last_features`` (static filter)

    # --- the algorithm ----------------------------------------------------------------------------

    def update(
        self, scan: Scan, robot_pose: FloatArray | tuple[float, float, float] | None = None
    ) -> list[Track]:
        """Integrate one scan taken at ``robot_pose`` (world frame); return all current tracks.

        With a ``pose_source`` (a recording without odometry) the pose comes from it instead and
        ``robot_pose`` must be None; the pose used is ``last_pose``.
        """
        if self.pose_source is not None:
            if robot_pose is not None:
                raise ValueError("a tracker with a pose_source takes its poses from it")
            pose = self.pose_source.match(scan)
        elif robot_pose is None:
            raise ValueError("robot_pose is needed without a pose_source")
        else:
            pose = np.asarray(robot_pose, dtype=np.float64)
        self.last_pose = pose
        dt = self._advance_time(scan.timestamp)
        features, moving, static = self._features(scan, pose)  # legs -> person features z_j(t), world frame
        self._predict(dt)  # p(x_i^t | x_i^{t-1}, dt) for every sample
        detect = self._detection_probability(scan, pose)  # P_D per sample, 0 where occluded
        assoc = self._associate(features, detect)  # Eq. 6-8 over gated clusters
        self._correct(assoc)  # Eq. 9 weights and bootstrap resampling
        self._manage(assoc, features, moving, static, detect, pose, dt)  # start, confirm, end tracks
        if self.pose_source is not None:
            # The scan joins the map built on the fly, but for the beams that end on a tracked
            # person, tentative or confirmed (Burgard et al. Sec. 5): a person walking where they
            # walked before, or slowly away from the laser, would otherwise stand on "static"
            # cells of their own making before the evidence could confirm them. A fixed object's
            # tentative track fades out (its cell seen occupied scan after scan), and the object
            # joins the map then.
            people = None
            if self.config.map_without_people and self._states:
                people = self._samples[..., 0:2].mean(axis=1)
            self.pose_source.integrate(scan, pose, people)
        return self.tracks()

    def tracks(self) -> list[Track]:
        """The current tracks (tentative ones too: check ``confirmed``)."""
        s = self._samples
        mean = s.mean(axis=1)
        centred = s - mean[:, None, :]
        cov = np.einsum("kni,knj->kij", centred, centred) / max(s.shape[1] - 1, 1)
        return [
            Track(
                id=st.id,
                position=(float(mean[k, 0]), float(mean[k, 1])),
                velocity=(float(mean[k, 2]), float(mean[k, 3])),
                covariance=cov[k],
                confirmed=st.confirmed,
                occluded=st.occluded,
                hits=st.hits,
                age=st.age,
                existence=1.0 / (1.0 + math.exp(-st.log_odds(self.config))),
            )
            for k, st in enumerate(self._states)
        ]

    def sample_sets(self) -> dict[int, FloatArray]:
        """Each track's samples ``(N, 4)`` by id (for people-filtered mapping, Eq. 10)."""
        return {st.id: self._samples[k].copy() for k, st in enumerate(self._states)}

    # --- steps ------------------------------------------------------------------------------------

    def _advance_time(self, t: float) -> float:
        dt = 0.0 if self._time is None else float(np.clip(t - self._time, 0.0, self.config.max_dt))
        self._time = t
        return dt

    def _features(self, scan: Scan, pose: FloatArray) -> tuple[PersonFeatures, FloatArray, FloatArray]:
        """The person features of ``scan`` in the world frame, each one's P(moving) (static
        filter: its cell seen free before) and whether it is on the static world built so far."""
        cfg = self.config
        legs = detect_legs(scan, cfg.legs)
        body = self.body.is_body(legs.points)  # the robot's own body, not a person's legs
        self.body.learn(legs.points, pose)
        if body.any():
            legs = LegFeatures(legs.points[~body], legs.width[~body], legs.probability[~body])
        sensor = compose(pose, np.asarray(scan.geometry.offset, dtype=np.float64))
        persons = group_legs(legs, cfg.legs).transformed(sensor)
        world_legs = LegFeatures(
            np.asarray(compose(sensor, np.c_[legs.points, np.zeros(len(legs))])[:, :2])
            if len(legs)
            else legs.points,
            legs.width,
            legs.probability,
        )
        leg_moving = self.static.moving_probability(world_legs.points, scan, pose)
        leg_static = np.zeros(len(legs), dtype=bool)
        if self.pose_source is not None:  # legs on the map built so far stand still
            leg_static = self.pose_source.on_map(world_legs.points)
            leg_moving[leg_static] = 0.0
        # A person moves when one of its legs does (the stance leg stands still while walking).
        m = persons.members
        moving = np.zeros(len(persons))
        static = np.zeros(len(persons))
        if len(persons):
            second = np.where(m[:, 1] >= 0, leg_moving[np.maximum(m[:, 1], 0)], 0.0)
            moving = np.maximum(leg_moving[m[:, 0]], second)
            # static when every leg of it is on the static world
            second_static = np.where(m[:, 1] >= 0, leg_static[np.maximum(m[:, 1], 0)], True)
            static = (leg_static[m[:, 0]] & second_static).astype(np.float64)
        # Features on the map are furniture: drop them (Burgard et al. Sec. 4, static objects).
        keep = ~self.static.on_map(persons.points)
        persons = PersonFeatures(persons.points[keep], persons.probability[keep], persons.members[keep])
        self.last_legs = world_legs
        self.last_features = persons
        self.last_moving = moving[keep]
        return persons, moving[keep], static[keep]

    def _predict(self, dt: float) -> None:
        if self._samples.shape[0] and dt > 0.0:
            noise = self.config.walking.noise(self.rng, self._samples.shape[:2])
            self._samples = predict_samples(self._samples, noise, dt, self.config.walking)

    def _detection_probability(self, scan: Scan, pose: FloatArray) -> FloatArray:
        K, N = self._samples.shape[:2]
        if K == 0:
            return np.zeros((0, N))
        local = points_in_sensor_frame(self._samples[..., 0:2].reshape(-1, 2), pose, scan)
        g = scan.geometry
        occluded = occlusion_probability(
            local, scan.ranges, g.angle_min, g.angle_increment, self.config.occlusion
        )
        return (self.config.detection_probability * (1.0 - occluded)).reshape(K, N)

    def _associate(self, persons: PersonFeatures, detect: FloatArray) -> _Association:
        cfg = self.config
        features = persons.points
        two_legs = persons.members[:, 1] >= 0
        sigma = np.where(two_legs, cfg.measurement_std, cfg.single_leg_std)
        K, N = self._samples.shape[:2]
        M = features.shape[0]
        miss = 1.0 - detect
        beta0 = np.ones(K)
        empty_i = np.zeros(0, dtype=np.int64)
        if K == 0 or M == 0:
            return _Association(empty_i, empty_i, np.zeros((0, N)), np.zeros(0), beta0, miss)
        # Gating: a feature near enough to the person's sample mean, given the samples' spread.
        mean = self._samples[..., 0:2].mean(axis=1)
        var = self._samples[..., 0:2].var(axis=1).sum(axis=1)
        gate = cfg.gate_sigmas * np.sqrt(var[:, None] + sigma[None, :] ** 2)
        dist = np.linalg.norm(mean[:, None, :] - features[None, :, :], axis=-1)
        pt, pf = np.nonzero(dist <= np.minimum(gate, cfg.max_gate))
        # Eq. 8: p(z_j | x_i) = 1/N sum_n p(z_j | x_{i,n}), with P_D folded in.
        lik = pair_likelihoods(self._samples, detect, features, pt, pf, sigma)
        mean_lik = lik.mean(axis=1)
        live = mean_lik > 1e-12
        pt, pf, lik, mean_lik = pt[live], pf[live], lik[live], mean_lik[live]
        q = miss.mean(axis=1)  # weight of "person i not detected"
        # Independent clusters of persons and features, each with its own joint events (Eq. 6-7).
        pair_beta, beta0 = cluster_betas(pt, pf, mean_lik / cfg.clutter_density, q, M, cfg.max_events)
        return _Association(pt, pf, lik, pair_beta, beta0, miss)

    def _correct(self, a: _Association) -> None:
        K = self._samples.shape[0]
        if K == 0:
            return
        w = sample_weights(a.likelihood, a.pair_track, a.pair_beta, a.miss, a.beta0)
        idx = systematic_resample_rows(w, self.rng.random(K))
        self._samples = np.take_along_axis(self._samples, idx[:, :, None], axis=1)

    def _feature_evidence(
        self, features: PersonFeatures, moving: FloatArray, static: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """The log odds each feature adds to the existence of a tentative and of a confirmed
        person it is assigned to: its cell seen free, hidden or occupied before, or on the static
        world (the shape is counted apart)."""
        cfg = self.config
        if cfg.birth_off_map and self.static.has_map:
            moving = np.ones(len(features))  # the map saw every cell off it free
        free = moving >= cfg.free_moving
        hidden = ~free & (moving >= 1.0 - cfg.free_moving)
        seen = np.where(free, cfg.free_evidence, np.where(hidden, cfg.hidden_evidence, 0.0))
        seen = seen + cfg.static_evidence * static
        still = np.where(free | hidden, 0.0, cfg.still_evidence)
        return seen + still, seen

    def _shape_log_odds(self, features: PersonFeatures) -> FloatArray:
        p = np.clip(features.probability, 1e-6, 1.0 - 1e-6)
        return np.clip(np.log(p / (1.0 - p)), -self.config.shape_cap, self.config.shape_cap)

    def _manage(
        self,
        a: _Association,
        features: PersonFeatures,
        moving: FloatArray,
        static: FloatArray,
        detect: FloatArray,
        pose: FloatArray,
        dt: float,
    ) -> None:
        cfg = self.config
        K = len(self._states)
        keep = np.ones(K, dtype=bool)
        visible = detect.mean(axis=1) > 0.5 * cfg.detection_probability if K else np.zeros(0, dtype=bool)
        spread = np.sqrt(self._samples[..., 0:2].var(axis=1).sum(axis=1)) if K else np.zeros(0)
        mean = self._samples[..., 0:2].mean(axis=1) if K else np.zeros((0, 2))
        far = np.linalg.norm(mean - pose[None, 0:2], axis=1) > cfg.max_range + 1.0
        evidence, confirmed_evidence = self._feature_evidence(features, moving, static)
        shape = self._shape_log_odds(features)
        # What the features explaining each person said, weighted by the betas (Eq. 6-7).
        gained = np.zeros(K)
        gained_confirmed = np.zeros(K)
        shaped = np.zeros(K)
        if K and a.pair_track.size:
            np.add.at(gained, a.pair_track, a.pair_beta * evidence[a.pair_feature])
            np.add.at(gained_confirmed, a.pair_track, a.pair_beta * confirmed_evidence[a.pair_feature])
            np.add.at(shaped, a.pair_track, a.pair_beta * shape[a.pair_feature])
        end = math.log(cfg.end_existence / (1.0 - cfg.end_existence))
        confirm = math.log(cfg.confirm_existence / (1.0 - cfg.confirm_existence))
        for k, st in enumerate(self._states):
            st.age += 1
            st.occluded = not bool(visible[k])
            detected = 1.0 - a.beta0[k]
            if a.beta0[k] < 0.5:
                st.hits += 1
                st.unseen = 0.0
                st.shape += (shaped[k] / max(detected, 1e-9) - st.shape) / st.hits
            else:
                st.unseen += dt
            # An occluded person is not missed: its samples just spread out (occlusion map).
            missed = a.beta0[k] * cfg.miss_evidence if visible[k] else 0.0
            said = gained_confirmed[k] if st.confirmed else gained[k]
            st.evidence = float(np.clip(st.evidence + said + missed, cfg.min_evidence, cfg.max_evidence))
            odds = st.log_odds(cfg)
            if odds >= confirm:
                st.confirmed = True
            lost = spread[k] > cfg.max_position_std or st.unseen > cfg.max_unseen
            if odds < end or lost or far[k]:
                keep[k] = False
        # Duplicates: two tracks on one person; the younger (fewer hits) ends.
        if K > 1:
            d = np.linalg.norm(mean[:, None] - mean[None, :], axis=-1)
            for i, j in zip(*np.nonzero(np.triu(d < cfg.merge_distance, k=1)), strict=True):
                if keep[i] and keep[j]:
                    older = (self._states[i].hits, -i) >= (self._states[j].hits, -j)
                    keep[j if older else i] = False
        # Births: features no person explains, that look like a person, on floor seen free before.
        M = len(features)
        explained = np.zeros(M)
        np.add.at(explained, a.pair_feature, a.pair_beta)
        born = (explained < cfg.birth_threshold) & (features.probability >= cfg.birth_probability)
        if not (cfg.birth_off_map and self.static.has_map):
            born &= moving >= cfg.birth_moving
        if K and M:
            near = np.linalg.norm(mean[keep][:, None] - features.points[None], axis=-1) < cfg.merge_distance
            born &= ~near.any(axis=0)
        self._samples = self._samples[keep]
        self._states = [st for st, k in zip(self._states, keep, strict=True) if k]
        new = np.flatnonzero(born)
        if new.size:
            N = cfg.num_samples
            s = np.empty((new.size, N, 4))
            s[..., 0:2] = features.points[new][
                :, None, :
            ] + cfg.birth_position_std * self.rng.standard_normal((new.size, N, 2))
            s[..., 2:4] = cfg.birth_velocity_std * self.rng.standard_normal((new.size, N, 2))
            self._samples = np.concatenate([self._samples, s], axis=0)
            for j in new.tolist():
                self._states.append(
                    _TrackState(id=self._next_id, evidence=float(evidence[j]), shape=float(shape[j]), hits=1)
                )
                self._next_id += 1
