"""``tourbot bench localization``: Fox et al. (1998) Table 1 on crowded real logs, against Nav2 AMCL.

For each log (FHW museum; optionally Intel as a second building), each seed and each localizer
(MCL and grid Markov localization, each without filter, with the entropy filter and with the
novelty filter; Nav2 AMCL through the ``amcl`` package), on logs overlaid with the crowd of
:mod:`tourbot.sim.overlay` (the one crowd model):

- *tracking* from the first reference pose on the ``sparse`` and the ``peak`` crowd: failures
  (% of scans whose estimate is > 45 cm from the reference, the paper's criterion), mean position
  and heading error, CPU time per update and real-time factor (log duration / total CPU time of
  the updates; CPU time because the machine is shared);
- *recovery* on the peak crowd with kidnaps (:mod:`tourbot.sim.kidnap`, 0.005 per metre):
  for each kidnap, whether and when the error stays < 45 cm for more than 10 s (the paper's
  criterion), in seconds and metres travelled;
- *global localization* from a uniform start on the first ``global_scans`` scans of the peak crowd:
  success and time until the error stays < 45 cm for more than 10 s.

Every figure is a mean over seeds with a 95 % confidence interval (Student t). Speed at the
project's target budget (5000 samples, all 180 beams) is measured side by side for MCL and AMCL on
``speed_scans`` scans. Crowded logs and maps are cached in ``--cache``. Seed ``s`` (of
``--first-seed`` .. ``--first-seed + --seeds - 1``) seeds the crowds, the kidnaps and the
localizers alike, so fresh seeds can be run apart from the earlier ones; the JSON keeps each
kidnap's outcome per seed.

``--workers N`` runs the (log, seed, method) tasks in a pool of N spawned processes (the crowds
are built first, in this process, and cached). Each task's randomness comes from its seed alone,
so the JSON is the one a single process writes, apart from the timings (CPU time per update,
real-time factor, the speed notes). Nav2 AMCL cannot be seeded: its figures vary from run to run
whatever the workers.
"""

from __future__ import annotations

import math
import multiprocessing
import signal
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Annotated, Any, Protocol

import numpy as np
import typer
from numpy.typing import ArrayLike, NDArray

from tourbot.bench._report import BenchReport
from tourbot.errors import TourbotError
from tourbot.metrics import (
    FAILURE_DISTANCE,
    failure_rate,
    mean_ci,
    pose_errors,
    recovery,
    settle_index,
)

__all__ = ["RunResult", "register"]

FloatArray = NDArray[np.float64]
KIDNAP_SEED_OFFSET = 10_000
PARTS = ("sparse", "peak", "kidnaps", "global")
METHODS = ("mcl-none", "mcl-entropy", "mcl-novelty", "grid-none", "grid-entropy", "grid-novelty", "amcl")
_GRIDS: dict[int, Any] = {}


class Localizer(Protocol):
    def update(self, odom_pose: ArrayLike, scan: Any) -> Any: ...


# --------------------------------------------------------------------------------------------
# Runs
# --------------------------------------------------------------------------------------------


@dataclass
class RunResult:
    est: FloatArray
    seconds: FloatArray
    used: NDArray[np.bool_]
    extra: dict[str, Any] = field(default_factory=dict)


def jumps(est: ArrayLike, ref: ArrayLike, threshold: float = 2.0) -> int:
    """Scans where the estimate moved more than ``threshold`` metres away from the reference's own step."""
    e = np.asarray(est, dtype=np.float64)
    r = np.asarray(ref, dtype=np.float64)[: len(e)]
    step = np.diff(e[:, :2], axis=0) - np.diff(r[:, :2], axis=0)
    return int(np.sum(np.hypot(step[:, 0], step[:, 1]) > threshold))


def _run(loc: Localizer, log: Any, scans: int | None = None) -> RunResult:
    chosen = log.scans[:scans] if scans else log.scans
    est = np.zeros((len(chosen), 3))
    secs = np.zeros(len(chosen))
    used = np.zeros((len(chosen), chosen[0].ranges.size), dtype=bool)
    for i, scan in enumerate(chosen):
        t0 = time.process_time()  # CPU time: the machine is shared, the wall clock is not ours
        e = loc.update(scan.odom, scan)
        secs[i] = time.process_time() - t0
        est[i] = e.pose
        used[i, : e.used_beams.size] = e.used_beams
    return RunResult(est, secs, used)


