"""The simulator: a tour-guide robot in a crowded exhibition site, as a drivable runtime source.

Each :meth:`Simulator.poll` advances the world by ``dt``: the base follows its command within its
limits (stopped by walls, doors, furniture and invisible obstacles, which count as collisions), the
crowd of visitors (``tourbot.sim.crowd``, the one crowd model) walks, doors and furniture change,
the wheel odometry accumulates its error, and at the laser's rate a scan is cast with the project's
one ray caster against the world and the visitors' legs (several robots in one museum share one
world: ``tourbot.sim.fleet``, the museum's world ``tourbot.sim.world`` stepping the one crowd); each
camera on the robot (``tourbot.sim.camera.SimCamera``: the upward ceiling camera, the forward
camera) renders its image when one is due. It returns the odometry reading, the scan and the
images as records; the truth (robot, people, doors, furniture, collisions) is kept beside them for
metrics only, and the whole sensor stream can be written as a CARMEN log.

Deterministic for a seed: the crowd, the odometry, the laser and the objects each draw from their
own generator spawned from one ``numpy.random.SeedSequence``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.objects import distance_to_segments
from tourbot.records import Image, Odometry, Record, RobotLog, Scan
from tourbot.robot import DiffDriveConfig
from tourbot.sim.crowd import Crowd, CrowdConfig
from tourbot.sim.fleet import FleetCrowd, FleetPoses, nearest
from tourbot.sim.laser import LaserConfig, SimLaser
from tourbot.sim.objects import DynamicObjects
from tourbot.sim.odometry import OdometryError, OdometryErrorConfig
from tourbot.sim.robot import DiffDrive
from tourbot.sim.world import site_crowd
from tourbot.site.model import TABLE_LEG_RADIUS, Site
from tourbot.snapshot import DoorState, FurnitureState, GroundTruth, PersonState

if TYPE_CHECKING:
    from tourbot.sim.camera import SimCamera

__all__ = ["Collisions", "SimConfig", "Simulator"]


@dataclass(frozen=True)
class SimConfig:
    """Everything the simulator needs besides the site; ``crowd=None`` means an empty museum."""

    dt: float = 0.1
    laser_rate: float = 10.0
    robot: DiffDriveConfig = field(default_factory=DiffDriveConfig)
    odometry: OdometryErrorConfig = field(default_factory=OdometryErrorConfig)
    laser: LaserConfig = field(default_factory=LaserConfig)
    crowd: CrowdConfig | None = None
    dynamic_objects: bool = True
    record: bool = False

    def __post_init__(self) -> None:
        if not self.dt > 0 or not self.laser_rate > 0:
            raise ValueError("SimConfig needs dt > 0 and laser_rate > 0")


@dataclass
class Collisions:
    """Collision events (contacts starting), by what was hit."""

    person: int = 0
    invisible: int = 0
    static: int = 0  # walls, doors, furniture
    robot: int = 0  # another robot of the fleet

    @property
    def total(self) -> int:
        return self.person + self.invisible + self.static + self.robot


class Simulator:
    """A drivable source (``tourbot.interfaces.DrivableSource``) over a site."""

    def __init__(
        self,
        site: Site,
        config: SimConfig | None = None,
        *,
        seed: int = 0,
        start: tuple[float, float, float] | None = None,
        cameras: Sequence[SimCamera] = (),
        fleet: tuple[FleetPoses, int] | None = None,
    ) -> None:
        self.site = site
        self.cameras: list[SimCamera] = list(cameras)
        # the other robots of the museum (sim.fleet): their bodies stand in this world
        self.fleet = fleet
        self.config = cfg = config or SimConfig()
        self.name = f"sim:{site.name}"
        self.dt = cfg.dt
        streams = np.random.SeedSequence(seed).spawn(4)
        self._rng_crowd, self._rng_odom, self._rng_laser, self._rng_objects = (
            np.random.default_rng(s) for s in streams
        )
        self.static = site.grid
        if start is None:
            start = site.exhibits[0].viewing_pose if site.exhibits else _some_free_pose(self.static)
        self.robot = DiffDrive(cfg.robot, start)
        self.odometry = OdometryError(cfg.odometry, start)
        self.objects = DynamicObjects(site, self.static, self._rng_objects, enabled=cfg.dynamic_objects)
        self._world = self.objects.grid()
        self.laser = SimLaser(cfg.laser, self.static)
        self._occupied = self._world.occupied()
        self._invisible = site.invisible_mask(self.static)
        # what the laser sees of the obstacles off its plane, derived from their height ranges
        self._seen_segments, self._seen_legs = _laser_parts(site, cfg.robot.laser_height)
        self._footprint = _disc_offsets(cfg.robot.radius, self.static.resolution)
        # a contact lasts while the robot stays this close: pushing on against an obstacle is one bump
        self._near = _disc_offsets(cfg.robot.radius + 0.05, self.static.resolution)
        self.crowd: Crowd | None = None
        # several robots in one museum: the museum's world (sim.world) steps the one crowd, every
        # robot's simulator sees it through the fleet's shared memory (sim.fleet)
        self._guest = fleet is not None
        self._shared: FleetCrowd | None = None
        if cfg.crowd is not None and not self._guest:
            self.crowd = Crowd(site_crowd(site, cfg.crowd), self.static, self._rng_crowd, robot_pose=start)
        if fleet is not None:
            fleet[0].write(fleet[1], self.robot.pose)  # here from the start: the world waits for it
        self._legs: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self._time = 0.0
        self._steps = 0
        self._scan_every = max(1, round(1.0 / (cfg.laser_rate * cfg.dt)))
        self.collisions = Collisions()
        self._in_contact = {"person": False, "invisible": False, "static": False, "robot": False}
        self.records: list[Scan | Odometry] = []
        self.truth_poses: list[tuple[float, float, float]] = []
        self.truth_times: list[float] = []
        self.people_history: list[NDArray[np.float64]] = []
        # per recorded scan: which beams returned from a visitor (ground truth for metrics)
        self.person_hit_history: list[NDArray[np.bool_]] = []
        # per camera (``config.record``): the images it took
        self.image_history: dict[str, list[Image]] = {}
        self.objects_history: list[tuple[tuple[DoorState, ...], tuple[FurnitureState, ...]]] = []
        self._show_world()

    def _show_world(self) -> None:
        """Hand the world grid (doors, furniture at their states) to the cameras that draw it."""
        from tourbot.sim.camera import WorldCamera

        for cam in self.cameras:
            if isinstance(cam, WorldCamera):
                cam.set_world(self._world)

    # -- DrivableSource ---------------------------------------------------------------------------

    @property
    def time(self) -> float:
        return self._time

    def command(self, speed: float, turn_rate: float) -> None:
        self.robot.command(speed, turn_rate)

    def poll(self) -> Sequence[Record] | None:
        """Advance one step; the odometry reading, at the laser rate a scan, and the images due."""
        dt = self.dt
        before = self.robot.pose
        others = self.fleet[0].others(self.fleet[1]) if self.fleet is not None else np.zeros((0, 2))
        self._move_robot(dt, others)
        if self.fleet is not None:
            th, v = self.robot.pose[2], self.robot.speed
            self.fleet[0].write(self.fleet[1], self.robot.pose, (v * math.cos(th), v * math.sin(th)))
        self._steps += 1
        self._time = round(self._steps * dt, 9)  # no drift from summing dt
        self._legs = None
        if self.crowd is not None:
            self.crowd.step(dt, self.robot.pose, self._rng_crowd)
        elif self._guest:
            assert self.fleet is not None
            self._shared = self.fleet[0].read_crowd() or self._shared
        self._check_people()
        if self.objects.step(self._time, dt, self._rng_objects):
            self._world = self.objects.grid()
            self._occupied = self._world.occupied()
            self._show_world()
        odom_pose = self.odometry.step(before, self.robot.pose, self._rng_odom)
        out: list[Record] = [Odometry(self._time, odom_pose, tv=self.robot.speed, rv=self.robot.turn_rate)]
        if self._steps % self._scan_every == 0:
            centres, radii = self.legs()
            people = len(radii)
            segments = self.objects.segments()
            if self._seen_segments.shape[1]:
                segments = np.concatenate([segments, self._seen_segments], axis=1)
            extra = [c for c in (self._seen_legs, others) if len(c)]
            if len(self._seen_legs):  # the legs of tables, and the other robots: seen, not as people
                radii = np.r_[radii, np.full(len(self._seen_legs), TABLE_LEG_RADIUS)]
            if len(others):
                radii = np.r_[radii, np.full(len(others), self.config.robot.radius)]
            if extra:
                centres = np.vstack([centres, *extra])
            ranges = self.laser.scan(
                self.robot.pose,
                centres,
                radii,
                self._rng_laser,
                people=people,
                segments=segments,
            )
            out.append(
                Scan(self._time, ranges, self.laser.geometry, odom=odom_pose, reference=self.robot.pose)
            )
            if self.config.record:
                self.truth_times.append(self._time)
                self.truth_poses.append(self.robot.pose)
                self.people_history.append(self.people_positions())
                self.person_hit_history.append(self.laser.last_person_hits.copy())
                self.objects_history.append((self.objects.door_states(), self.objects.furniture_states()))
        if self.cameras:
            people_now = self.people_positions()
            for cam in self.cameras:
                if cam.due(self._time):
                    frame = cam.frame(self._time, self.robot.pose, people_now)
                    image = Image(
                        self._time, frame.image, camera=cam.name, odom=odom_pose, reference=self.robot.pose
                    )
                    out.append(image)
                    if self.config.record:
                        self.image_history.setdefault(cam.name, []).append(image)
        if self.config.record:
            self.records.extend(r for r in out if not isinstance(r, Image))  # the log: no images
        return out

    def carry(self, pose: tuple[float, float, float]) -> None:
        """The robot is picked up and set down at ``pose`` (a kidnap: staff push it aside, a visitor
        carries it off). The wheels do not turn, so the odometry sees nothing; it stands there."""
        self.robot.apply((float(pose[0]), float(pose[1]), float(pose[2])), 0.0, 0.0)

    def truth(self) -> GroundTruth:
        pos = self.people_positions()
        if self.crowd is not None:
            vel = self.crowd.velocities
        else:
            vel = self._shared.velocities if self._shared is not None else np.zeros((0, 2))
        people = tuple(
            PersonState(i, float(p[0]), float(p[1]), float(v[0]), float(v[1]))
            for i, (p, v) in enumerate(zip(pos, vel, strict=True))
        )
        return GroundTruth(
            pose=self.robot.pose,
            people=people,
            doors=self.objects.door_states(),
            furniture=self.objects.furniture_states(),
            collisions=self.collisions.person + self.collisions.invisible,
        )

    # -- views ------------------------------------------------------------------------------------

    def legs(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """People's legs as circles (centres ``(K, 2)``, radii ``(K,)``); doors and furniture are
        :meth:`DynamicObjects.segments`. A robot of a fleet: the museum world's crowd."""
        if self.crowd is None:
            if self._shared is not None:
                return self._shared.centres, self._shared.radii
            return np.zeros((0, 2)), np.zeros(0)
        return self._crowd_circles()

    def _crowd_circles(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        assert self.crowd is not None
        if self._legs is None:
            self._legs = self.crowd.circles()
        return self._legs

    def people_positions(self) -> NDArray[np.float64]:
        if self.crowd is not None:
            return self.crowd.positions.copy()
        return self._shared.positions.copy() if self._shared is not None else np.zeros((0, 2))

    @property
    def world(self) -> OccupancyGrid:
        """The static grid with doors and furniture at their current states."""
        return self._world

    def to_robot_log(self) -> RobotLog:
        """The recorded sensor stream (``config.record``), scans carrying the true pose as reference."""
        log = RobotLog(source=self.name)
        for r in self.records:
            if isinstance(r, Scan):
                log.scans.append(r)
            else:
                log.odometry.append(r)
        return log

    # -- internals --------------------------------------------------------------------------------

    def _move_robot(self, dt: float, others: NDArray[np.float64]) -> None:
        pose, v, w = self.robot.propose(dt)
        radius = self.config.robot.radius
        leaves = self.objects.segments()[0, : 4 * len(self.objects.doors)]
        hit_door = distance_to_segments(pose[0], pose[1], leaves) < radius
        hit_static = hit_door or _covers(self._occupied, self.static, pose, self._footprint)
        hit_invisible = _covers(self._invisible, self.static, pose, self._footprint)
        here = self.robot.pose
        self._contact("static", hit_static, _covers(self._occupied, self.static, here, self._near))
        self._contact("invisible", hit_invisible, _covers(self._invisible, self.static, here, self._near))
        # another robot: two bases of this radius touch when their centres are 2 radii apart; a
        # step that moves away from it is always allowed (two robots set down touching part)
        gap_next, gap_now = nearest(others, pose[0], pose[1]), nearest(others, here[0], here[1])
        hit_robot = gap_next < 2 * radius and gap_next < gap_now
        self._contact("robot", hit_robot, gap_now < 2 * radius + 0.05)
        if hit_static or hit_invisible or hit_robot:
            # a bump: the base stops where it was (its bumper halts it)
            self.robot.halt()
        else:
            self.robot.apply(pose, v, w)

    def _check_people(self) -> None:
        centres, radii = self.legs()
        if not len(radii):
            self._contact("person", False)
            return
        x, y, _ = self.robot.pose
        d = np.hypot(centres[:, 0] - x, centres[:, 1] - y) - radii
        radius = self.config.robot.radius
        self._contact("person", bool(d.size and d.min() < radius), bool(d.size and d.min() < radius + 0.05))

    def _contact(self, kind: str, now: bool, near: bool = False) -> None:
        """Count a collision when a contact starts; it lasts while touching or still ``near``."""
        if now and not self._in_contact[kind]:
            setattr(self.collisions, kind, getattr(self.collisions, kind) + 1)
        self._in_contact[kind] = now or (self._in_contact[kind] and near)


def _laser_parts(site: Site, laser_height: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The edges ``(1, M, 4)`` of the obstacles whose outline spans the laser plane, and the centres
    ``(L, 2)`` of the table legs the laser sees (the rest of each obstacle it does not see)."""
    edges: list[list[float]] = []
    legs: list[tuple[float, float]] = []
    for obs in site.invisible_obstacles:
        if obs.laser_outline(laser_height):
            pts = obs.outline
            edges.extend([*a, *b] for a, b in zip(pts, pts[1:] + pts[:1], strict=True))
        legs.extend(obs.laser_legs(laser_height))
    seg = np.asarray(edges, dtype=np.float64).reshape(1, -1, 4)
    return seg, np.asarray(legs, dtype=np.float64).reshape(-1, 2)


def _disc_offsets(radius: float, resolution: float) -> NDArray[np.int64]:
    """``(row, col)`` offsets of the cells whose centres lie within ``radius`` of a cell's centre."""
    k = math.ceil(radius / resolution)
    rr, cc = np.mgrid[-k : k + 1, -k : k + 1]
    inside = np.hypot(rr, cc) * resolution <= radius
    return np.stack([rr[inside], cc[inside]], axis=-1).astype(np.int64)


def _covers(
    mask: NDArray[np.bool_], grid: OccupancyGrid, pose: tuple[float, float, float], disc: NDArray[np.int64]
) -> bool:
    """Whether the robot's footprint at ``pose`` covers a ``True`` cell of ``mask``."""
    ox, oy, oth = grid.origin
    c, s = math.cos(oth), math.sin(oth)
    dx, dy = pose[0] - ox, pose[1] - oy
    col = math.floor((c * dx + s * dy) / grid.resolution)
    row = math.floor((-s * dx + c * dy) / grid.resolution)
    rc = disc + np.array([row, col])
    ok = (rc[:, 0] >= 0) & (rc[:, 0] < mask.shape[0]) & (rc[:, 1] >= 0) & (rc[:, 1] < mask.shape[1])
    return bool(mask[rc[ok, 0], rc[ok, 1]].any())


def _some_free_pose(grid: OccupancyGrid) -> tuple[float, float, float]:
    d = ndimage.distance_transform_edt(grid.free())
    r, c = np.unravel_index(int(np.argmax(d)), d.shape)
    x, y = grid.cell_to_world(np.array([r, c]))
    return (float(x), float(y), 0.0)
