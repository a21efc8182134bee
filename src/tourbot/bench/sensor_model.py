"""``tourbot bench sensor-model``: the laser against the map, measured on the real logs.

The intrinsic parameters of a range-finder model are to be learned from data (Probabilistic
Robotics, Sec. 6.3), and the novelty filter's ``p(d | l)`` is "the probability of measuring
distance ``d`` if the sensor detects the next obstacle in the map" (Fox, Burgard, Thrun & Cremers
1998, Eq. 5; their laser model is learned from data as well). On each shared log (without a crowd),
every scan is laid out at its reference pose on the log's own reference map and three figures are
measured:

- ``range sigma``: the spread of the reading about the range ray cast in the map (robust: 1.4826
  times the median absolute deviation), the width of Eq. 5's ``p(d | l)``;
- ``field sigma``: the maximum-likelihood ``sigma_hit`` of the likelihood field (PR Table 6.3:
  a half-normal of the endpoint's distance to the nearest obstacle, mixed with a uniform part up
  to ``max_dist``, fitted by EM), with the distance to the occupied cell's centre and to the
  surface between free and occupied space (:func:`tourbot.maps.likelihood_field.surface_distance`);
- ``correlation length``: how many neighbouring beams err together, ``1 + 2 sum_k rho(k)`` over
  the lags ``k`` whose correlation ``rho`` of the residuals (clipped to +-0.5 m) is above 0.05.
  Beams that err together are not independent (PR Sec. 6.4 and 6.8), and the product of their
  likelihoods is that many times too confident: its inverse is the likelihood exponent they
  call for.

These are the measurements behind the defaults of :class:`tourbot.localization.mcl.SensorConfig`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from numpy.typing import NDArray
from scipy import ndimage

from tourbot.errors import TourbotError
from tourbot.geometry import compose
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.likelihood_field import LikelihoodFieldParams, surface_distance
from tourbot.maps.raycast import DistanceCaster
from tourbot.records import RobotLog

__all__ = ["SensorFit", "correlation_length", "fit_sigma_hit", "measure", "register", "robust_sigma"]

FloatArray = NDArray[np.float64]
CLIP = 0.5  # residuals clipped to this (m) for the correlation: a person or a glass pane is no noise


@dataclass(frozen=True)
class SensorFit:
    """The figures of one log (metres; the correlation length in beams)."""

    beams: int
    beam_spacing_deg: float
    range_sigma: float
    field_sigma_centre: float
    field_sigma_surface: float
    z_hit_surface: float
    correlation_beams: float


def robust_sigma(residuals: FloatArray) -> float:
    """``1.4826 * median |r - median r|``: the standard deviation of the normal core of ``residuals``."""
    r = np.asarray(residuals, dtype=np.float64)
    if r.size == 0:
        raise ValueError("no residuals")
    return float(1.4826 * np.median(np.abs(r - np.median(r))))


def fit_sigma_hit(distances: FloatArray, max_dist: float, iterations: int = 200) -> tuple[float, float]:
    """Maximum likelihood ``(sigma_hit, z_hit)`` of ``z_hit * 2 N(d; 0, sigma) + (1 - z_hit) / max_dist``
    over ``distances`` capped at ``max_dist`` (EM; PR Sec. 6.3 learns the beam model's the same way)."""
    d = np.minimum(np.asarray(distances, dtype=np.float64), max_dist)
    if d.size == 0:
        raise ValueError("no distances")
    z, s = 0.8, max(float(np.median(d)), 1e-3)
    for _ in range(iterations):
        hit = z * 2.0 * np.exp(-0.5 * (d / s) ** 2) / (s * math.sqrt(2.0 * math.pi))
        resp = hit / (hit + (1.0 - z) / max_dist)
        z = float(resp.mean())
        s = max(float(np.sqrt(np.sum(resp * d * d) / max(float(resp.sum()), 1e-12))), 1e-4)
    return s, z


def correlation_length(residuals: FloatArray, max_lag: int = 30, floor: float = 0.05) -> float:
    """``1 + 2 sum_k rho(k)`` of scans of residuals ``(S, B)`` (NaN: no return), over the lags
    ``1..max_lag`` up to the first whose correlation is below ``floor``."""
    r = np.asarray(residuals, dtype=np.float64)
    total = 1.0
    for k in range(1, min(max_lag, r.shape[1] - 1) + 1):
        a, b = r[:, :-k].ravel(), r[:, k:].ravel()
        ok = np.isfinite(a) & np.isfinite(b)
        if ok.sum() < 3 or np.std(a[ok]) == 0.0 or np.std(b[ok]) == 0.0:
            break
        rho = float(np.corrcoef(a[ok], b[ok])[0, 1])
        if rho < floor:
            break
        total += 2.0 * rho
    return total


def measure(log: RobotLog, grid: OccupancyGrid, scans: int = 400) -> SensorFit:
    """The figures of ``log`` (a :class:`~tourbot.records.RobotLog` with reference poses) on its
    reference map ``grid``, from ``scans`` scans spread over the log."""
    if not log.scans or not log.has_reference:
        raise TourbotError(
            f"{log.source}: the sensor model is measured at reference poses, and this log has none"
        )
    geometry = log.scans[0].geometry
    caster = DistanceCaster(grid, float(geometry.max_range))
    centre = ndimage.distance_transform_edt(~grid.occupied()) * grid.resolution
    surface = surface_distance(grid, centre)
    ref = log.reference_poses
    picked = np.unique(np.linspace(0, len(log.scans) - 1, min(scans, len(log.scans))).astype(np.int64))
    rows, ends = [], []
    for i in picked:
        scan = log.scans[int(i)]
        g = scan.geometry
        z = np.asarray(scan.ranges, dtype=np.float64)
        valid = np.isfinite(z) & (z >= g.min_range) & (z < g.max_range)
        laser = compose(ref[i], g.offset)
        expected = caster.cast(laser[None, :], g.angles)[0].astype(np.float64)
        rows.append(np.where(valid, z - expected, np.nan))
        a = laser[2] + g.angles[valid]
        ends.append(np.column_stack([laser[0] + z[valid] * np.cos(a), laser[1] + z[valid] * np.sin(a)]))
    residuals = np.array(rows)
    cells = grid.world_to_cell(np.concatenate(ends))
    cells = cells[grid.inside(cells)]
    max_dist = LikelihoodFieldParams().max_dist
    sig_c, _ = fit_sigma_hit(centre[cells[:, 0], cells[:, 1]], max_dist)
    sig_s, z_s = fit_sigma_hit(surface[cells[:, 0], cells[:, 1]], max_dist)
    return SensorFit(
        beams=int(geometry.num_beams),
        beam_spacing_deg=float(np.degrees(np.mean(np.diff(geometry.angles)))),
        range_sigma=robust_sigma(residuals[np.isfinite(residuals)]),
        field_sigma_centre=sig_c,
        field_sigma_surface=sig_s,
        z_hit_surface=z_s,
        correlation_beams=correlation_length(np.clip(residuals, -CLIP, CLIP)),
    )


def register(bench: typer.Typer) -> None:
    @bench.command("sensor-model")
    def sensor_model(
        logs: Annotated[
            str, typer.Option(help="Logs, comma-separated: fhw, intel, aces, freiburg-079.")
        ] = "fhw,intel,aces,freiburg-079",
        scans: Annotated[int, typer.Option(help="Scans per log, spread over it.")] = 400,
        cache: Annotated[Path, typer.Option(help="Cache of maps (shared with bench localization).")] = Path(
            "bench-results/cache/localization"
        ),
        output: Annotated[Path | None, typer.Option("-o", "--output", help="JSON file to write.")] = None,
    ) -> None:
        """The laser against the map at the reference poses: range noise, sigma_hit, beam correlation."""
        from rich.console import Console

        from tourbot.bench._report import BenchReport
        from tourbot.bench.logs import chosen_logs, reference_map
        from tourbot.io import read_carmen

        if scans < 10:
            raise TourbotError(f"--scans must be >= 10, not {scans}")
        files = chosen_logs(logs)
        cache.mkdir(parents=True, exist_ok=True)
        report = BenchReport(
            "sensor-model",
            [
                "log",
                "beams",
                "spacing deg",
                "range sigma cm",
                "field sigma centre cm",
                "field sigma surface cm",
                "z_hit surface",
                "correlated beams",
                "exponent 1/L",
            ],
        )
        for name, file in files.items():
            log = read_carmen(file)
            fit = measure(log, reference_map(log, name, cache), scans)
            report.add(
                log=name,
                beams=fit.beams,
                **{
                    "spacing deg": fit.beam_spacing_deg,
                    "range sigma cm": 100.0 * fit.range_sigma,
                    "field sigma centre cm": 100.0 * fit.field_sigma_centre,
                    "field sigma surface cm": 100.0 * fit.field_sigma_surface,
                    "z_hit surface": fit.z_hit_surface,
                    "correlated beams": fit.correlation_beams,
                    "exponent 1/L": 1.0 / fit.correlation_beams,
                },
            )
        report.meta = {"scans": scans}
        report.finish(output, Console())