def _factory(
    method: str,
    grid: Any,
    particles: int,
    *,
    fixed: bool = False,
    beams: int | None = None,
    profile: Any = None,
) -> Callable[[str, Any, int], Localizer]:
    """A function ``(start, first_pose, seed) -> localizer`` for ``method`` (start: ``tracking``
    or ``global``). ``fixed`` holds the sample count at ``particles`` (no KLD adaptation); ``beams``
    sets AMCL's ``max_beams``. The grid localizer (and its expected-range table) is built once."""
    from tourbot.localization.beam_filters import BeamFilter

    kind, _, filt = method.partition("-")
    if kind == "mcl":
        from tourbot.localization.mcl import MonteCarloLocalization

        cfg = profile.mcl.with_filter(BeamFilter(filt)).with_samples(particles, fixed=fixed)

        def make_mcl(start: str, pose: Any, seed: int) -> Localizer:
            m = MonteCarloLocalization(grid, cfg, seed=seed)
            if start == "global":
                m.reset_global()
            else:
                m.reset_tracking(pose)
            return m

        return make_mcl
    if kind == "grid":
        from tourbot.localization.grid_markov import GridMarkovLocalization

        # One lattice and expected-range table for the three filters (it is the costly part).
        shared = _GRIDS.get(id(grid))
        if shared is None:
            shared = _GRIDS[id(grid)] = GridMarkovLocalization(grid, profile.grid)
        shared.config = replace(profile.grid, beam_filter=BeamFilter(filt))

        def make_grid(start: str, pose: Any, seed: int) -> Localizer:  # noqa: ARG001 (deterministic)
            if start == "global":
                shared.reset_global()
            else:
                shared.reset_tracking(pose, np.diag(np.square((0.1, 0.1, math.radians(5.0)))))
            return shared

        return make_grid
    if kind == "amcl":
        from tourbot.bench.peers.amcl_adapter import AMCLLocalizer, AMCLParams

        params = AMCLParams(max_particles=particles)
        if fixed:
            params = replace(params, min_particles=particles)
        if beams is not None:
            params = replace(params, max_beams=beams)
        a = AMCLLocalizer(grid, params)

        def make_amcl(start: str, pose: Any, seed: int) -> Localizer:  # noqa: ARG001 (unseedable)
            if start == "global":
                a.reset_global()
            else:
                a.reset_tracking(pose)
            return a

        return make_amcl
    raise typer.BadParameter(f"unknown method {method!r}; choose from {', '.join(METHODS)}")


# --------------------------------------------------------------------------------------------
# One task of the sweep: (log, seed, method), run in this process or in a worker of a pool
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SeedData:
    """One seed's crowded logs and kidnaps (built in the parent, cached on disk)."""

    sparse: Any  # None when the sparse runs are left out (--parts)
    peak: Any
    kidnapped: Any
    kidnaps: list[int]


@dataclass(frozen=True)
class Sweep:
    """What every task of one log needs: sent once to each worker, not once per task."""

    grid: Any
    ref: FloatArray
    times: FloatArray
    path: FloatArray
    duration: float
    particles: int
    global_scans: int
    profile: Any
    seeds: dict[int, SeedData]
    parts: tuple[str, ...] = PARTS


@dataclass(frozen=True)
class SeedOutcome:
    """One (log, seed, method) task's figures; ``peak_run`` is kept only for the figure's seed."""

    fail_sparse: float  # NaN (and jumps None, recoveries None) for the runs left out
    fail_peak: float
    err_peak_cm: float
    jumps: int | None
    heading_deg: float
    ms_per_update: float  # timing: differs from run to run
    real_time_factor: float  # timing
    recoveries: list[Any] | None  # None without kidnaps; else one Recovery (or None: censored) each
    global_ok: float
    global_s: float
    peak_run: RunResult | None


