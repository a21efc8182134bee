"""The object overlay: doors and furniture in chosen, changing states written into a *real* log.

Like the crowd overlay (:mod:`tourbot.sim.overlay`), from a corrected log with its reference
trajectory: every beam that meets a door leaf or a piece of furniture of the site (the
:class:`~tourbot.maps.objects.ObjectShape` geometry the estimator and the simulator use, cast by
the same kernel, :func:`tourbot.maps.objects.segment_ranges`) before the recorded range is
shortened to it, with range noise. A real wall nearer than the object keeps its reading, so the
result is consistent with what the laser could have seen. The states change on a schedule drawn
from the seed (a door to a new opening angle, a piece of furniture to another of its site poses);
the true states at every scan are kept (:class:`ObjectTruth`). The crowd overlay can then be laid
over the result (``tourbot crowd --objects``).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tourbot.errors import InputError
from tourbot.geometry import compose
from tourbot.io.output import write_text_whole
from tourbot.maps.objects import ObjectShape, segment_ranges
from tourbot.records import RobotLog, Scan
from tourbot.sim.overlay import OverlayError

__all__ = [
    "ObjectOverlayConfig",
    "ObjectTruth",
    "object_truth_path",
    "overlay_objects",
    "read_object_truth",
    "write_object_truth",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ObjectOverlayConfig:
    """``period``: mean seconds between changes of one object (exponential, drawn from the seed);
    ``range_noise``: standard deviation (m) of a range to an object (a SICK-class laser, as the
    crowd overlay's 1 cm)."""

    period: float = 120.0
    range_noise: float = 0.01


@dataclass
class ObjectTruth:
    """The true state of every object at every scan: ``states[i]`` is ``(S, dim_i)``."""

    names: list[str]
    times: FloatArray
    states: list[FloatArray]
    changed: list[int]  # beams shortened per scan

    def at(self, scan: int) -> list[FloatArray]:
        return [s[scan] for s in self.states]


def _schedule(
    shapes: Sequence[ObjectShape],
    poses: Sequence[Sequence[Sequence[float]]],
    times: FloatArray,
    cfg: ObjectOverlayConfig,
    rng: np.random.Generator,
) -> list[FloatArray]:
    """Each object's state at every scan time: a new state drawn at exponential intervals."""
    out = []
    for shape, choices in zip(shapes, poses, strict=True):
        n = times.shape[0]
        states = np.empty((n, shape.dim))
        t_next = times[0] + rng.exponential(cfg.period)
        state = _draw(shape, choices, rng)
        for k in range(n):
            while times[k] >= t_next:
                state = _draw(shape, choices, rng)
                t_next += rng.exponential(cfg.period)
            states[k] = state
        out.append(states)
    return out


def _draw(shape: ObjectShape, choices: Sequence[Sequence[float]], rng: np.random.Generator) -> FloatArray:
    if shape.kind == "door":
        return np.array([rng.uniform(shape.low, shape.high)])
    return np.asarray(choices[int(rng.integers(len(choices)))], dtype=np.float64)


def overlay_objects(
    log: RobotLog,
    shapes: Sequence[ObjectShape],
    furniture_poses: Sequence[Sequence[Sequence[float]]],
    config: ObjectOverlayConfig | None = None,
    seed: int = 0,
) -> tuple[RobotLog, ObjectTruth]:
    """Write ``shapes`` into ``log`` (which needs reference poses), deterministically for ``seed``.

    ``furniture_poses[i]``: the poses object ``i`` is moved between (ignored for doors).
    """
    cfg = config or ObjectOverlayConfig()
    if not log.scans:
        raise OverlayError(f"{log.source}: the log has no scans")
    if not log.has_reference:
        raise OverlayError(
            f"{log.source}: the objects are cast from the reference trajectory, and this log has none"
        )
    sched_rng, noise_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2))
    times = np.maximum.accumulate(log.times)
    states = _schedule(shapes, furniture_poses, times, cfg, sched_rng)
    ref = log.reference_poses
    scans: list[Scan] = []
    changed = []
    for k, scan in enumerate(log.scans):
        segs = [shape.segments(s[k])[0] for shape, s in zip(shapes, states, strict=True)]
        ranges, n = _cut(
            scan, ref[k], np.concatenate(segs)[None] if segs else np.zeros((1, 0, 4)), cfg, noise_rng
        )
        scans.append(replace(scan, ranges=ranges))
        changed.append(n)
    out = RobotLog(
        source=log.source,
        scans=scans,
        odometry=list(log.odometry),
        warnings=list(log.warnings),
        odometry_kind=log.odometry_kind,
        notes=list(log.notes),
    )
    return out, ObjectTruth([s.name for s in shapes], times, states, changed)


def _cut(
    scan: Scan, reference: FloatArray, segs: FloatArray, cfg: ObjectOverlayConfig, rng: np.random.Generator
) -> tuple[FloatArray, int]:
    g = scan.geometry
    laser = compose(reference, g.offset)[None, :]
    recorded = np.asarray(scan.ranges, dtype=np.float64)
    if not segs.shape[1]:
        return recorded, 0
    cast = segment_ranges(laser, g.angles, segs, recorded[None, :])[0, 0].astype(np.float64)
    hit = cast < recorded - 1e-6
    noisy = np.clip(cast + rng.normal(0.0, cfg.range_noise, cast.shape), max(g.min_range, 0.0), None)
    return np.where(hit, noisy, recorded), int(hit.sum())


def object_truth_path(log_path: str | Path) -> Path:
    """Where the object truth of an overlaid log is kept: ``X.log.gz`` -> ``X.objects.json``."""
    p = Path(log_path)
    name = p.name
    for suffix in (".gz", ".log", ".clf", ".txt"):
        name = name.removesuffix(suffix)
    return p.with_name(name + ".objects.json")


def write_object_truth(truth: ObjectTruth, path: str | Path) -> None:
    data = {
        "names": truth.names,
        "times": truth.times.tolist(),
        "states": [np.round(s, 6).tolist() for s in truth.states],
        "changed": truth.changed,
    }
    write_text_whole(path, json.dumps(data))


def read_object_truth(path: str | Path) -> ObjectTruth:
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
        return ObjectTruth(
            [str(n) for n in data["names"]],
            np.asarray(data["times"], dtype=np.float64),
            [np.asarray(s, dtype=np.float64).reshape(len(data["times"]), -1) for s in data["states"]],
            [int(c) for c in data["changed"]],
        )
    except FileNotFoundError:
        raise InputError("no such file", path=p) from None
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(f"not an object truth file ({exc})", path=p) from None
