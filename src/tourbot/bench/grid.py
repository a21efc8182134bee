"""``tourbot bench grid``: grid Markov localization (Fox et al. 1998) on the real FHW museum log.

The map is the reference map of the log (:func:`tourbot.maps.reference.build_reference_map`,
from the corrected poses); the localizer reads only the raw odometry and the scans; errors are
measured against the corrected poses. Three experiments, after the paper's Table 1:

- tracking, for each beam filter (none, entropy, novelty): mean position error, failures (error
  above 45 cm, the paper's criterion), time per update and the real-time factor (log duration
  over the summed update times; target >= 10x on FHW: 2007 s, 488 scans);
- global localization from a uniform belief at a few starting scans: scans and log seconds until
  the estimate is within 45 cm, and the time of the first (whole-grid) update;
- recovery: the odometry is kidnapped with the paper's statistics
  (:mod:`tourbot.sim.kidnap`: 0.005 per metre, 180 +- 90 deg, 0 +- 1 m); the recovery
  time is from the kidnap to the start of the first stretch of more than 10 s within 45 cm
  (the paper's definition).

:func:`run_grid_bench` is the function other benchmarks can call.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from numpy.typing import NDArray

from tourbot.bench._report import BenchReport, default_output
from tourbot.metrics import FAILURE_DISTANCE, converged_index, failure_rate, recovery

__all__ = [
    "TARGET_REALTIME",
    "LogRun",
    "register",
    "run_grid_bench",
    "run_log",
]

FloatArray = NDArray[np.float64]

TARGET_REALTIME = 10.0  # the target: >= 10x faster than real time on FHW


@dataclass
class LogRun:
    """Per-scan results of one pass of a localizer over a log."""

    times: FloatArray  # scan timestamps
    errors: FloatArray  # position error against the reference, m
    heading_errors: FloatArray  # rad
    update_seconds: FloatArray  # wall clock
    cpu_seconds: FloatArray  # this process's CPU time (the machine is shared: less noisy)
    used_beams: FloatArray
    held: FloatArray  # poses held by the grid
    poses: FloatArray  # the estimates, (S, 3)

    @property
    def duration(self) -> float:
        return float(self.times[-1] - self.times[0]) if self.times.size > 1 else 0.0

    @property
    def realtime_factor(self) -> float:
        """Log duration over the summed wall-clock update times."""
        total = float(self.update_seconds.sum())
        return self.duration / total if total > 0 else math.nan

    @property
    def realtime_factor_cpu(self) -> float:
        """Log duration over the summed CPU time of the updates."""
        total = float(self.cpu_seconds.sum())
        return self.duration / total if total > 0 else math.nan


def run_log(
    loc: Any,
    log: Any,
    start: int = 0,
    stop: int | None = None,
    advance: Callable[[], None] | None = None,
) -> LogRun:
    """Feed scans ``start:stop`` of ``log`` (odometry from ``Scan.odom``) to ``loc``; score each."""
    from tourbot.geometry import wrap_angle

    scans = log.scans[start:stop]
    ref = log.reference_poses[start:stop]
    out = {k: np.zeros(len(scans)) for k in ("t", "e", "h", "s", "c", "u", "n")}
    poses = np.zeros((len(scans), 3))
    for i, scan in enumerate(scans):
        c0 = time.process_time()
        est = loc.update(np.asarray(scan.odom, dtype=np.float64), scan)
        out["c"][i] = time.process_time() - c0
        poses[i] = est.pose
        out["t"][i] = scan.timestamp
        out["e"][i] = math.hypot(est.pose[0] - ref[i, 0], est.pose[1] - ref[i, 1])
        out["h"][i] = abs(float(wrap_angle(est.pose[2] - ref[i, 2])))
        out["s"][i] = est.update_seconds
        out["u"][i] = est.n_used_beams
        out["n"][i] = est.n_samples
        if advance is not None:
            advance()
    return LogRun(out["t"], out["e"], out["h"], out["s"], out["c"], out["u"], out["n"], poses)


def run_grid_bench(
    log_name: str = "carmen/fhw-corrected.log.gz",
    filters: Sequence[str] = ("none", "entropy", "novelty"),
    scans: int | None = None,
    global_starts: Sequence[int] = (0, 150, 300),
    global_scans: int = 10,
    kidnap_filters: Sequence[str] = ("novelty",),
    kidnap_seeds: Sequence[int] = (0, 3),
    progress: Any = None,
    picture: Path | None = None,
    config: Any = None,
) -> BenchReport:
    """Run the three experiments on a real log; returns the filled :class:`BenchReport`.

    ``picture``: where to draw the map with the reference path and each filter's tracked path.
    ``config``: the :class:`GridMarkovConfig` (its defaults when None).
    """
    from dataclasses import replace

    from tourbot.data import find_data
    from tourbot.io.carmen import read_carmen
    from tourbot.localization.beam_filters import BeamFilter
    from tourbot.localization.grid_markov import GridMarkovConfig, GridMarkovLocalization
    from tourbot.maps.reference import build_reference_map
    from tourbot.sim.kidnap import apply_kidnaps, plan_kidnaps

    report = BenchReport(
        "grid",
        [
            "experiment",
            "filter",
            "scans",
            "mean err cm",
            "failures %",
            "s / update",
            "p95 s",
            "x real time",
            "x real time cpu",
            "target",
            "result",
        ],
    )
    log = read_carmen(find_data(log_name))
    if scans is not None:
        log.scans = log.scans[:scans]
    t0 = time.perf_counter()
    grid = build_reference_map(log)
    t_map = time.perf_counter() - t0
    cfg = config if config is not None else GridMarkovConfig()
    base = GridMarkovLocalization(grid, cfg)
    t0 = time.perf_counter()
    task = progress.add_task("expected-range table", total=base.lattice.n_free) if progress else None
    table = base.prepare(
        log.scans[0].geometry.max_range,
        progress=(lambda done, _total: progress.update(task, completed=done)) if progress else None,
    )
    t_table = time.perf_counter() - t0
    lat = base.lattice
    report.meta.update(
        log=log_name,
        scans=len(log),
        log_seconds=float(log.times[-1] - log.times[0]),
        map_cells=list(grid.shape),
        lattice_cells=list(lat.shape),
        free_cells=lat.n_free,
        poses=lat.n_poses,
        map_seconds=t_map,
        table_seconds=t_table,
        table_mbytes=table.bins.nbytes / 1e6,
        config={k: str(v) for k, v in cfg.__dict__.items()},
    )

    def new(filter_name: str) -> Any:
        return GridMarkovLocalization(grid, replace(cfg, beam_filter=BeamFilter(filter_name)), table=table)

    def stepper(name: str, total: int) -> Callable[[], None] | None:
        if progress is None:
            return None
        task = progress.add_task(name, total=total)
        return lambda: progress.advance(task)

    # Tracking (Table 1, "Tracking ability" and "Accuracy")
    ref0 = log.reference_poses[0]
    tracked: dict[str, LogRun] = {}
    for name in filters:
        loc = new(name)
        loc.reset_tracking(ref0, np.diag([0.1, 0.1, math.radians(3.0)]) ** 2)
        run = run_log(loc, log, advance=stepper(f"tracking, {name}", len(log)))
        tracked[name] = run
        rt = run.realtime_factor
        rt_cpu = run.realtime_factor_cpu
        report.add(
            experiment="tracking",
            filter=name,
            scans=len(log),
            **{
                "mean err cm": 100 * float(run.errors.mean()),
                "failures %": 100 * failure_rate(run.errors),
                "s / update": float(run.update_seconds.mean()),
                "p95 s": float(np.percentile(run.update_seconds, 95)),
                "x real time": rt,
                "x real time cpu": rt_cpu,
                "target": f">= {TARGET_REALTIME:g}x",
                "result": f"wall {'met' if rt >= TARGET_REALTIME else 'MISSED'}, "
                f"cpu {'met' if rt_cpu >= TARGET_REALTIME else 'MISSED'}",
                "cpu s / update": float(run.cpu_seconds.mean()),
                "median held poses": float(np.median(run.held)),
                "mean used beams": float(run.used_beams.mean()),
                "mean heading err deg": math.degrees(float(run.heading_errors.mean())),
            },
        )

    if picture is not None and tracked:
        _draw(grid, log.reference_poses, tracked, picture)
        report.notes.append(f"picture: {picture}")

    # Global localization from a uniform belief
    for start in global_starts:
        if start >= len(log) - 1:
            continue
        loc = new("novelty")
        loc.reset_global()
        run = run_log(
            loc, log, start, start + global_scans, stepper(f"global from scan {start}", global_scans)
        )
        first = converged_index(run.errors)
        report.add(
            experiment=f"global from scan {start}",
            filter="novelty",
            scans=global_scans,
            **{
                "mean err cm": 100 * float(run.errors[-1]),
                "failures %": 100 * failure_rate(run.errors),
                "s / update": float(run.update_seconds[1:].mean())
                if run.update_seconds.size > 1
                else math.nan,
                "p95 s": float(run.update_seconds[0]),
                "x real time": run.realtime_factor,
                "x real time cpu": run.realtime_factor_cpu,
                "target": "localized",
                "result": "no"
                if first is None
                else f"after {first + 1} scans, {run.times[first] - run.times[0]:.0f} s",
                "first update s": float(run.update_seconds[0]),
            },
        )

    # Recovery from kidnapping (Table 1, "Recovery")
    for name in kidnap_filters:
        rec: list[float] = []
        n_kid = censored = 0
        seconds: list[float] = []
        kid_times: list[float] = []
        for seed in kidnap_seeds:
            kidnaps = plan_kidnaps(log.reference_poses, log.times, np.random.default_rng(seed))
            if not kidnaps:
                continue
            kid_log = apply_kidnaps(log, kidnaps)
            kid_times.extend(k.time - log.times[0] for k in kidnaps)
            loc = new(name)
            loc.reset_tracking(ref0, np.diag([0.1, 0.1, math.radians(3.0)]) ** 2)
            run = run_log(loc, kid_log, advance=stepper(f"kidnap {name}, seed {seed}", len(log)))
            for r in recovery(run.errors, run.times, [k.scan for k in kidnaps]):
                censored += r is None
                rec.append(math.nan if r is None or not r.recovered else r.seconds)
            n_kid += len(kidnaps)
            seconds += run.update_seconds.tolist()
        arr = np.array(rec)
        done = arr[np.isfinite(arr)]
        report.add(
            experiment="kidnap recovery",
            filter=name,
            scans=len(seconds),
            **{
                "mean err cm": math.nan,
                "failures %": math.nan,
                "s / update": float(np.mean(seconds)) if seconds else math.nan,
                "p95 s": float(np.percentile(seconds, 95)) if seconds else math.nan,
                "x real time": math.nan,
                "x real time cpu": math.nan,
                "target": "recovers",
                "result": (
                    f"{done.size}/{n_kid - censored} recovered, mean t_rec {done.mean():.0f} s"
                    if done.size
                    else f"0/{n_kid - censored} recovered"
                )
                + (f" ({censored} censored)" if censored else ""),
                "recovery seconds": arr.tolist(),
                "kidnaps censored": censored,
                "kidnap at log seconds": kid_times,
            },
        )
    report.notes.append(
        f"map {grid.shape[0]}x{grid.shape[1]} cells from the log's corrected poses ({t_map:.1f} s); lattice "
        f"{lat.n_free} free 15 cm cells x {lat.n_theta} headings = {lat.n_poses} poses; expected-range table "
        f"{table.bins.nbytes / 1e6:.0f} MB built in {t_table:.1f} s (once per map, not in the update times)"
    )
    report.notes.append(
        "failures: position error > 45 cm (Fox et al. 1998); global rows: 'mean err cm' is the error at the "
        "last scan, 'p95 s' the first (whole-grid) update"
    )
    return report


def _draw(grid: Any, reference: FloatArray, runs: dict[str, LogRun], path: Path) -> None:
    """The map, the reference path and each filter's estimates; crosses where a scan failed."""
    from tourbot.plotting import draw_map, draw_path, new_map_figure, save_figure

    fig, ax = new_map_figure(grid)
    draw_map(ax, grid)
    draw_path(ax, reference, "reference (corrected poses)", color="black", linewidth=2.0)
    for name, run in runs.items():
        draw_path(ax, run.poses, f"grid Markov, {name} filter", linewidth=1.0, markers=False)
        bad = run.errors > FAILURE_DISTANCE
        if bad.any():
            ax.plot(run.poses[bad, 0], run.poses[bad, 1], "x", markersize=6, label=f"{name}: > 45 cm off")
    ax.set_title("tourbot bench grid: FHW, grid Markov localization (15 cm x 2 deg)")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="best", fontsize=8)
    save_figure(fig, path)