Task = tuple[str, int, str]  # (log, seed, method)
_SWEEPS: dict[str, Sweep] = {}


def _install(sweeps: dict[str, Sweep]) -> None:
    """Make ``sweeps`` the data that :func:`run_task` reads (in this process)."""
    _SWEEPS.clear()
    _SWEEPS.update(sweeps)


def _worker_start(sweeps: dict[str, Sweep]) -> None:
    """A pool worker's initializer: Ctrl-C is the parent's to handle (it stops the pool)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _install(sweeps)


def run_task(name: str, seed: int, method: str, keep_run: bool = False) -> SeedOutcome:
    """The tracking, kidnap and global runs of ``method`` on log ``name``'s crowds of ``seed``.

    Top-level (picklable) for a process pool. All its randomness comes from ``seed`` (the crowds,
    the kidnaps and the localizer's generator, ``numpy.random.default_rng(seed)``, that is a
    ``SeedSequence`` of the seed), none from the state of the process, so 1 or N workers give the
    same figures."""
    sw = _SWEEPS[name]
    d = sw.seeds[seed]
    ref = sw.ref
    make = _factory(method, sw.grid, sw.particles, profile=sw.profile)
    first = tuple(ref[0])
    nan = math.nan
    fail_s = fail_p = err_p = head_p = ms = rtf = glob_ok = glob_s = nan
    leaps: int | None = None
    judged = None
    r_p: RunResult | None = None
    if "sparse" in sw.parts:
        r_s = _run(make("tracking", first, seed), d.sparse)
        e_s, _ = pose_errors(r_s.est, ref[: len(r_s.est)])
        fail_s = 100.0 * failure_rate(e_s)
    if "peak" in sw.parts:
        r_p = _run(make("tracking", first, seed), d.peak)
        e_p, h_p = pose_errors(r_p.est, ref[: len(r_p.est)])
        fail_p, err_p = 100.0 * failure_rate(e_p), 100.0 * float(e_p.mean())
        head_p, leaps = float(np.degrees(h_p.mean())), jumps(r_p.est, ref)
        ms = 1000.0 * float(np.mean(r_p.seconds))
        rtf = sw.duration / max(float(r_p.seconds.sum()), 1e-12)
    if "kidnaps" in sw.parts and d.kidnaps:
        r_k = _run(make("tracking", first, seed), d.kidnapped)
        e_k, _ = pose_errors(r_k.est, ref[: len(r_k.est)])
        judged = recovery(e_k, sw.times, d.kidnaps, sw.path)
    if "global" in sw.parts:
        r_g = _run(make("global", first, seed), d.peak, sw.global_scans)
        e_g, _ = pose_errors(r_g.est, ref[: len(r_g.est)])
        j = settle_index(e_g, sw.times, 0, len(e_g))
        glob_ok = 100.0 * (j is not None)
        glob_s = nan if j is None else float(sw.times[j] - sw.times[0])
    return SeedOutcome(
        fail_sparse=fail_s,
        fail_peak=fail_p,
        err_peak_cm=err_p,
        jumps=leaps,
        heading_deg=head_p,
        ms_per_update=ms,
        real_time_factor=rtf,
        recoveries=judged,
        global_ok=glob_ok,
        global_s=glob_s,
        peak_run=r_p if keep_run else None,
    )


def _failed(task: Task, exc: BaseException) -> TourbotError:
    name, seed, method = task
    first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return TourbotError(
        f"task (log {name}, seed {seed}, method {method}) failed: {type(exc).__name__}"
        + (f": {first}" if first else "")
    )


def run_task_with(sweeps: dict[str, Sweep], name: str, seed: int, method: str, keep_run: bool) -> SeedOutcome:
    """:func:`run_task` on a Dask worker: ``sweeps`` (scattered once to every worker) installed
    in the worker's process the first time, then the task."""
    if _SWEEPS_ID[0] != id(sweeps):
        _install(sweeps)
        _SWEEPS_ID[0] = id(sweeps)
    return run_task(name, seed, method, keep_run=keep_run)


_SWEEPS_ID = [0]


