"""A ready-wired runtime on the simulator: a site, a crowd, Monte Carlo localization, the navigator.

This is what ``tourbot demo``, ``tourbot bench sim`` and the web server (``tourbot serve``) run:
the robot localizes with Monte Carlo localization on the site's static map (which knows nothing of
the people, the doors' states or where the benches are now) and navigates on that estimate. With
``ceiling=True`` the robot also carries the upward camera of Gamallo et al.: the simulator renders
its images from the site's ceiling lights at 1 Hz and MCL weighs its samples with them
(:class:`tourbot.ceiling.likelihood.CeilingSensor`). With ``objects=True`` the robot estimates its
site's doors and furniture (Schulz and Burgard 2001, :mod:`tourbot.objects`) from every scan and
MCL's samples, and both MCL and the navigator use the map with them drawn in their estimated states
(:class:`tourbot.objects.world.ObjectWorld`): a door found closed is planned around.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from tourbot.errors import InputError
from tourbot.geometry import wrap_angle
from tourbot.interfaces import Estimator, Sink
from tourbot.localization.mcl.config import MCLConfig
from tourbot.navigation.navigator import NavigationConfig, SiteNavigator
from tourbot.navigation.planner import CostMap
from tourbot.runtime.localizers import MCLLocalizer, UpdatePolicy
from tourbot.runtime.loop import Runtime, RuntimeConfig
from tourbot.runtime.sinks import MetricsSink, Recorder
from tourbot.sim.crowd import PRESETS, CrowdConfig, CrowdError
from tourbot.sim.fleet import FleetPoses
from tourbot.sim.simulator import SimConfig, Simulator
from tourbot.site.model import Site

if TYPE_CHECKING:
    from tourbot.localization.mcl import MonteCarloLocalization
    from tourbot.maps.grid import OccupancyGrid
    from tourbot.objects.world import ObjectWorld
    from tourbot.sim.camera import SimCamera

__all__ = [
    "CAMERAS",
    "KidnapRun",
    "SimulatedRobot",
    "SimulationSettings",
    "camera_names",
    "carry_destination",
    "crowd_config",
    "kidnap_run",
    "simulated_runtime",
    "time_to_recover",
]

# The cameras a simulated robot can carry: the upward camera of Gamallo et al. (its images fused
# into MCL) and the forward obstacle camera (its detector beside the laser).
CAMERAS = ("ceiling", "forward")


def crowd_config(crowd: str | int) -> CrowdConfig | None:
    """A crowd preset by name (``empty``, ``sparse``, ``peak``) or a number of visitors."""
    if isinstance(crowd, int) or str(crowd).isdigit():
        n = int(crowd)
        if n < 0:
            raise CrowdError(f"a crowd of {n} visitors: the number must be 0 or more")
        return None if n == 0 else replace(CrowdConfig.preset("sparse"), num_people=n, density=None)
    if str(crowd) not in PRESETS:
        raise CrowdError(
            f"unknown crowd {crowd!r}; choose {', '.join(PRESETS)} or a number of visitors (0 or more)"
        )
    cfg = CrowdConfig.preset(str(crowd))
    empty = (cfg.density is None and cfg.num_people == 0) or cfg.density == 0
    return None if empty else cfg


def camera_names(values: Iterable[str], *, field: str = "cameras") -> tuple[str, ...]:
    """The camera names in ``values`` (each one name or a comma list), checked against
    :data:`CAMERAS`, each once, in the order given; an unknown one is an :class:`InputError` of
    ``field``."""
    out: list[str] = []
    for value in values:
        for name in (v.strip() for v in value.split(",")):
            if name not in CAMERAS:
                raise InputError(f"unknown camera {name!r}; choose {' or '.join(CAMERAS)}", field=field)
            if name not in out:
                out.append(name)
    return tuple(out)


@dataclass(frozen=True)
class SimulationSettings:
    """Knobs of a simulated run (one home); defaults are the demo's."""

    crowd: str | int = "peak"
    seed: int = 0
    # The robot's Monte Carlo localization: the one configuration of the estimator (its defaults,
    # or a profile loaded with --config; tourbot.localization.profile).
    mcl: MCLConfig = field(default_factory=MCLConfig)
    localization: UpdatePolicy = field(default_factory=UpdatePolicy)
    sim: SimConfig = field(default_factory=SimConfig)
    navigation: NavigationConfig = field(default_factory=NavigationConfig)
    speedup: float | None = None
    # the upward ceiling camera, rendered and fused into MCL (the site needs ceiling lights)
    ceiling: bool = False
    # the forward camera and its obstacle detector (tourbot.runtime.vision) feeding the navigator
    vision: bool = False
    # the doors' and furniture's states estimated and fed back to MCL's and the navigator's map
    objects: bool = False
    # the people tracker on the laser (its tracks in the snapshot); always on with ``vision``,
    # whose detector masks the tracker's visitors: one tracker per robot
    people: bool = False
    record_every: int = 5  # keep every 5th snapshot (0.5 s): enough for the animation, small files

    def carrying(self, cameras: Iterable[str]) -> SimulationSettings:
        """These settings with the robot carrying (and using) the named cameras of :data:`CAMERAS`
        and no other."""
        names = camera_names(cameras)
        return replace(self, ceiling="ceiling" in names, vision="forward" in names)


