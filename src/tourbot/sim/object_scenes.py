"""The three experiments of Schulz and Burgard (2001, Sec. 4) as simulated sites and drives.

- :func:`corridor_scene`: a corridor with 14 doors (Sec. 4.1, Fig. 3-5), seven a side, each into
  an office, in the paper's states (Fig. 5's exact values: 0, 30, 38, 58 or 90 degrees open),
  passed at 0.7 m/s.
- :func:`ushape_scene`: a 37 x 37 cm U-shaped object in a corridor (Sec. 4.2, Fig. 6-7), passed
  twice, then turned by 30 degrees and passed again.
- :func:`door_tour_site`: beyond the paper, two exhibition halls joined by two doorways with
  doors that open and close at random and a long way round; a tour crosses between the halls.
- :func:`desk_scene`: two offices with four desks shifted 20 cm towards the rooms' centres from
  where the model has them (Sec. 4.3, Fig. 8); desk-3 stands behind a small square table that
  the model knows and a chair that it does not (only the simulated world has it).

Each scene gives the site the simulator runs (the world), the site the robot's model is (the
estimator's: the same but for unmodelled clutter and for where the furniture is believed to
be), the scripted drive (speed and turn-rate commands, open loop), and the object changes over
time (scene time -> states). Everything is plain data; :func:`run_scene` drives the simulator and
returns the recorded log with the true object states at every scan.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tourbot.records import RobotLog
from tourbot.site.model import Site, site_from_dict

__all__ = [
    "DOOR_STATES_DEG",
    "Scene",
    "SceneRun",
    "corridor_scene",
    "desk_scene",
    "door_tour_site",
    "run_scene",
    "ushape_scene",
]

# Fig. 5's exact values, as opening angles from closed (world-model orientation minus 180 deg,
# or 180 minus it for the door opening the other way)
DOOR_STATES_DEG = (0, 90, 38, 90, 0, 0, 0, 90, 90, 0, 0, 30, 58, 0)
SPEED = 0.7  # m/s on the straight parts (Sec. 4.1)


@dataclass(frozen=True)
class Scene:
    """A simulated experiment: the world, the model, the drive and the object changes."""

    name: str
    world: Site
    model: Site
    start: tuple[float, float, float]
    drive: list[tuple[float, float, float]]  # (duration s, speed m/s, turn rate rad/s)
    changes: list[tuple[float, dict[int, float], dict[int, int]]] = field(default_factory=list)
    initial: tuple[dict[int, float], dict[int, int]] = field(default_factory=lambda: ({}, {}))

    @property
    def duration(self) -> float:
        return float(sum(d for d, _, _ in self.drive))


@dataclass
class SceneRun:
    """A recorded run: the sensor log (scans carry the true pose as reference) and the truth."""

    log: RobotLog
    truth: list[list[NDArray[np.float64]]]  # per scan, the true state of every object
    times: NDArray[np.float64]


def _box(x0: float, y0: float, x1: float, y1: float) -> list[list[float]]:
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]


def _wall_x(y: float, x0: float, x1: float, gaps: list[tuple[float, float]], t: float = 0.05) -> list[Any]:
    """A wall along x at ``y`` from ``x0`` to ``x1`` with door gaps, as thin boxes."""
    out, x = [], x0
    for a, b in sorted(gaps):
        if a > x:
            out.append(_box(x, y - t / 2, a, y + t / 2))
        x = b
    if x1 > x:
        out.append(_box(x, y - t / 2, x1, y + t / 2))
    return out


def corridor_scene(states_deg: tuple[int, ...] = DOOR_STATES_DEG, spacing: float = 5.0) -> Scene:
    """Sec. 4.1: a 2 m corridor, offices both sides, 14 doors (0.9 m leaves) passed at 0.7 m/s."""
    n = len(states_deg)
    per_side = math.ceil(n / 2)
    length = per_side * spacing + 2.0
    walls: list[Any] = []
    doors = []
    gaps: dict[int, list[tuple[float, float]]] = {1: [], -1: []}
    for i in range(n):
        side = 1 if i % 2 == 0 else -1
        xd = 2.0 + (i // 2) * spacing + (0.0 if side == 1 else spacing / 2)
        gaps[side].append((xd, xd + 0.9))
        doors.append(
            {
                "name": f"D-{i + 1}",
                "hinge": [xd, float(side)],
                "leaf_length": 0.9,
                "closed_direction": 0.0,
                "opening_angle": side * math.pi / 2,
                "thickness": 0.04,
            }
        )
        # the office behind the door: 4 m wide, 3 m deep
        y_far = side * 4.0
        walls.append(_box(xd - 1.5, min(side, y_far), xd - 1.45, max(side, y_far)))
        walls.append(_box(xd + 2.45, min(side, y_far), xd + 2.5, max(side, y_far)))
        walls.append(_box(xd - 1.5, y_far - 0.025, xd + 2.5, y_far + 0.025))
    for side in (1, -1):
        walls += _wall_x(float(side), -1.0, length + 1.0, gaps[side])
    walls.append(_box(-1.05, -1.0, -1.0, 1.0))
    walls.append(_box(length + 1.0, -1.0, length + 1.05, 1.0))
    site = site_from_dict(
        {"name": "corridor", "map": {"walls": walls, "resolution": 0.05}, "doors": doors}, base_dir=_here()
    )
    start = (-0.3, 0.0, 0.0)
    distance = length + 0.8
    fractions = {i: abs(math.radians(d)) / (math.pi / 2) for i, d in enumerate(states_deg)}
    return Scene(
        "doors", site, site, start, [(1.0, 0.0, 0.0), (distance / SPEED, SPEED, 0.0)], initial=(fractions, {})
    )


# the U of Sec. 4.2: 37 x 37 cm, legs 7 cm thick, its frame at the centre of its square
_U = [
    (-0.185, -0.185),
    (0.185, -0.185),
    (0.185, 0.185),
    (0.115, 0.185),
    (0.115, -0.115),
    (-0.115, -0.115),
    (-0.115, 0.185),
    (-0.185, 0.185),
]


def _turnaround() -> list[tuple[float, float, float]]:
    """Half a turn on the spot at 0.9 rad/s."""
    return [(math.pi / 0.9, 0.0, 0.9)]


def ushape_scene(turn_deg: float = 30.0) -> Scene:
    """Sec. 4.2: the U-shape in a 2.5 m corridor, passed twice, turned by ``turn_deg``, passed again."""
    walls = [
        _box(-1.0, -1.25, 13.0, -1.2),
        _box(-1.0, 1.2, 13.0, 1.25),
        _box(-1.05, -1.25, -1.0, 1.25),
        _box(13.0, -1.25, 13.05, 1.25),
    ]
    pose0 = (6.0, 0.7, math.radians(-90.0))
    pose1 = (6.0, 0.7, math.radians(-90.0 + turn_deg))
    u = {"name": "U", "outline": [list(p) for p in _U], "poses": [list(pose0), list(pose1)]}
    site = site_from_dict(
        {"name": "ushape", "map": {"walls": walls, "resolution": 0.05}, "furniture": [u]}, base_dir=_here()
    )
    leg = (10.0 / SPEED, SPEED, 0.0)
    drive = [(1.0, 0.0, 0.0), leg, *_turnaround(), leg, *_turnaround(), leg]
    # the object is turned while the robot turns round after its second pass
    t_turn = 1.0 + 2 * leg[0] + math.pi / 0.9 + 0.5 * math.pi / 0.9
    return Scene("ushape", site, site, (1.0, -0.3, 0.0), drive, changes=[(t_turn, {}, {0: 1})])


def desk_scene(shift: float = 0.2) -> Scene:
    """Sec. 4.3: two offices, four desks shifted ``shift`` towards the rooms' centres; desk-3 mostly
    hidden behind a square table (in the model) and a chair (not in the model)."""
    walls = [
        _box(0.0, 0.0, 10.05, 0.05),
        _box(0.0, 4.0, 10.05, 4.05),
        _box(0.0, 0.0, 0.05, 4.05),
        _box(10.0, 0.0, 10.05, 4.05),
        _box(5.0, 0.0, 5.05, 1.1),
        _box(5.0, 2.1, 5.05, 4.05),
        _box(8.55, 2.35, 9.45, 2.85),  # the small square table in front of desk-3 (in the model)
    ]
    chair = _box(7.75, 2.9, 8.25, 3.4)  # in the world only
    desk = [[-0.7, -0.35], [0.7, -0.35], [0.7, 0.35], [-0.7, 0.35]]
    model_poses = [(1.5, 3.55, 0.0), (3.5, 0.5, 0.0), (9.25, 3.55, 0.0), (7.5, 0.5, 0.0)]
    centres = [(2.5, 2.0), (2.5, 2.0), (7.5, 2.0), (7.5, 2.0)]
    true_poses = []
    for (x, y, th), (cx, cy) in zip(model_poses, centres, strict=True):
        d = math.hypot(cx - x, cy - y)
        true_poses.append((x + shift * (cx - x) / d, y + shift * (cy - y) / d, th))

    def site(poses: list[tuple[float, float, float]], extra: list[Any]) -> Site:
        furniture = [
            {"name": f"desk-{i + 1}", "outline": desk, "poses": [list(p)]} for i, p in enumerate(poses)
        ]
        return site_from_dict(
            {"name": "offices", "map": {"walls": walls + extra, "resolution": 0.05}, "furniture": furniture},
            base_dir=_here(),
        )

    drive = [(1.0, 0.0, 0.0), (8.6 / 0.4, 0.4, 0.0), *_turnaround(), (8.6 / 0.4, 0.4, 0.0)]
    return Scene("desks", site(true_poses, [chair]), site(model_poses, []), (0.7, 1.6, 0.0), drive)


def door_tour_site(period: float = 30.0) -> Site:
    """Two 10 x 12 m halls side by side, joined by two doorways (1.3 m) with doors that open and
    close at random (mean ``period`` seconds between changes, both open at the start) and by an
    open passage at the far end (the long way round: about 17 m more). The tour ``crossings``
    goes between exhibits of both halls seven times."""
    walls: list[Any] = [
        _box(0.0, 0.0, 20.0, 0.05),
        _box(0.0, 11.95, 20.0, 12.0),
        _box(0.0, 0.0, 0.05, 12.0),
        _box(19.95, 0.0, 20.0, 12.0),
    ]
    gaps = [(2.0, 3.3), (5.0, 6.3), (10.4, 11.7)]  # south door, north door, the open passage
    y = 0.0
    for a, b in gaps:
        walls.append(_box(10.0, y, 10.05, a))
        y = b
    walls.append(_box(10.0, y, 10.05, 12.0))
    schedule = {"period": period, "random": True, "start_open": True}
    doors = [
        {
            "name": name,
            "hinge": [10.025, a],
            "leaf_length": 1.25,
            "closed_direction": math.pi / 2,
            "opening_angle": -math.pi / 2,
            "thickness": 0.04,
            "schedule": schedule,
        }
        for name, (a, _) in (("south-door", gaps[0]), ("north-door", gaps[1]))
    ]
    exhibits = []
    for name, x, vx, yy, th in (
        ("west-south", 0.6, 3.0, 2.6, math.pi),
        ("east-south", 19.4, 17.0, 2.6, 0.0),
        ("west-north", 0.6, 3.0, 5.6, math.pi),
        ("east-north", 19.4, 17.0, 5.6, 0.0),
    ):
        exhibits.append(
            {"name": name, "position": [x, yy], "viewing_pose": [vx, yy, th], "text": name, "dwell": 4.0}
        )
    order = ["west-south", "east-south", "west-north", "east-north", "west-south", "east-north"]
    order += ["west-north", "east-south"]
    return site_from_dict(
        {
            "name": "door-halls",
            "map": {"walls": walls, "resolution": 0.05},
            "doors": doors,
            "exhibits": exhibits,
            "tours": [{"name": "crossings", "exhibits": order}],
        },
        base_dir=_here(),
    )


def _here() -> Any:
    from pathlib import Path

    return Path(".")


def run_scene(
    scene: Scene, seed: int, crowd: Any = None, progress: Callable[[float], None] | None = None
) -> SceneRun:
    """Drive the simulator through ``scene`` (open loop) and record the log and the true states."""
    from tourbot.sim.robot import DiffDriveConfig
    from tourbot.sim.simulator import SimConfig, Simulator

    # Rhino drove 0.7 m/s on the straight parts (the tour default is 0.6)
    robot = DiffDriveConfig(max_speed=SPEED)
    config = SimConfig(record=True, dynamic_objects=False, crowd=crowd, robot=robot)
    sim = Simulator(scene.world, config, seed=seed, start=scene.start)
    sim.objects.set_states(*scene.initial)
    changes = sorted(scene.changes, key=lambda c: c[0])
    truth: list[list[NDArray[np.float64]]] = []
    seen = 0
    for duration, v, w in scene.drive:
        sim.command(v, w)
        end = sim.time + duration
        while sim.time < end - 1e-9:
            while changes and sim.time >= changes[0][0]:
                _, doors, furniture = changes.pop(0)
                sim.objects.set_states(doors, furniture)
            sim.poll()
            while seen < len(sim.truth_times):
                truth.append([s.copy() for s in sim.objects.states()])
                seen += 1
            if progress is not None:
                progress(sim.time)
    log = sim.to_robot_log()
    return SceneRun(log, truth, np.asarray(sim.truth_times, dtype=np.float64))