def _take(out: dict[Task, SeedOutcome], task: Task, future: Any) -> None:
    """A finished task's outcome into ``out``; its exception as one error naming the task."""
    try:
        out[task] = future.result()
    except Exception as exc:
        raise _failed(task, exc) from exc


def run_tasks(
    sweeps: dict[str, Sweep],
    tasks: list[Task],
    workers: int,
    keep: Callable[[Task], bool],
    advance: Callable[[int], None] | None = None,
    dask: str | None = None,
) -> dict[Task, SeedOutcome]:
    """Every task's outcome, by task; in this process (``workers == 1``), in a pool of
    ``workers`` spawned processes, or on a Dask ``distributed`` cluster (``dask``: the scheduler's
    address, or ``"local"`` for a ``LocalCluster`` of ``workers`` processes). ``advance(running)``
    is called after each task that ends. A task's exception becomes one :class:`TourbotError`
    naming the task; Ctrl-C stops the pool."""
    out: dict[Task, SeedOutcome] = {}
    if dask is not None:
        return _run_on_dask(sweeps, tasks, workers, keep, advance, dask)
    if workers == 1:
        _install(sweeps)
        for task in tasks:
            try:
                out[task] = run_task(*task, keep_run=keep(task))
            except (KeyboardInterrupt, TourbotError):
                raise
            except Exception as exc:
                raise _failed(task, exc) from exc
            if advance is not None:
                advance(min(1, len(tasks) - len(out)))
        return out
    pool = ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_worker_start,
        initargs=(sweeps,),
    )
    try:
        pending: dict[Future[SeedOutcome], Task] = {
            pool.submit(run_task, *task, keep_run=keep(task)): task for task in tasks
        }
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                _take(out, pending.pop(future), future)
                if advance is not None:
                    advance(min(workers, len(pending)))
    except BaseException:
        # A failed task or Ctrl-C: the queued tasks are dropped and the running ones stopped.
        processes = getattr(pool, "_processes", None) or {}
        for process in list(processes.values()):
            process.terminate()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()
    return out


def _run_on_dask(
    sweeps: dict[str, Sweep],
    tasks: list[Task],
    workers: int,
    keep: Callable[[Task], bool],
    advance: Callable[[int], None] | None,
    address: str,
) -> dict[Task, SeedOutcome]:
    """The tasks on a Dask cluster: the sweeps broadcast once, a future per task."""
    from contextlib import ExitStack

    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise TourbotError("--dask needs Dask's distributed: pip install 'tourbot[cluster]'") from None
    out: dict[Task, SeedOutcome] = {}
    with ExitStack() as stack:
        if address == "local":
            cluster = stack.enter_context(
                LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
            )
            client = stack.enter_context(Client(cluster))
        else:
            try:
                client = stack.enter_context(Client(address, timeout=10))
            except (OSError, TimeoutError) as exc:
                raise TourbotError(f"--dask {address}: no Dask scheduler answers ({exc})") from None
        (shared,) = client.scatter([sweeps], broadcast=True, hash=False)  # one object, to every worker
        pending = {
            client.submit(run_task_with, shared, *task, keep_run=keep(task), pure=False): task
            for task in tasks
        }
        for future in as_completed(list(pending)):
            _take(out, pending.pop(future), future)
            if advance is not None:
                advance(min(len(pending), max(1, len(client.scheduler_info().get("workers", {})))))
    return out


# --------------------------------------------------------------------------------------------
# Data: maps and crowded logs, cached
# --------------------------------------------------------------------------------------------


def _crowded(log: Any, grid: Any, name: str, preset: str, seed: int, cache: Path) -> tuple[Any, Any]:
    name = f"{name}{len(log.scans)}"
    from tourbot.io import read_carmen, write_carmen
    from tourbot.sim.overlay import OverlayConfig, overlay_crowd, read_truth, truth_path, write_truth

    path = cache / f"{name}-{preset}-{seed}-{log.odometry_kind}.log.gz"  # never an older odometry's
    if path.exists() and truth_path(path).exists():
        return read_carmen(path), read_truth(truth_path(path))
    result = overlay_crowd(log, grid, OverlayConfig.preset(preset), seed=seed, preset=preset)
    write_carmen(result.log, path)
    write_truth(result.truth, truth_path(path))
    return read_carmen(path), result.truth