@dataclass
class SimulatedRobot:
    """The runtime and the parts a caller may want to look at."""

    runtime: Runtime
    simulator: Simulator
    navigator: SiteNavigator
    metrics: MetricsSink
    recorder: Recorder | None
    objects: ObjectWorld | None = None


def simulated_runtime(
    site: Site,
    settings: SimulationSettings | None = None,
    *,
    start: tuple[float, float, float] | None = None,
    record: bool = True,
    sinks: tuple[Sink, ...] = (),
    fleet: tuple[FleetPoses, int] | None = None,
) -> SimulatedRobot:
    """Wire simulator -> MCL -> navigator -> sinks on ``site``; ``fleet``: the shared poses of the
    museum's robots and this one's index (``tourbot.sim.fleet``)."""
    s = settings or SimulationSettings()
    sim_cfg = replace(s.sim, crowd=crowd_config(s.crowd), robot=s.navigation.robot)
    ceiling = None
    cameras: list[SimCamera] = []
    estimators: list[Estimator] = []
    if s.ceiling:
        import numpy as np

        from tourbot.ceiling.likelihood import CeilingSensor
        from tourbot.ceiling.rig import CeilingCamera
        from tourbot.sim.camera import CeilingCameraSim

        rig = CeilingCamera()
        cameras.append(CeilingCameraSim(site, rig, seed=s.seed))  # an error if the site has no lights
        lights = np.array([light.position for light in site.ceiling_lights], dtype=np.float64)
        ceiling = CeilingSensor(rig, lights, site.grid, seed=s.seed)
    tracker = None
    if s.people or s.vision:
        import numpy as np

        from tourbot.people.estimator import PeopleEstimator

        tracker = PeopleEstimator(grid_map=site.grid, rng=np.random.default_rng(s.seed))
        estimators.append(tracker)
    if s.vision:
        from tourbot.runtime.vision import VisionObstacleEstimator
        from tourbot.sim.camera import ForwardCameraSim

        forward = ForwardCameraSim(site, seed=s.seed)
        cameras.append(forward)
        estimators.append(VisionObstacleEstimator(site.grid, forward.camera, people=tracker))
    from tourbot.localization.mcl import MonteCarloLocalization

    simulator = Simulator(site, sim_cfg, seed=s.seed, start=start, cameras=cameras, fleet=fleet)
    mcl = MonteCarloLocalization(site.grid, s.mcl, seed=s.seed)
    # the robot starts at a known place (its docking station), as in the paper's tracking runs
    mcl.reset_tracking(simulator.robot.pose)
    navigator = SiteNavigator(site, s.navigation)
    world = None
    if s.objects and (site.doors or site.furniture):
        world = _object_estimator(site, sim_cfg.laser.max_range, mcl, navigator, estimators, s.seed)
    metrics = MetricsSink()
    recorder = Recorder(every=s.record_every) if record else None
    all_sinks: list[Sink] = [metrics, *sinks]
    if recorder is not None:
        all_sinks.append(recorder)
    runtime = Runtime(
        simulator,
        MCLLocalizer(mcl, s.localization, seed=s.seed, ceiling=ceiling),
        estimators=estimators,
        navigator=navigator,
        sinks=all_sinks,
        site=site.name,
        config=RuntimeConfig(speedup=s.speedup),
    )
    return SimulatedRobot(runtime, simulator, navigator, metrics, recorder, world)


