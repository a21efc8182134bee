"""The crowd overlay: museum visitors walking through a *real* log, as the laser would have seen them.

From a recorded log with its reference trajectory and a map of the building, the
:class:`~tourbot.sim.crowd.Crowd` (the simulator's crowd: one implementation) is run along the
reference trajectory, in the log's own time, and every beam that hits a visitor's leg before the
recorded range is shortened to that leg, with sensor noise. Visitors persist from scan to scan and
occlude each other and the walls, so the corruption is consistent over time, as in the crowded
museum data of Fox, Burgard, Thrun & Cremers (1998, Sec. "Experimental results", Fig. 1b, Fig. 4).
The result is a new log (every localizer reads identical input) and the truth: which beams were
corrupted in each scan, and the kidnaps (:mod:`tourbot.sim.kidnap`) if asked for.

Beams are cut with the project's ray caster, :func:`tourbot.maps.raycast.circle_ranges`: the
recorded range already ends at the real wall, so only the circles need casting.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tourbot.errors import InputError, TourbotError
from tourbot.geometry import compose, interpolate_poses
from tourbot.io.output import write_text_whole
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.raycast import circle_ranges
from tourbot.records import RobotLog, Scan
from tourbot.sim.crowd import PRESETS, Crowd, CrowdConfig
from tourbot.sim.kidnap import Kidnap, KidnapConfig, apply_kidnaps, plan_kidnaps

__all__ = [
    "CrowdTruth",
    "OverlayConfig",
    "OverlayError",
    "OverlayResult",
    "overlay_crowd",
    "read_truth",
    "truth_path",
    "write_truth",
]

FloatArray = NDArray[np.float64]


class OverlayError(TourbotError):
    """A log the crowd cannot be laid over (no reference trajectory, no scans)."""


@dataclass(frozen=True)
class OverlayConfig:
    """How the crowd is laid over a log.

    ``range_noise``: standard deviation of the range to a leg, 1 cm (SICK LMS 200 class lasers,
    the RHINO/TOURBOT sensors; Fox et al. 1998 model the noise of hits with a Gaussian).
    ``robot_step``: the robot pose is interpolated along the reference trajectory at this period
    while the crowd walks between scans. ``warmup``: the crowd walks this long with the robot at
    its first pose before the first scan, so that interested visitors have gathered.
    """

    crowd: CrowdConfig = field(default_factory=lambda: PRESETS["peak"])
    range_noise: float = 0.01
    robot_step: float = 0.25
    warmup: float = 60.0
    kidnap: KidnapConfig | None = None

    @classmethod
    def preset(cls, name: str, *, kidnap: bool = False, **crowd_overrides: Any) -> OverlayConfig:
        """The overlay for a crowd preset (``sparse``, ``peak``...), optionally with kidnaps."""
        return cls(
            crowd=CrowdConfig.preset(name, **crowd_overrides),
            kidnap=KidnapConfig() if kidnap else None,
        )


@dataclass
class CrowdTruth:
    """What the overlay did to a log: per scan, which beams a visitor corrupted; the kidnaps."""

    times: FloatArray  # (S,)
    corrupted: NDArray[np.bool_]  # (S, B)
    kidnaps: list[Kidnap]
    preset: str = ""
    seed: int | None = None
    people: int = 0

    @property
    def fraction(self) -> FloatArray:
        """Fraction of corrupted beams per scan, ``(S,)``."""
        return np.asarray(self.corrupted.mean(axis=1), dtype=np.float64)

    def longest_above(self, threshold: float = 0.5) -> float:
        """The longest stretch of time (s) during which every scan had more than ``threshold`` of
        its beams corrupted (from the first such scan to the last of the run)."""
        best = 0.0
        start: float | None = None
        for t, f in zip(self.times.tolist(), self.fraction.tolist(), strict=True):
            if f > threshold:
                start = t if start is None else start
                best = max(best, t - start)
            else:
                start = None
        return best


@dataclass
class OverlayResult:
    log: RobotLog
    truth: CrowdTruth


def overlay_crowd(
    log: RobotLog,
    grid: OccupancyGrid,
    config: OverlayConfig | None = None,
    seed: int = 0,
    preset: str = "",
    progress: Callable[[int, int], None] | None = None,
) -> OverlayResult:
    """Lay a crowd over ``log`` (which needs reference poses), deterministically for ``seed``.

    The crowd, the range noise and the kidnaps draw from independent streams of ``seed``, so the
    same seed gives the same visitors with or without kidnaps.
    """
    cfg = config or OverlayConfig()
    if not log.scans:
        raise OverlayError(f"{log.source}: the log has no scans")
    if not log.has_reference:
        raise OverlayError(
            f"{log.source}: the crowd walks along the reference trajectory, and this log has none "
            "(use a 'corrected' log, whose FLASER poses are the reference)"
        )
    crowd_rng, noise_rng, kidnap_rng = (
        np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(3)
    )
    ref = log.reference_poses
    times = log.times
    warnings = list(log.warnings)
    back = np.diff(times) < 0
    if np.any(back):
        # A few logs (Intel) have scans stamped slightly out of order: the crowd takes such a step
        # as no time passing, so the visitors never walk backwards in time.
        worst = float(-np.diff(times)[back].max())
        warnings.append(
            f"{log.source}: scan timestamps go backwards {int(back.sum())} times (by up to {worst:.2f} s); "
            "the crowd takes those steps as no time passing"
        )
        times = np.maximum.accumulate(times)

    crowd = Crowd(cfg.crowd, grid, crowd_rng, ref[0])
    warm = 0.0
    while warm < cfg.warmup:
        dt = min(1.0, cfg.warmup - warm)
        crowd.step(dt, ref[0], crowd_rng)
        warm += dt

    scans: list[Scan] = []
    corrupted = np.zeros((len(log.scans), max(s.ranges.size for s in log.scans)), dtype=bool)
    t_prev = times[0]
    for i, scan in enumerate(log.scans):
        t = times[i]
        while t - t_prev > 1e-9:
            dt = min(cfg.robot_step, t - t_prev)
            crowd.step(dt, interpolate_poses(times, ref, np.array([t_prev + dt]))[0], crowd_rng)
            t_prev += dt
        t_prev = t
        ranges, hit = _cut(scan, ref[i], crowd, cfg.range_noise, noise_rng)
        corrupted[i, : hit.size] = hit
        scans.append(replace(scan, ranges=ranges))
        if progress is not None:
            progress(i + 1, len(log.scans))

    out = RobotLog(
        source=log.source,
        scans=scans,
        odometry=list(log.odometry),
        warnings=warnings,
        odometry_kind=log.odometry_kind,
    )
    kidnaps: list[Kidnap] = []
    if cfg.kidnap is not None:
        kidnaps = plan_kidnaps(ref, times, kidnap_rng, cfg.kidnap)
        out = apply_kidnaps(out, kidnaps)
    truth = CrowdTruth(
        times=times, corrupted=corrupted, kidnaps=kidnaps, preset=preset, seed=seed, people=crowd.num_people
    )
    return OverlayResult(out, truth)


def _cut(
    scan: Scan, reference: FloatArray, crowd: Crowd, noise: float, rng: np.random.Generator
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """The scan's ranges shortened to the visitors' legs, and which beams were."""
    g = scan.geometry
    laser = compose(reference, g.offset)
    recorded = np.asarray(scan.ranges, dtype=np.float64)
    centres, radii = crowd.circles()
    near = np.hypot(centres[:, 0] - laser[0], centres[:, 1] - laser[1]) < g.max_range + 1.0
    centres, radii = centres[near], radii[near]
    cut = recorded.astype(np.float32)[None, :].copy()
    if len(radii):
        circle_ranges(
            np.array([laser[0]]),
            np.array([laser[1]]),
            np.array([laser[2]]),
            g.angles,
            np.ascontiguousarray(centres[:, 0]),
            np.ascontiguousarray(centres[:, 1]),
            np.ascontiguousarray(radii),
            cut,
        )
    to_leg = cut[0].astype(np.float64)
    hit = to_leg < recorded.astype(np.float32) - 1e-6
    noisy = to_leg + rng.normal(0.0, noise, size=to_leg.shape)
    noisy = np.clip(noisy, max(g.min_range, 0.0), None)
    return np.where(hit, noisy, recorded), hit


# --------------------------------------------------------------------------------------------
# The truth file beside a crowded log
# --------------------------------------------------------------------------------------------


def truth_path(log_path: str | Path) -> Path:
    """Where the truth of a crowded log is kept: ``X.log.gz`` -> ``X.truth.json``."""
    p = Path(log_path)
    name = p.name
    for suffix in (".gz", ".log", ".clf", ".txt"):
        if name.endswith(suffix):
            name = name[: -len(suffix)]
    return p.with_name(name + ".truth.json")


def write_truth(truth: CrowdTruth, path: str | Path) -> None:
    """Save :class:`CrowdTruth` as JSON (corrupted-beam masks as hex strings of packed bits)."""
    data = {
        "preset": truth.preset,
        "seed": truth.seed,
        "people": truth.people,
        "beams": int(truth.corrupted.shape[1]),
        "times": truth.times.tolist(),
        "fraction": [round(float(f), 6) for f in truth.fraction],
        "mean_fraction": float(truth.fraction.mean()) if len(truth.times) else 0.0,
        "corrupted": [np.packbits(row).tobytes().hex() for row in truth.corrupted],
        "kidnaps": [{"scan": k.scan, "time": k.time, "delta": list(k.delta)} for k in truth.kidnaps],
    }
    write_text_whole(path, json.dumps(data, indent=1))


def read_truth(path: str | Path) -> CrowdTruth:
    """Read what :func:`write_truth` wrote."""
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
        beams = int(data["beams"])
        rows = [
            np.unpackbits(np.frombuffer(bytes.fromhex(h), dtype=np.uint8))[:beams].astype(bool)
            for h in data["corrupted"]
        ]
        corrupted = np.array(rows, dtype=bool).reshape(len(rows), beams)
        kidnaps = [
            Kidnap(
                int(k["scan"]),
                float(k["time"]),
                (float(k["delta"][0]), float(k["delta"][1]), float(k["delta"][2])),
            )
            for k in data["kidnaps"]
        ]
        return CrowdTruth(
            times=np.asarray(data["times"], dtype=np.float64),
            corrupted=corrupted,
            kidnaps=kidnaps,
            preset=str(data.get("preset", "")),
            seed=data.get("seed"),
            people=int(data.get("people", 0)),
        )
    except FileNotFoundError:
        raise InputError("no such file", path=p) from None
    except (ValueError, KeyError, TypeError, IndexError) as exc:
        raise InputError(f"not a crowd truth file ({exc})", path=p) from None