# --------------------------------------------------------------------------------------------
# The command
# --------------------------------------------------------------------------------------------


def register(bench: typer.Typer) -> None:
    @bench.command("localization")
    def localization(
        logs: Annotated[
            str, typer.Option(help="Logs, comma-separated: fhw, intel, aces, freiburg-079.")
        ] = "fhw",
        methods: Annotated[str, typer.Option(help="Localizers, comma-separated.")] = ",".join(METHODS),
        seeds: Annotated[
            int, typer.Option(help="Seeds (crowds, kidnaps, filters); >= 5 for the report.")
        ] = 5,
        first_seed: Annotated[
            int, typer.Option(help="First seed: seeds FIRST_SEED .. FIRST_SEED + SEEDS - 1 are run.")
        ] = 0,
        particles: Annotated[
            int, typer.Option(help="Sample budget of MCL and AMCL for accuracy (Nav2's max_particles).")
        ] = 2000,
        global_scans: Annotated[int, typer.Option(help="Scans of the global-localization runs.")] = 60,
        speed_scans: Annotated[int, typer.Option(help="Scans timed at 5000 samples and all beams.")] = 30,
        quick: Annotated[bool, typer.Option(help="A small run for smoke tests: 1 seed, 25 scans.")] = False,
        scans: Annotated[
            int | None, typer.Option(help="Use only the first SCANS scans of each log (a shorter tour).")
        ] = None,
        parts: Annotated[
            str,
            typer.Option(
                help="Runs, comma-separated: sparse, peak (tracking in each crowd), kidnaps, global; "
                "the others are left out of the table ('-')."
            ),
        ] = ",".join(PARTS),
        cache: Annotated[Path, typer.Option(help="Cache of maps and crowded logs.")] = Path(
            "bench-results/cache/localization"
        ),
        kidnap_rate: Annotated[
            float, typer.Option(help="Kidnaps per metre (the paper: 0.005; raise it for short runs).")
        ] = 0.005,
        figure: Annotated[bool, typer.Option(help="Draw the Fig. 5-like picture.")] = True,
        output: Annotated[Path | None, typer.Option("-o", "--output", help="JSON file to write.")] = None,
        config: Annotated[
            Path | None, typer.Option("--config", help="Localization profile (YAML; tourbot config show).")
        ] = None,
        workers: Annotated[
            int, typer.Option(help="Processes running the (log, seed, method) tasks; 1: in this one.")
        ] = 1,
        dask: Annotated[
            str | None,
            typer.Option(
                "--dask",
                metavar="ADDRESS",
                help="Run the tasks on a Dask distributed scheduler (tcp://HOST:8786), or 'local' for a "
                "LocalCluster of --workers processes.",
            ),
        ] = None,
    ) -> None:
        """Failures, errors, kidnap recovery, global localization and speed in crowds, vs Nav2 AMCL."""
        from rich.console import Console

        from tourbot.bench.logs import chosen_logs, reference_map
        from tourbot.bench.peers.amcl_adapter import amcl_available
        from tourbot.io import read_carmen
        from tourbot.io.progress import ScanProgress
        from tourbot.sim.kidnap import KidnapConfig, apply_kidnaps, plan_kidnaps

        console = Console()
        from tourbot.localization.profile import LocalizationProfile

        profile = LocalizationProfile.load(config)
        if first_seed < 0:
            raise TourbotError(f"--first-seed must be >= 0, not {first_seed}")
        if workers < 1:
            raise TourbotError(f"--workers must be >= 1, not {workers}")
        files = chosen_logs(logs)
        names = list(files)
        chosen = [m.strip() for m in methods.split(",") if m.strip()]
        runs = tuple(p.strip() for p in parts.split(",") if p.strip())
        for p in runs:
            if p not in PARTS:
                raise TourbotError(f"--parts: unknown run {p!r}; choose from {', '.join(PARTS)}")
        if not runs:
            raise TourbotError(f"--parts names no run; choose from {', '.join(PARTS)}")
        if "amcl" in chosen and not amcl_available():
            console.print("[yellow]amcl not installed: Nav2 AMCL left out (pip install amcl)[/]")
            chosen.remove("amcl")
        n_seeds = 1 if quick else seeds
        limit = 25 if quick else scans
        g_scans = min(global_scans, 25) if quick else global_scans
        cache.mkdir(parents=True, exist_ok=True)

        report = BenchReport(
            "localization",
            [
                "log",
                "method",
                "fail sparse %",
                "fail peak %",
                "err peak cm",
                "jumps>2m peak",
                "head peak deg",
                "recovered %",
                "t rec s",
                "d rec m",
                "global ok %",
                "t global s",
                "ms/update",
                "x real time",
            ],
        )
        report.meta = {
            "config": str(config) if config is not None else "defaults",
            "seeds": n_seeds,
            "first_seed": first_seed,
            "particles": particles,
            "global_scans": g_scans,
            "scans": limit,
            "kidnap_rate_per_m": kidnap_rate,
            "quick": quick,
            "workers": workers,
            "dask": dask,
            "crowd": {},
            "parts": list(runs),
        }
        figure_runs: dict[str, tuple[RunResult, Any]] = {}
        sweeps: dict[str, Sweep] = {}
        bases: dict[str, Any] = {}
        seed_list = list(range(first_seed, first_seed + n_seeds))
        for name in names:
            base = read_carmen(files[name])
            grid = reference_map(base, name, cache)  # the whole log's reference map
            if limit:
                base = replace(base, scans=base.scans[:limit])
            bases[name] = base
            ref = base.reference_poses
            path = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(ref[:, :2], axis=0).T))])
            per_seed: dict[int, SeedData] = {}
            fractions: list[tuple[float, float]] = []
            longest: list[float] = []
            with ScanProgress(f"{name}: crowds", 2 * n_seeds, unit="crowds") as crowds:
                for seed in seed_list:
                    sparse, sparse_truth = (
                        _crowded(base, grid, name, "sparse", seed, cache)
                        if "sparse" in runs
                        else (None, None)
                    )
                    crowds.advance()
                    peak, peak_truth = _crowded(base, grid, name, "peak", seed, cache)
                    crowds.advance()
                    kid_rng = np.random.default_rng(KIDNAP_SEED_OFFSET + seed)
                    kidnaps = plan_kidnaps(
                        ref, base.times, kid_rng, KidnapConfig(probability_per_metre=kidnap_rate)
                    )
                    per_seed[seed] = SeedData(
                        sparse, peak, apply_kidnaps(peak, kidnaps), [k.scan for k in kidnaps]
                    )
                    fractions.append(
                        (
                            math.nan if sparse_truth is None else float(sparse_truth.fraction.mean()),
                            float(peak_truth.fraction.mean()),
                        )
                    )
                    longest.append(peak_truth.longest_above(0.5))
            sweeps[name] = Sweep(
                grid=grid,
                ref=ref,
                times=np.asarray(base.times, dtype=np.float64),
                path=path,
                duration=float(base.times[-1] - base.times[0]),
                particles=particles,
                global_scans=g_scans,
                profile=profile,
                seeds=per_seed,
                parts=runs,
            )
            report.meta["crowd"][name] = {
                "sparse_mean_corrupted": mean_ci([f[0] for f in fractions]),
                "peak_mean_corrupted": mean_ci([f[1] for f in fractions]),
                "peak_longest_above_50_s": mean_ci(longest),
                "kidnaps": [per_seed[s].kidnaps for s in seed_list],
            }
        tasks = [(name, seed, method) for name in names for method in chosen for seed in seed_list]
        label = f"{len(tasks)} tasks, " + (
            f"Dask {dask}" if dask else f"{workers} worker{'s' if workers > 1 else ''}"
        )
        with ScanProgress(label, len(tasks), unit="tasks") as done:
            # The figure shows the first log's runs of the first seed.
            results = run_tasks(
                sweeps,
                tasks,
                workers,
                lambda t: t[0] == names[0] and t[1] == first_seed,
                lambda running: done.advance(running=running),
                dask,
            )
        for name in names:
            for method in chosen:
                outcomes = [results[(name, seed, method)] for seed in seed_list]
                _add_row(report, name, method, seed_list, outcomes, sweeps[name].seeds)
                kept = results[(name, first_seed, method)].peak_run
                if name == names[0] and kept is not None:
                    figure_runs[method] = (kept, sweeps[name].seeds[first_seed].peak)
        first_log = names[0]
        duration0 = sweeps[first_log].duration
        grid0 = sweeps[first_log].grid
        _speed(report, bases[first_log], grid0, chosen, duration0, speed_scans if not quick else 5, profile)
        if figure and figure_runs:
            pic = (output or Path("bench-results/localization.json")).with_name("localization-fig5.png")
            _figure(figure_runs, grid0, sweeps[first_log].ref, pic)
            report.notes.append(f"Fig. 5-like picture (peak crowd, seed {first_seed}): {pic}")
        for name, c in report.meta["crowd"].items():
            s, p, longest = c["sparse_mean_corrupted"], c["peak_mean_corrupted"], c["peak_longest_above_50_s"]
            report.notes.append(
                f"{name}: corrupted beams sparse {100 * s[0]:.1f} ± {100 * s[1]:.1f} %, peak "
                f"{100 * p[0]:.1f} ± {100 * p[1]:.1f} % (longest stretch above 50 %: {longest[0]:.0f} s); "
                f"kidnaps per seed {[len(k) for k in c['kidnaps']]}"
            )
        report.finish(output, console)