def _object_estimator(
    site: Site,
    max_range: float,
    mcl: MonteCarloLocalization,
    navigator: SiteNavigator,
    estimators: list[Estimator],
    seed: int,
) -> ObjectWorld:
    """The object state estimator on every scan, its world feeding MCL's and the navigator's map."""
    from tourbot.maps.objects import shapes_of_site
    from tourbot.maps.raycast import DistanceCaster
    from tourbot.objects.estimator import ObjectStateEstimator
    from tourbot.objects.runtime import ObjectsEstimator
    from tourbot.objects.world import ObjectWorld

    shapes = shapes_of_site(site.doors, site.furniture)
    estimator = ObjectStateEstimator(shapes, DistanceCaster(site.grid, max_range), seed=seed)
    world = ObjectWorld(site.grid, shapes, [mcl, navigator])
    angles = {d.name: d.opening_angle for d in site.doors}
    estimators.append(ObjectsEstimator(estimator, angles, world=world))
    return world


def time_to_recover(
    robot: SimulatedRobot,
    window: float,
    *,
    distance: float = 0.3,
    heading: float = math.radians(10.0),
    hold: float = 3.0,
) -> float | None:
    """Step ``robot`` until its estimate is within ``distance`` metres and ``heading`` radians of
    the truth and stays there for ``hold`` seconds; the seconds from now until it got there, or
    None if that does not happen within ``window`` seconds (or the source ends)."""
    rt = robot.runtime
    start = rt.source.time
    since: float | None = None
    while rt.source.time < start + window:
        snap = rt.step()
        if snap is None:
            return None
        error = snap.position_error
        good = (
            error is not None
            and snap.pose is not None
            and snap.truth is not None
            and error <= distance
            and abs(float(wrap_angle(snap.pose.theta - snap.truth.pose[2]))) <= heading
        )
        if not good:
            since = None
            continue
        since = snap.time if since is None else since
        if snap.time - since >= hold:
            return since - start
    return None


@dataclass(frozen=True)
class KidnapRun:
    """One kidnap in the simulator: where from and to, and the seconds until the robot was found
    again (None: not within the window)."""

    seed: int
    touring: bool
    time: float
    source: tuple[float, float, float]
    destination: tuple[float, float, float]
    recovered: float | None
    collisions: int


def carry_destination(
    world: OccupancyGrid, pose: tuple[float, float, float], distance: float, rng: np.random.Generator
) -> tuple[float, float, float]:
    """A pose the robot could stand at in ``world`` (the site with its doors and furniture as they
    are now: a traversable cell of the planner's :class:`CostMap`), ``distance`` +- 0.5 m from
    ``pose``, any heading."""
    costmap = CostMap(world)
    for _ in range(100_000):
        r = distance + rng.uniform(-0.5, 0.5)
        bearing = rng.uniform(-math.pi, math.pi)
        cand = (
            pose[0] + r * math.cos(bearing),
            pose[1] + r * math.sin(bearing),
            float(rng.uniform(-math.pi, math.pi)),
        )
        if costmap.traversable(cand):
            return cand
    raise ValueError(f"no free pose {distance} m from {pose}")


def kidnap_run(
    site: Site,
    settings: SimulationSettings,
    start: tuple[float, float, float],
    tour: str | None,
    at: float,
    spread: float,
    distance: float,
    window: float,
) -> KidnapRun:
    """A kidnap experiment: stand (``tour`` None) or tour until ``at`` + U(0, ``spread``) seconds
    (the kidnap falls anywhere between two of the localizer's verifications), carry the robot
    ``distance`` metres off (:meth:`Simulator.carry`, to :func:`carry_destination`), and time its
    recovery (:func:`time_to_recover`, up to ``window`` seconds). Its draws come from
    ``settings.seed`` and whether it tours."""
    rng = np.random.default_rng([settings.seed, int(tour is None)])
    at += rng.uniform(0.0, spread)
    robot = simulated_runtime(site, settings, start=start, record=False)
    rt = robot.runtime
    if tour is not None:
        rt.start_tour(tour)
    while rt.source.time < at and rt.step() is not None:
        pass
    here = robot.simulator.robot.pose
    there = carry_destination(robot.simulator.world, here, distance, rng)
    robot.simulator.carry(there)
    recovered = time_to_recover(robot, window)
    c = robot.simulator.collisions
    rt.close()
    return KidnapRun(settings.seed, tour is not None, at, here, there, recovered, c.person + c.invisible)
