"""The navigator: global plan, local avoidance among people, blocked-time accounting, tours.

It implements the runtime's ``Navigator`` protocol and acts only on the snapshot's pose *estimate*
and the latest laser scan, never on the simulator's truth. Each control cycle:

1. dwell at an exhibit, or pick the goal (the current exhibit's viewing pose);
2. (re)plan on the inflated static + invisible-obstacle map when there is no path, every
   ``replan_period``, or after being blocked for ``replan_after`` (then with the obstacles the laser
   sees as temporary obstacles, so the plan goes around a crowd or a closed door);
3. follow the path: a carrot point ahead on it, the dynamic window among the laser's endpoints and
   the invisible obstacles; at the goal turn to the viewing heading;
4. keep account of the time blocked (the on-board face shows it), and give up a goal after
   ``give_up_after`` seconds blocked.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import transform_points
from tourbot.maps.grid import OccupancyGrid
from tourbot.navigation.avoidance import DWAConfig, DynamicWindow
from tourbot.navigation.planner import CostMap, NoPathError, PlannerConfig
from tourbot.navigation.tour import TourExecutor
from tourbot.records import Scan
from tourbot.robot import DiffDriveConfig
from tourbot.site.model import Site
from tourbot.snapshot import NavigationStatus, NavMode, StateSnapshot

__all__ = ["NavigationConfig", "SiteNavigator"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class NavigationConfig:
    """Navigator parameters (one home); the robot's limits come from ``robot``."""

    robot: DiffDriveConfig = field(default_factory=DiffDriveConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    dwa: DWAConfig = field(default_factory=DWAConfig)
    goal_tolerance: float = 0.25  # m
    heading_tolerance: float = 0.2  # rad
    lookahead: float = 1.0  # m: carrot distance along the path
    replan_period: float = 5.0  # s
    replan_after: float = 3.0  # s blocked before planning around what blocks the way
    give_up_after: float = 90.0  # s blocked on one goal before skipping it
    obstacle_range: float = 3.0  # m: laser points farther than this do not matter to the window
    crawl_speed: float = 0.1  # m/s: creeping slower than this among people counts as blocked
    map_tolerance: float = 0.15  # m: laser points this close to a mapped obstacle are the map's
    dwell_scale: float = 1.0  # scales the exhibits' dwell times (short demos)
    # the site's hand-drawn map of the obstacles the laser cannot see (the paper's baseline); off
    # when the forward camera finds them (an estimator publishing "obstacles", tourbot.runtime.vision)
    hand_drawn: bool = True
    replan_on_obstacles: float = 1.0  # s: at most this often, replan when new published obstacles appear


class SiteNavigator:
    """Drives a robot around a :class:`~tourbot.site.model.Site` (see the module docstring)."""

    def __init__(self, site: Site, config: NavigationConfig | None = None) -> None:
        self.site = site
        self.config = cfg = config or NavigationConfig()
        planner_cfg = cfg.planner
        if planner_cfg.robot_radius != cfg.robot.radius:
            from dataclasses import replace

            planner_cfg = replace(planner_cfg, robot_radius=cfg.robot.radius)
        self._planner_config = planner_cfg
        self._hand = hand = site.invisible_mask() if cfg.hand_drawn else None
        self.costmap = CostMap(site.grid, planner_cfg, invisible=hand)
        # the static map's plan: the fallback when the world as estimated has no way through
        self._static_costmap = self.costmap
        self.map_changes = 0
        self._invisible_points = _outline_points(site, spacing=0.05) if cfg.hand_drawn else np.zeros((0, 2))
        self._published: FloatArray = np.zeros((0, 2))
        self._published_planned = 0
        r = cfg.robot
        self.window = DynamicWindow(
            cfg.dwa,
            radius=r.radius,
            max_speed=r.max_speed,
            max_turn_rate=r.max_turn_rate,
            max_accel=r.max_accel,
            max_turn_accel=r.max_turn_accel,
        )
        self.tours = TourExecutor(site, cfg.dwell_scale)
        self.goal: tuple[float, float, float] | None = None
        self.path: FloatArray | None = None
        self.mode = NavMode.IDLE
        self.message = ""
        self.blocked_time = 0.0
        self.total_blocked_time = 0.0
        self._since_plan = 0.0
        self._cmd = (0.0, 0.0)
        self._blocked_on_goal = 0.0
        self._path_key: FloatArray | None = None
        self._path_view: tuple[tuple[float, float], ...] = ()

    # -- Navigator protocol -----------------------------------------------------------------------

    def send_goal(self, goal: tuple[float, float, float]) -> None:
        self.tours.cancel()
        self._set_goal(goal)

    def start_tour(self, tour: str) -> None:
        exhibit = self.tours.start(tour)
        self._set_goal(exhibit.viewing_pose)

    def stop(self) -> None:
        self.tours.cancel()
        self.goal = None
        self.path = None
        self.mode = NavMode.IDLE
        self.blocked_time = 0.0
        self._cmd = (0.0, 0.0)

    def status(self) -> NavigationStatus:
        t = self.tours.state
        if self._path_key is not self.path:
            self._path_key = self.path
            self._path_view = ()
            if self.path is not None and len(self.path):
                thin = np.vstack([self.path[:: max(1, len(self.path) // 60)], self.path[-1:]])
                self._path_view = tuple(tuple(p) for p in thin.tolist())
        path = self._path_view
        return NavigationStatus(
            mode=self.mode,
            goal=self.goal,
            tour=None if t is None else t.name,
            current_exhibit=None if t is None or t.current is None else t.current.name,
            exhibit_index=0 if t is None else t.index,
            exhibits_total=0 if t is None else len(t.exhibits),
            visited=() if t is None else tuple(t.visited),
            path=path,
            blocked_time=self.blocked_time,
            total_blocked_time=self.total_blocked_time,
            speed=self._cmd[0],
            turn_rate=self._cmd[1],
            message=self.message,
        )

    def control(self, snapshot: StateSnapshot, scan: Scan | None, dt: float) -> tuple[float, float]:
        self._cmd = self._control(snapshot, scan, dt)
        return self._cmd

    def set_map(self, grid: OccupancyGrid) -> None:
        """Plan on ``grid`` from now on (the site with its doors and furniture in their estimated
        states, :class:`tourbot.objects.world.ObjectWorld`) and replan at the next cycle: a door
        found closed on the path, or a bench moved into a passage, is planned around at once."""
        self.costmap = CostMap(grid, self._planner_config, invisible=self._hand)
        self.map_changes += 1
        if self.goal is not None:
            self.path = None

    # -- internals --------------------------------------------------------------------------------

    def _set_goal(self, goal: tuple[float, float, float]) -> None:
        self.goal = (float(goal[0]), float(goal[1]), float(goal[2]))
        self.path = None
        self.mode = NavMode.NAVIGATING
        self.blocked_time = 0.0
        self._blocked_on_goal = 0.0
        self.message = ""

    def _next_exhibit_or_finish(self, exhibit: object) -> None:
        if exhibit is None:
            self.goal, self.path = None, None
            self.mode = NavMode.FINISHED
            t = self.tours.state
            skipped = f", skipped {', '.join(t.skipped)}" if t and t.skipped else ""
            self.message = f"tour finished{skipped}"
        else:
            self._set_goal(exhibit.viewing_pose)  # type: ignore[attr-defined]

    def _control(  # noqa: PLR0911  (one return per situation reads best)
        self, snapshot: StateSnapshot, scan: Scan | None, dt: float
    ) -> tuple[float, float]:
        t = self.tours.state
        if t is not None and t.dwelling:
            return self._dwell(dt)
        if self.goal is None or snapshot.pose is None:
            return 0.0, 0.0
        pose = snapshot.pose.pose
        if math.hypot(self.goal[0] - pose[0], self.goal[1] - pose[1]) < self.config.goal_tolerance:
            return self._at_goal(pose)
        self._since_plan += dt
        self._published = _published_obstacles(snapshot)
        points = self._obstacle_points(pose, scan)
        fresh = (
            len(self._published) != self._published_planned
            and self._since_plan >= self.config.replan_on_obstacles
        )
        if (self.path is None or self._since_plan >= self.config.replan_period or fresh) and not self._plan(
            pose
        ):
            return 0.0, 0.0
        carrot = self._carrot(pose)
        bearing = math.atan2(carrot[1], carrot[0])
        speed, turn, moving = self.window.choose(self._cmd[0], self._cmd[1], carrot, points)
        if abs(bearing) > 1.2:
            # the path turns back: turn on the spot first (a round robot can)
            self._unblocked()
            return 0.0, math.copysign(self.config.robot.max_turn_rate * 0.8, bearing)
        crawl = self.config.crawl_speed
        if moving and speed >= crawl:
            self._unblocked()
            return speed, turn
        if (
            moving
            and self.window.choose(self._cmd[0], self._cmd[1], carrot, self._mapped(pose, points))[0] < crawl
        ):
            # as slow with only what the map explains (walls, a narrow door, starting up): not blocked
            self._unblocked()
            return speed, turn
        if moving:
            # creeping between people: the way is as good as blocked (the face shows it), but the
            # robot makes progress, so no replanning and no giving up
            self.mode = NavMode.BLOCKED
            self.blocked_time += dt
            self.total_blocked_time += dt
            self.message = f"slowed by people for {self.blocked_time:.0f} s"
            return speed, turn
        return self._blocked(dt, pose, points, turn)

    def _dwell(self, dt: float) -> tuple[float, float]:
        self.mode = NavMode.DWELLING
        nxt = self.tours.dwell(dt)
        if nxt is not True:
            self._next_exhibit_or_finish(nxt)
        return 0.0, 0.0

    def _at_goal(self, pose: tuple[float, float, float]) -> tuple[float, float]:
        """Within the goal tolerance: turn to the viewing heading, then arrive."""
        assert self.goal is not None
        err = math.remainder(self.goal[2] - pose[2], 2 * math.pi)
        if abs(err) > self.config.heading_tolerance:
            self.mode = NavMode.NAVIGATING
            limit = self.config.robot.max_turn_rate
            return 0.0, float(np.clip(1.5 * err, -limit, limit))
        return self._arrived()

    def _arrived(self) -> tuple[float, float]:
        self.path = None
        if self.tours.state is not None:
            self.tours.arrived()
            self.mode = NavMode.DWELLING
        else:
            self.goal = None
            self.mode = NavMode.FINISHED
            self.message = "goal reached"
        self.blocked_time = 0.0
        return 0.0, 0.0

    def _unblocked(self) -> None:
        self.mode = NavMode.NAVIGATING
        self.blocked_time = 0.0

    def _blocked(
        self, dt: float, pose: tuple[float, float, float], points: FloatArray, turn: float = 0.0
    ) -> tuple[float, float]:
        """No way forward: wait, replan around what the laser sees, give up after a while."""
        self.mode = NavMode.BLOCKED
        self.blocked_time += dt
        self.total_blocked_time += dt
        self._blocked_on_goal += dt
        if self._blocked_on_goal >= self.config.give_up_after:
            return self._give_up(f"blocked for {self._blocked_on_goal:.0f} s")
        if self.blocked_time >= self.config.replan_after and self._since_plan >= self.config.replan_after:
            world = transform_points(np.asarray(pose), points) if len(points) else np.zeros((0, 2))
            self._plan(pose, extra=world)
        self.message = f"waiting: way blocked for {self.blocked_time:.0f} s"
        return 0.0, turn

    def _give_up(self, why: str) -> tuple[float, float]:
        if self.tours.state is not None:
            name = self.tours.state.current.name if self.tours.state.current else "?"
            self.message = f"skipped {name}: {why}"
            nxt = self.tours.skip()
            self._next_exhibit_or_finish(nxt)
            if nxt is not None:
                self.message = f"skipped {name}: {why}"
        else:
            self.goal, self.path = None, None
            self.mode = NavMode.FAILED
            self.message = f"gave up the goal: {why}"
        return 0.0, 0.0

    def _plan(self, pose: tuple[float, float, float], extra: FloatArray | None = None) -> bool:
        assert self.goal is not None
        self._since_plan = 0.0
        self._published_planned = len(self._published)
        if len(self._published):
            extra = (
                self._published if extra is None or not len(extra) else np.vstack([extra, self._published])
            )
        costmap = self.costmap if extra is None or not len(extra) else self.costmap.with_obstacles(extra)
        try:
            self.path = costmap.plan(pose[:2], self.goal[:2])
        except NoPathError:
            if extra is None:
                if self.costmap is not self._static_costmap and self._plan_static(pose):
                    return True
                self.path = None
                self._give_up("no path")
                return False
            return self.path is not None  # keep the old path if going around the crowd fails
        return True

    def _plan_static(self, pose: tuple[float, float, float]) -> bool:
        """A path on the static map, when the estimated world (a door found closed some time ago)
        leaves none: the door may have been opened since, so go and look."""
        assert self.goal is not None
        try:
            self.path = self._static_costmap.plan(pose[:2], self.goal[:2])
        except NoPathError:
            return False
        return True

    def _mapped(self, pose: tuple[float, float, float], points: FloatArray) -> FloatArray:
        """The obstacle points (robot frame) the static map explains: walls, not people.

        A point within ``map_tolerance`` of a mapped obstacle is the map's: the pose estimate is a
        few centimetres off and a wall's endpoints fall partly into the free cell beside it.
        """
        if not len(points):
            return points
        world = transform_points(np.asarray(pose), points)
        on_map = self.costmap.clearance_at(world) <= self.config.map_tolerance
        return np.ascontiguousarray(points[on_map])

    def _carrot(self, pose: tuple[float, float, float]) -> tuple[float, float]:
        """The point ``lookahead`` metres ahead along the path, in the robot frame."""
        assert self.path is not None
        p = self.path
        d = np.hypot(p[:, 0] - pose[0], p[:, 1] - pose[1])
        i = int(np.argmin(d))
        seg = np.hypot(np.diff(p[i:, 0]), np.diff(p[i:, 1]))
        along = np.r_[0.0, np.cumsum(seg)]
        j = i + int(np.searchsorted(along, self.config.lookahead))
        target = p[min(j, len(p) - 1)]
        c, s = math.cos(pose[2]), math.sin(pose[2])
        dx, dy = target[0] - pose[0], target[1] - pose[1]
        return (c * dx + s * dy, -s * dx + c * dy)

    def _obstacle_points(self, pose: tuple[float, float, float], scan: Scan | None) -> FloatArray:
        """Laser endpoints and invisible-obstacle points within ``obstacle_range``, robot frame."""
        rng = self.config.obstacle_range
        parts = []
        if scan is not None:
            g = scan.geometry
            r = scan.ranges
            ok = (r < min(g.max_range, rng)) & (r > g.min_range)
            if g.num_beams > 180:  # half a degree apart is more than the window needs
                ok[1::2] = False
            a = g.angles[ok] + g.offset[2]
            pts = np.stack([r[ok] * np.cos(a), r[ok] * np.sin(a)], axis=-1)
            parts.append(transform_points(np.asarray(g.offset), pts) if any(g.offset) else pts)
        inv = self._invisible_points
        if len(self._published):
            inv = np.vstack([inv, self._published])
        if len(inv):
            near = np.hypot(inv[:, 0] - pose[0], inv[:, 1] - pose[1]) < rng
            if near.any():
                c, s = math.cos(pose[2]), math.sin(pose[2])
                dx, dy = inv[near, 0] - pose[0], inv[near, 1] - pose[1]
                parts.append(np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1))
        if not parts:
            return np.zeros((0, 2))
        return np.ascontiguousarray(np.vstack(parts))


def _published_obstacles(snapshot: StateSnapshot) -> FloatArray:
    """The obstacle points (world) the estimators publish (``"obstacles"``: the forward camera's)."""
    parts = [
        np.asarray(extra["obstacles"], dtype=np.float64).reshape(-1, 2)
        for extra in (snapshot.estimators or {}).values()
        if isinstance(extra, dict) and len(extra.get("obstacles", ()))
    ]
    return np.vstack(parts) if parts else np.zeros((0, 2))


def _outline_points(site: Site, spacing: float) -> FloatArray:
    """Points every ``spacing`` metres along the edges of the site's invisible obstacles."""
    out = []
    for obs in site.invisible_obstacles:
        poly = np.asarray(obs.outline + obs.outline[:1], dtype=np.float64)
        for a, b in itertools.pairwise(poly):
            n = max(2, math.ceil(np.hypot(*(b - a)) / spacing) + 1)
            out.append(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
    return np.vstack(out) if out else np.zeros((0, 2))