def _add_row(
    report: BenchReport,
    name: str,
    method: str,
    seeds: list[int],
    outcomes: list[SeedOutcome],
    data: dict[int, SeedData],
) -> None:
    """One table row (mean ± 95 % CI over seeds) from the seeds' outcomes, in seed order."""
    rec_ok: list[float] = []
    rec_t: list[float] = []
    rec_d: list[float] = []
    censored = 0
    per_seed: dict[int, list[Any]] = {}
    for seed, o in zip(seeds, outcomes, strict=True):
        if o.recoveries is None:
            continue
        per_seed[seed] = [
            {"scan": k, "outcome": None if r is None else [r.recovered, r.seconds, r.metres]}
            for k, r in zip(data[seed].kidnaps, o.recoveries, strict=True)
        ]
        for r in o.recoveries:
            if r is None:
                censored += 1
                continue
            rec_ok.append(100.0 * r.recovered)
            rec_t.append(r.seconds)
            rec_d.append(r.metres)
    fails_s = [o.fail_sparse for o in outcomes]
    fails_p = [o.fail_peak for o in outcomes]
    errs = [o.err_peak_cm for o in outcomes]
    leaps = [o.jumps for o in outcomes]
    counted = [n for n in leaps if n is not None]
    heads = [o.heading_deg for o in outcomes]
    secs = [o.ms_per_update for o in outcomes]
    rtf = [o.real_time_factor for o in outcomes]
    glob_ok = [o.global_ok for o in outcomes]
    glob_t = [o.global_s for o in outcomes]

    def fmt(values: list[float], digits: int = 1) -> str:
        m, h = mean_ci(values)
        return "-" if math.isnan(m) else f"{m:.{digits}f} ± {h:.{digits}f}"

    report.add(
        **{
            "log": name,
            "method": method,
            "fail sparse %": fmt(fails_s),
            "fail peak %": fmt(fails_p),
            "err peak cm": fmt(errs),
            "jumps>2m peak": "-"
            if len(counted) < len(leaps)
            else f"{sum(counted)} (max {max(counted, default=0)} a seed)",
            "head peak deg": fmt(heads, 2),
            "recovered %": fmt(rec_ok, 0)
            + f" (n={len(rec_ok)}"
            + (f", {censored} censored)" if censored else ")"),
            "t rec s": fmt(rec_t),
            "d rec m": fmt(rec_d),
            "global ok %": fmt(glob_ok, 0),
            "t global s": fmt(glob_t),
            "ms/update": fmt(secs),
            "x real time": fmt(rtf, 0),
            "raw": {
                "fail_sparse": fails_s,
                "fail_peak": fails_p,
                "err_peak_cm": errs,
                "jumps_2m_peak": leaps,
                "heading_peak_deg": heads,
                "recovered": rec_ok,
                "kidnaps_censored": censored,
                "kidnaps_per_seed": per_seed,
                "recovery_s": rec_t,
                "recovery_m": rec_d,
                "global_ok": glob_ok,
                "global_s": glob_t,
                "ms_per_update": secs,
                "real_time_factor": rtf,
            },
        }
    )


