"""``tourbot bench kernels``: speed of the range-sensing kernels on the real FHW map.

Per-core figures: every kernel is a plain (non-parallel) numba function and numba is pinned to one
thread; time is the CPU time of the calling thread (``time.thread_time``), best of ``--repeat``
runs, so other jobs on the shared machine inflate the figures less than wall-clock time would.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

__all__ = ["register"]

TARGET_RAYS = 25e6  # rays/s/core for the accelerated caster (issue 2, section 4)
TARGET_RATIO = 10.0  # accelerated caster vs the DDA, same run
TARGET_LF = 500e6  # likelihood-field beam evaluations/s/core
RANGE_LIBC = "range_libc (C++) publishes 2.6 M rays/s/core for Bresenham and ~23 M for its best CPU method"


def register(bench: typer.Typer) -> None:
    @bench.command("kernels")
    def kernels(
        resolution: Annotated[float, typer.Option(help="Map resolution, metres.")] = 0.05,
        particles: Annotated[int, typer.Option(help="Poses cast per run (x 180 beams).")] = 2000,
        field_poses: Annotated[int, typer.Option(help="Poses scored per likelihood-field run.")] = 20000,
        max_range: Annotated[
            list[float] | None, typer.Option(help="Caster max ranges, metres (default 10 and the laser's).")
        ] = None,
        repeat: Annotated[int, typer.Option(help="Runs per figure; the best one counts.")] = 3,
        seed: Annotated[int, typer.Option(help="Seed of the sampled poses.")] = 0,
        output: Annotated[
            Path | None,
            typer.Option("-o", "--output", help="JSON output (default bench-results/kernels.json)."),
        ] = None,
    ) -> None:
        """Rays/s/core of each caster, beam evaluations/s/core of the likelihood field and the beam
        model, build time and memory, on the FHW map built from the real log."""
        from tourbot.errors import InputError

        for name, value in (("--particles", particles), ("--field-poses", field_poses), ("--repeat", repeat)):
            if value < 1:
                raise InputError(f"{name} must be at least 1, got {value}", field=name)
        if max_range is not None and min(max_range) <= 0:
            raise InputError(f"--max-range must be positive, got {min(max_range)}", field="--max-range")
        _run(resolution, particles, field_poses, max_range, repeat, seed, output)


def _best_time(fn: object, repeat: int) -> float:
    import time

    assert callable(fn)
    fn()  # compile / warm caches
    best = float("inf")
    for _ in range(max(1, repeat)):
        t0 = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t0)
    return max(best, 1e-9)


def _casts(
    report: Any,
    log: Any,
    grid: Any,
    lasers: Any,
    angles: Any,
    max_ranges: list[float],
    repeat: int,
) -> tuple[float, Any]:
    """Rows of the casters at each max range: speed, build, memory, agreement with the DDA on the
    sampled poses and with the log's real scans from its reference poses (every 5th scan).
    Returns the last max range and its DDA ranges (for the beam model rows)."""
    import time

    import numpy as np

    from tourbot.geometry import compose
    from tourbot.maps.raycast import DDACaster, DistanceCaster, RayCaster

    geom = log.scans[0].geometry
    n_rays = lasers.shape[0] * angles.shape[0]
    idx = np.arange(0, len(log), 5)
    real_lasers = compose(log.reference_poses[idx], np.asarray(geom.offset))
    real = log.ranges[idx]
    makers: list[tuple[str, str, Any]] = [
        ("DDACaster", "dda", lambda mr: DDACaster(grid, mr)),
        ("DistanceCaster", "distance", lambda mr: DistanceCaster(grid, mr)),
    ]
    dda_out = None
    for mr in max_ranges:
        cast_meta: dict[str, float] = {}
        measured = (real >= geom.min_range) & (real < mr)
        real_notes = []
        for label, key, make in makers:
            t0 = time.perf_counter()
            caster: RayCaster = make(mr)
            build_s = time.perf_counter() - t0
            out = caster.cast(lasers, angles)
            secs = _best_time(lambda c=caster: c.cast(lasers, angles), repeat)
            row: dict[str, Any] = {
                "kernel": f"cast {label}",
                "max range m": mr,
                "M evals/s/core": n_rays / secs / 1e6,
                "build s": build_s,
                "memory MB": caster.nbytes / 1e6,
            }
            cast_meta[f"{key}_rays_per_s"] = n_rays / secs
            if key == "dda":
                dda_out = out
                row["vs DDA"] = 1.0
                cast_meta["mean_range_m"] = float(out.mean())
            else:
                assert dda_out is not None
                acc = _agreement(out, dda_out, grid.resolution)
                row["vs DDA"] = cast_meta[f"{key}_rays_per_s"] / cast_meta["dda_rays_per_s"]
                row["check"] = (
                    f"{100 * acc['within_one_cell']:.2f}% within 1 cell of DDA; error median "
                    f"{acc['median_m']:.2g}, p99 {acc['p99_m']:.2g}, max {acc['max_m']:.2g} m"
                )
                cast_meta[f"{key}_ratio"] = row["vs DDA"]
                cast_meta.update({f"{key}_{k}": v for k, v in acc.items()})
            err = np.abs(caster.cast(real_lasers, geom.angles)[measured] - real[measured])
            cast_meta[f"{key}_real_median_m"] = float(np.median(err))
            cast_meta[f"{key}_real_within_10cm"] = float(np.mean(err < 0.1))
            real_notes.append(
                f"{label} {100 * np.median(err):.1f} cm ({100 * np.mean(err < 0.1):.0f}% within 10 cm)"
            )
            report.add(**row)
        report.meta[f"cast_{mr:g}m"] = cast_meta
        report.notes.append(
            f"Casts from the reference poses of every 5th scan against the real ranges "
            f"({int(measured.sum())} beams < {mr:g} m), median |cast - measured|: "
            + "; ".join(real_notes)
            + "."
        )
    assert dda_out is not None
    return max_ranges[-1], dda_out


def _agreement(ranges: object, dda: object, resolution: float) -> dict[str, float]:
    """How far a caster's ranges are from the DDA's: share within one cell, error quantiles (m)."""
    import numpy as np

    diff = np.abs(np.asarray(ranges, dtype=np.float64) - np.asarray(dda, dtype=np.float64))
    return {
        "within_one_cell": float(np.mean(diff <= resolution + 1e-6)),
        "median_m": float(np.median(diff)),
        "p99_m": float(np.percentile(diff, 99)),
        "max_m": float(diff.max()),
    }


def _run(
    resolution: float,
    particles: int,
    field_poses: int,
    max_ranges: list[float] | None,
    repeat: int,
    seed: int,
    output: Path | None,
) -> None:
    import os
    import time

    import numba
    import numpy as np
    from rich.console import Console
    from rich.progress import Progress

    from tourbot.bench._report import BenchReport
    from tourbot.data import find_data
    from tourbot.geometry import compose
    from tourbot.io.carmen import read_carmen
    from tourbot.maps.beam_model import BeamModel
    from tourbot.maps.likelihood_field import LikelihoodField
    from tourbot.maps.reference import build_reference_map

    numba.set_num_threads(1)
    console = Console()
    report = BenchReport(
        name="kernels",
        columns=["kernel", "max range m", "M evals/s/core", "vs DDA", "build s", "memory MB", "check"],
    )
    with Progress(console=console, transient=True) as progress:
        task = progress.add_task("FHW map", total=None)
        log = read_carmen(find_data("carmen/fhw-corrected.log.gz"))
        t0 = time.perf_counter()
        grid = build_reference_map(log, resolution)
        map_s = time.perf_counter() - t0
        progress.update(task, description="kernels")
        geom = log.scans[0].geometry
        rng = np.random.default_rng(seed)
        ref = log.reference_poses
        picks = rng.integers(0, len(log), particles)
        # particles around the true poses, as a localizer would spread them
        robot = ref[picks] + rng.normal(0.0, [0.2, 0.2, 0.1], (particles, 3))
        lasers = compose(robot, np.asarray(geom.offset))
        angles = geom.angles
        ranges_list = max_ranges or [10.0, geom.max_range]
        cast_for_model = _casts(report, log, grid, lasers, angles, ranges_list, repeat)

        # likelihood field: one real scan scored from many poses
        k = int(rng.integers(0, len(log)))
        scan = log.scans[k].ranges
        t0 = time.perf_counter()
        field = LikelihoodField.from_grid(grid, max_range=geom.max_range)
        lf_build = time.perf_counter() - t0
        poses = ref[k] + rng.normal(0.0, [0.3, 0.3, 0.1], (field_poses, 3))
        used = int(np.count_nonzero((scan < geom.max_range) & (scan >= geom.min_range)))
        evals = field_poses * used
        secs = _best_time(lambda: field.log_likelihood(poses, scan, geom), repeat)
        report.add(
            **{
                "kernel": "likelihood field, scan sums",
                "M evals/s/core": evals / secs / 1e6,
                "build s": lf_build,
                "memory MB": field.nbytes / 1e6,
            }
        )
        lf_rate = evals / secs
        secs = _best_time(lambda: field.beam_log_likelihoods(poses, scan, geom), repeat)
        report.add(**{"kernel": "likelihood field, per beam (N, B)", "M evals/s/core": evals / secs / 1e6})
        # the same scan from poses drawn over the whole free space (as a global localization
        # draws its candidates): many are near the map's edges, where beams end off the grid
        free = grid.free_cell_centres()
        spread = free[rng.integers(0, len(free), field_poses)]
        spread = np.column_stack([spread, rng.uniform(-np.pi, np.pi, field_poses)])
        secs = _best_time(lambda: field.log_likelihood(spread, scan, geom), repeat)
        lf_spread_rate = evals / secs
        report.add(
            **{"kernel": "likelihood field, scan sums, free space", "M evals/s/core": lf_spread_rate / 1e6}
        )

        # beam model on the cast expected ranges
        assert cast_for_model is not None
        mr, expected = cast_for_model
        model = BeamModel()
        meas = log.scans[int(picks[0])].ranges
        m_evals = expected.size
        secs = _best_time(lambda: model.probabilities(expected, meas, mr), repeat)
        report.add(
            **{"kernel": "beam model mixture", "max range m": mr, "M evals/s/core": m_evals / secs / 1e6}
        )
        secs = _best_time(lambda: model.prob_shorter(expected, meas, mr), repeat)
        report.add(
            **{
                "kernel": "beam model P(shorter), Fox Eq. 5",
                "max range m": mr,
                "M evals/s/core": m_evals / secs / 1e6,
            }
        )

    rows, cols = grid.shape
    report.meta.update(
        {
            "map": f"FHW, {rows} x {cols} cells at {resolution} m, built in {map_s:.1f} s",
            "rays_per_run": particles * geom.num_beams,
            "likelihood_field_evals_per_run": evals,
            "numba_threads": 1,
            "timing": "time.thread_time, best of repeat",
            "load_average_1min": os.getloadavg()[0],
        }
    )
    report.notes.insert(
        0,
        f"FHW map {rows} x {cols} at {resolution} m; {particles} poses (true poses + N(0, 0.2 m, 0.1 rad)) x "
        f"{geom.num_beams} beams; numba pinned to 1 thread, CPU time of the thread, best of {repeat}; "
        f"machine load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs (shared machine).",
    )
    casts = [v for key, v in report.meta.items() if key.startswith("cast_")]
    accelerated = [("distance", "DistanceCaster (exact)")]
    for key, name in accelerated:
        best_fast = max(v[f"{key}_rays_per_s"] for v in casts)
        worst_fast = min(v[f"{key}_rays_per_s"] for v in casts)
        worst_ratio = min(v[f"{key}_ratio"] for v in casts)
        report.notes.append(
            f"{name}: target >= {TARGET_RAYS / 1e6:.0f} M rays/s/core: "
            f"{'met' if worst_fast >= TARGET_RAYS else 'MISSED'} "
            f"({worst_fast / 1e6:.1f}-{best_fast / 1e6:.1f} M); "
            f"target >= {TARGET_RATIO:.0f}x DDA: {'met' if worst_ratio >= TARGET_RATIO else 'MISSED'} "
            f"(worst {worst_ratio:.1f}x)."
        )
    report.notes.append(f"{RANGE_LIBC}.")
    report.notes.append(
        f"target >= {TARGET_LF / 1e6:.0f} M likelihood-field evals/s/core: "
        f"{'met' if lf_rate >= TARGET_LF else 'MISSED'} ({lf_rate / 1e6:.0f} M; "
        f"{lf_spread_rate / 1e6:.0f} M from poses over the whole free space)."
    )
    report.finish(output, Console(width=150))