_OUTPUT = typer.Option(None, "-o", "--output", help="JSON file (default bench-results/).")


def register(bench: typer.Typer) -> None:
    @bench.command("grid")
    def grid(
        log: str = typer.Option("carmen/fhw-corrected.log.gz", help="Log in the shared data folder."),
        filters: str = typer.Option("none,entropy,novelty", help="Beam filters to track with."),
        scans: int = typer.Option(0, help="Use only the first N scans (0: all)."),
        global_starts: str = typer.Option("0,150,300", help="Scans to start global localization at."),
        kidnap_filters: str = typer.Option("novelty", help="Beam filters to kidnap (empty: none)."),
        kidnap_seeds: str = typer.Option(
            "0,3", help="Seeds of the kidnapped runs (one run per seed and filter)."
        ),
        output: Path | None = _OUTPUT,
        config: Annotated[Path | None, typer.Option("--config", help="Localization profile (YAML).")] = None,
    ) -> None:
        """Grid Markov localization on FHW: speed (real-time factor), accuracy, global, kidnap recovery."""
        from rich.progress import Progress

        from tourbot.errors import InputError
        from tourbot.localization.beam_filters import BeamFilter
        from tourbot.localization.profile import LocalizationProfile

        def split(text: str) -> list[str]:
            return [t.strip() for t in text.split(",") if t.strip()]

        def numbers(text: str, field: str) -> list[int]:
            try:
                return [int(t) for t in split(text)]
            except ValueError:
                raise InputError(f"expected comma-separated integers, got {text!r}", field=field) from None

        known = {f.value for f in BeamFilter}
        for field, value in (("--filters", filters), ("--kidnap-filters", kidnap_filters)):
            bad = [f for f in split(value) if f not in known]
            if bad:
                raise InputError(f"unknown beam filter {bad[0]!r} (choose from {sorted(known)})", field=field)

        with Progress() as progress:
            report = run_grid_bench(
                log_name=log,
                filters=split(filters),
                scans=scans or None,
                global_starts=numbers(global_starts, "--global-starts"),
                kidnap_filters=split(kidnap_filters),
                kidnap_seeds=numbers(kidnap_seeds, "--kidnap-seeds"),
                progress=progress,
                picture=(output or default_output("grid")).with_suffix(".png"),
                config=LocalizationProfile.load(config).grid,
            )
        report.finish(output)