def _speed(
    report: BenchReport, log: Any, grid: Any, methods: list[str], duration: float, scans: int, profile: Any
) -> None:
    """MCL vs AMCL at 5000 samples and all beams, side by side on the same scans."""
    per_scan = duration / max(1, len(log.scans) - 1)
    timed: dict[str, float] = {}
    for method in ("mcl-novelty", "mcl-none", "amcl"):
        if method not in methods:
            continue
        make = _factory(method, grid, 5000, fixed=True, beams=log.scans[0].ranges.size, profile=profile)
        loc = make("tracking", tuple(log.reference_poses[0]), 0)
        r = _run(loc, log, scans)
        timed[method] = float(np.median(r.seconds[1:] if len(r.seconds) > 1 else r.seconds))
    for method, s in timed.items():
        ratio = timed.get("amcl", math.nan) / s if method != "amcl" else 1.0
        report.notes.append(
            f"speed, 5000 samples, all {log.scans[0].ranges.size} beams, {scans} scans: {method} "
            f"{1000 * s:.1f} ms/update median, {per_scan / s:.0f}x real time; AMCL/this = {ratio:.1f}x"
        )
    report.meta["speed_5000_all_beams_s"] = timed


def _figure(runs: dict[str, tuple[RunResult, Any]], grid: Any, ref: FloatArray, path: Path) -> None:
    """Estimated and reference paths with the endpoints of the integrated beams, one panel per
    localizer (Fox et al. 1998, Fig. 5), on the peak-crowd log."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tourbot.geometry import compose

    n = len(runs)
    cols = min(4, n)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 5.5 * rows), squeeze=False)
    extent = (
        grid.origin[0],
        grid.origin[0] + grid.width,
        grid.origin[1],
        grid.origin[1] + grid.height,
    )
    image = np.where(grid.prob < 0, 0.85, 1.0 - 0.8 * grid.prob)
    for ax, (method, (run, log)) in zip(axes.ravel(), runs.items(), strict=False):
        ax.imshow(image, origin="lower", cmap="gray", vmin=0, vmax=1, extent=extent)
        pts = []
        for i in range(0, len(run.est), 3):
            scan = log.scans[i]
            g = scan.geometry
            laser = compose(run.est[i], g.offset)
            u = run.used[i, : g.num_beams] & (scan.ranges < g.max_range)
            a = laser[2] + g.angles[u]
            r = scan.ranges[u]
            pts.append(np.stack([laser[0] + r * np.cos(a), laser[1] + r * np.sin(a)], axis=-1))
        if pts:
            p = np.concatenate(pts)
            ax.scatter(p[:, 0], p[:, 1], s=0.3, c="tab:orange", alpha=0.5, linewidths=0)
        ax.plot(ref[: len(run.est), 0], ref[: len(run.est), 1], "k-", lw=0.8, label="reference")
        ax.plot(run.est[:, 0], run.est[:, 1], "b-", lw=0.8, label="estimate")
        err = np.hypot(*(run.est[:, :2] - ref[: len(run.est), :2]).T)
        ax.set_title(f"{method}: {100 * np.mean(err > FAILURE_DISTANCE):.1f} % failures", fontsize=9)
        lo = ref[: len(run.est), :2].min(axis=0) - 6.0
        hi = ref[: len(run.est), :2].max(axis=0) + 6.0
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.tick_params(labelsize=6)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    axes.ravel()[0].legend(fontsize=6, loc="lower left")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
