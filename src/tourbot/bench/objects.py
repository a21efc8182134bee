"""``tourbot bench objects``: the experiments of Schulz and Burgard (2001, Sec. 4), and a real log.

Scenarios, each over ``--seeds`` seeds (95 % intervals, Student t), each with MCL localizing from
the scans and the object estimator integrating over its pose samples (Table 1):

- ``doors``: the simulated corridor with 14 doors passed at 0.7 m/s (Sec. 4.1). Mean angle error
  of the door estimates reported as well observed, milliseconds per door update.
- ``ushape``: the 37 x 37 cm U-shape passed twice, turned by 30 degrees, passed again (Sec. 4.2).
  Mean position / heading error of the well-observed estimates; whether the new heading is found
  (within 5 degrees) during the pass after the turn, and how long after the turn.
- ``desks``: four desks shifted 20 cm (Sec. 4.3). Mean position error of the three observable
  desks; how often the mostly hidden desk-3 was reported as well observed, and with what error.
- ``real``: FHW's real log (``../shared/data``), odometry rebuilt from its increments, with the
  doors and benches of the ``fhw-doors`` site overlaid in changing states and the peak crowd of
  visitors over them (``tourbot crowd --objects``).
- ``changed``: localization in a changed world (issue 15). MCL (the novelty filter, FHW's
  localization profile) on the same real log with the same peak crowd three times: the world
  unchanged (no objects overlaid), changed (the overlaid doors and benches) with the static map,
  and changed with the map holding the objects in their estimated states (``ObjectWorld`` through
  MCL's ``set_map``). Mean position error and failures (share of scans more than 45 cm off, Fox
  et al. 1998) of each.
- ``tours``: tours in the simulator with doors that close (``door_tour_site``): the doors always
  open, then closing at random with the static map only, then with the estimator feeding the
  navigator's and MCL's map. Tours completed (every exhibit, within the time limit), duration and
  the time lost against the run with the doors open (same seed).
- ``viewpoint``: going to look (beyond the paper): an unseen door 7 m away, at an opening drawn
  from the seed; the navigator is sent to the viewpoint :mod:`tourbot.objects.viewpoint` chooses;
  whether it arrives, and how many of the door's last 10 updates there are observed, how close.

Every scenario runs with the paper's scan alternation (``alternate``) and with every scan used
by both estimators (``all``) unless ``--share`` picks one; ``changed``, ``tours`` and ``viewpoint``
use every scan.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from numpy.typing import NDArray

from tourbot.bench._report import BenchReport

__all__ = ["register"]

FloatArray = NDArray[np.float64]
SCENARIOS = ("doors", "ushape", "desks", "real", "changed", "tours", "viewpoint")
SINGLE_SHARE = ("changed", "tours", "viewpoint")  # closed-loop scenarios: every scan, the default
TOUR_LIMIT = 900.0  # simulated seconds for the tour of ``tours``


@dataclass
class Trial:
    """One scenario, one seed, one scan share: the figures the table aggregates."""

    figures: dict[str, float]
    seconds: float


def _errors(
    run: Any, shapes: list[Any], truth_at: Callable[[int], list[FloatArray]]
) -> dict[str, list[tuple]]:
    """Per object: (scan, time, status, position error, angle error) of every update."""
    names = [s.name for s in shapes]
    out: dict[str, list[tuple]] = {n: [] for n in names}
    for k, est in run.updates:
        i = names.index(est.name)
        d, a = shapes[i].error(est.state, truth_at(k)[i])
        out[est.name].append((k, est.time, str(est.quality.status), d, a))
    return out


def _observed(rows: list[tuple]) -> list[tuple]:
    return [r for r in rows if r[2] == "observed"]


def _run(scenario: str, seed: int, share: Any, figure: Path | None) -> Trial:
    from tourbot.maps.objects import shapes_of_site
    from tourbot.objects.picture import draw_objects_figure
    from tourbot.objects.pipeline import estimate_log
    from tourbot.sim.object_scenes import corridor_scene, desk_scene, run_scene, ushape_scene

    t0 = time.perf_counter()
    figures: dict[str, float] = {}
    if scenario == "real":
        return _run_real(seed, share, figure)
    if scenario == "changed":
        return _run_changed(seed)
    if scenario == "tours":
        return _run_tours(seed)
    if scenario == "viewpoint":
        return _run_viewpoint(seed)
    builders: dict[str, Callable[[], Any]] = {
        "doors": corridor_scene,
        "ushape": ushape_scene,
        "desks": desk_scene,
    }
    scene = builders[scenario]()
    sim = run_scene(scene, seed)
    shapes = shapes_of_site(scene.model.doors, scene.model.furniture)
    run = estimate_log(sim.log, shapes, scene.model.grid, share=share, seed=seed)
    errs = _errors(run, shapes, lambda k: sim.truth[k])
    figures["ms_per_update"] = 1000 * float(np.median(run.update_seconds)) if run.update_seconds else math.nan
    figures["ms_p95"] = (
        1000 * float(np.percentile(run.update_seconds, 95)) if run.update_seconds else math.nan
    )
    obs_all = [r for rows in errs.values() for r in _observed(rows)]
    figures["observed_share"] = len(obs_all) / max(1, sum(len(r) for r in errs.values()))
    if scenario == "doors":
        figures["angle_err_deg"] = (
            math.degrees(float(np.mean([r[4] for r in obs_all]))) if obs_all else math.nan
        )
        figures["doors_observed"] = float(sum(1 for rows in errs.values() if _observed(rows)))
    elif scenario == "ushape":
        obs = _observed(errs["U"])
        figures["pos_err_cm"] = 100 * float(np.mean([r[3] for r in obs])) if obs else math.nan
        figures["angle_err_deg"] = math.degrees(float(np.mean([r[4] for r in obs]))) if obs else math.nan
        t_turn = scene.changes[0][0]
        after = [r for r in obs if r[1] >= t_turn]
        found = [r for r in after if r[4] < math.radians(5.0) and r[3] < 0.05]
        figures["turn_found"] = 1.0 if found else 0.0
        figures["found_after_s"] = float(found[0][1] - t_turn) if found else math.nan
        steady = [r for r in obs if r[1] < t_turn or (found and r[1] >= found[0][1])]
        figures["steady_pos_cm"] = 100 * float(np.mean([r[3] for r in steady])) if steady else math.nan
        figures["steady_angle_deg"] = (
            math.degrees(float(np.mean([r[4] for r in steady]))) if steady else math.nan
        )
    else:
        visible = [r for n in ("desk-1", "desk-2", "desk-4") for r in _observed(errs[n])]
        figures["pos_err_cm"] = 100 * float(np.mean([r[3] for r in visible])) if visible else math.nan
        hidden = errs["desk-3"]
        wrong = [r for r in _observed(hidden) if r[3] > 0.05]
        figures["desk3_observed_share"] = len(_observed(hidden)) / max(1, len(hidden))
        figures["desk3_wrong_found"] = float(len(wrong))
        figures["desk3_final_poor"] = (
            1.0
            if run.final[shapes.index(next(s for s in shapes if s.name == "desk-3"))].quality.poor
            else 0.0
        )
    if figure is not None:
        draw_objects_figure(
            figure,
            scene.world.grid,
            shapes,
            run.final,
            np.array([p[1:] for p in run.path]),
            truth=sim.truth[-1],
            title=f"{scenario}, seed {seed}, {share}",
            reference=sim.log.reference_poses,
        )
    return Trial(figures, time.perf_counter() - t0)


def _run_real(seed: int, share: Any, figure: Path | None) -> Trial:
    from tourbot.data import find_data
    from tourbot.io import load_log
    from tourbot.maps.objects import shapes_of_site
    from tourbot.objects.picture import draw_objects_figure
    from tourbot.objects.pipeline import estimate_log
    from tourbot.sim.object_overlay import overlay_objects
    from tourbot.sim.overlay import OverlayConfig, overlay_crowd
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site

    t0 = time.perf_counter()
    site = load_site(site_path("fhw-doors"))
    log = load_log(find_data("carmen/fhw-corrected.log.gz"))  # odometry rebuilt (the default)
    shapes = shapes_of_site(site.doors, site.furniture)
    poses: list[Any] = [[] for _ in site.doors] + [f.poses for f in site.furniture]
    with_objects, truth = overlay_objects(log, shapes, poses, seed=seed)
    crowded = overlay_crowd(with_objects, site.grid, OverlayConfig.preset("peak"), seed=seed).log
    run = estimate_log(crowded, shapes, site.grid, share=share, seed=seed)
    errs = _errors(run, shapes, truth.at)
    doors = [r for s in shapes if s.kind == "door" for r in errs[s.name]]
    obs = _observed(doors)
    figures = {
        "angle_err_deg": math.degrees(float(np.mean([r[4] for r in obs]))) if obs else math.nan,
        "observed_share": len(obs) / max(1, len(doors)),
        "door_updates": float(len(doors)),
        "ms_per_update": 1000 * float(np.median(run.update_seconds)) if run.update_seconds else math.nan,
        "ms_p95": 1000 * float(np.percentile(run.update_seconds, 95)) if run.update_seconds else math.nan,
    }
    benches = [r for s in shapes if s.kind != "door" for r in _observed(errs[s.name])]
    figures["bench_pos_err_cm"] = 100 * float(np.mean([r[3] for r in benches])) if benches else math.nan
    ref = crowded.reference_poses
    path = np.array([p[1:] for p in run.path])
    figures["pose_err_cm"] = 100 * float(np.mean(_pose_errors(run, crowded)))
    if figure is not None:
        draw_objects_figure(
            figure,
            site.grid,
            shapes,
            run.final,
            path,
            truth=truth.at(len(crowded.scans) - 1),
            title=f"FHW overlay + peak crowd, seed {seed}, {share}",
            reference=ref,
        )
    return Trial(figures, time.perf_counter() - t0)


def _pose_errors(run: Any, log: Any) -> FloatArray:
    """Position error (m) of the estimated path at each of its scans against the log's reference."""
    ref = log.reference_poses
    path = np.array([p[1:] for p in run.path])
    idx = np.clip(np.searchsorted(log.times, [p[0] for p in run.path]), 0, len(ref) - 1)
    return np.asarray(np.hypot(path[:, 0] - ref[idx, 0], path[:, 1] - ref[idx, 1]), dtype=np.float64)


def _run_changed(seed: int) -> Trial:
    """Novelty MCL on FHW with the peak crowd: the world unchanged, changed with the static map,
    changed with the objects' estimated states in the map."""
    from tourbot.data import find_data
    from tourbot.interfaces import ScanShare
    from tourbot.io import load_log
    from tourbot.localization.profile import FHW_PROFILE, LocalizationProfile
    from tourbot.maps.objects import shapes_of_site
    from tourbot.metrics import failure_rate
    from tourbot.objects.pipeline import estimate_log
    from tourbot.sim.object_overlay import overlay_objects
    from tourbot.sim.overlay import OverlayConfig, overlay_crowd
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site

    t0 = time.perf_counter()
    site = load_site(site_path("fhw-doors"))
    mcl = LocalizationProfile.load(FHW_PROFILE).mcl
    log = load_log(find_data("carmen/fhw-corrected.log.gz"))  # odometry rebuilt (the default)
    shapes = shapes_of_site(site.doors, site.furniture)
    poses: list[Any] = [[] for _ in site.doors] + [f.poses for f in site.furniture]
    changed, _ = overlay_objects(log, shapes, poses, seed=seed)
    peak = OverlayConfig.preset("peak")
    figures: dict[str, float] = {}
    for name, source, world in (
        ("unchanged", log, False),
        ("static", changed, False),
        ("estimated", changed, True),
    ):
        crowded = overlay_crowd(source, site.grid, peak, seed=seed).log
        run = estimate_log(
            crowded, shapes, site.grid, share=ScanShare.ALL, mcl_config=mcl, seed=seed, world=world
        )
        err = _pose_errors(run, crowded)
        figures[f"{name}_err_cm"] = 100 * float(np.mean(err))
        figures[f"{name}_fail_pct"] = 100 * failure_rate(err)
        if world:
            figures["redraws"] = float(run.redraws)
    return Trial(figures, time.perf_counter() - t0)


class _ObjectsWire:
    """A sink: the web's objects message (:class:`tourbot.web.stream.ObjectsPayload`) made from the
    snapshots at the stream's 5 Hz, its bytes and messages counted (what every viewer gets)."""

    def __init__(self, rate_hz: float = 5.0) -> None:
        from tourbot.web.stream import ObjectsPayload

        self.payload = ObjectsPayload()
        self.period = 1.0 / rate_hz
        self.next = 0.0
        self.bytes = 0
        self.messages = 0

    def on_snapshot(self, snapshot: Any) -> None:
        from tourbot.web.runtime_link import objects_of

        if snapshot.time < self.next:
            return
        self.next = snapshot.time + self.period
        message = self.payload.update(objects_of(snapshot))
        if message is not None:
            self.bytes += len(message)
            self.messages += 1

    def close(self) -> None:
        pass


def _run_tours(seed: int) -> Trial:
    """The ``crossings`` tour of :func:`door_tour_site`: doors open, closing with the static map,
    closing with the estimated states. Completed: every exhibit visited within ``TOUR_LIMIT``;
    the duration runs to the tour's end (exhibits skipped or not) or the limit; time lost is it
    less the duration with the doors open (same seed)."""
    from dataclasses import replace

    from tourbot.app.simulated import SimulationSettings, simulated_runtime
    from tourbot.localization.mcl import MCLConfig
    from tourbot.sim.object_scenes import door_tour_site
    from tourbot.snapshot import NavMode

    t0 = time.perf_counter()
    site = door_tour_site()
    figures: dict[str, float] = {}
    # MCL tracks from the known start with its recovery off (no scan-drawn guesses: they take
    # four fifths of the loop's CPU on this machine), the same in all three runs
    mcl = MCLConfig()
    mcl = replace(mcl, recovery=replace(mcl.recovery, max_injection=0.0))
    base = SimulationSettings(crowd="empty", seed=seed, mcl=mcl)
    done = (NavMode.FINISHED, NavMode.FAILED)
    for name, settings in (
        ("open", replace(base, sim=replace(base.sim, dynamic_objects=False))),
        ("static", base),
        ("estimated", replace(base, objects=True)),
    ):
        web = _ObjectsWire()  # what the web's objects message would cost, sent on change at 5 Hz
        robot = simulated_runtime(site, settings, record=False, sinks=(web,))
        robot.runtime.start_tour("crossings")
        robot.runtime.run(max_time=TOUR_LIMIT, until=lambda snap: snap.navigation.mode in done)
        m = robot.metrics.metrics
        completed = m.finished and len(m.visited) == m.exhibits_total
        figures[f"{name}_completed"] = 1.0 if completed else 0.0
        figures[f"{name}_duration_s"] = m.duration  # to the tour's end (exhibits skipped) or the limit
        figures[f"{name}_visited"] = float(len(m.visited))
        figures[f"{name}_finished"] = 1.0 if m.finished else 0.0  # ended, possibly with exhibits skipped
        figures[f"{name}_bumps"] = float(robot.simulator.collisions.static)
        figures[f"{name}_blocked_s"] = m.total_blocked_time
        figures[f"{name}_err_cm"] = 100 * float(np.mean(m.errors)) if m.errors else math.nan
        if name != "open":
            figures[f"{name}_lost_s"] = figures[f"{name}_duration_s"] - figures["open_duration_s"]
        if robot.objects is not None:
            figures["redraws"] = float(robot.objects.redraws)
            figures["web_objects_bps"] = 8 * web.bytes / max(m.duration, 1e-9)
            figures["web_objects_messages"] = float(web.messages)
    return Trial(figures, time.perf_counter() - t0)


def _run_viewpoint(seed: int) -> Trial:
    """Going to look (beyond the paper): the south door of :func:`door_tour_site`, unseen, 7 m away,
    at an opening drawn from the seed; :func:`tourbot.objects.viewpoint.inspect_object` sends the
    navigator to the chosen viewpoint; how well the door is estimated from the scans there (the last
    10 updates, 2 s after arriving)."""
    from dataclasses import replace

    from tourbot.app.simulated import SimulationSettings, simulated_runtime
    from tourbot.localization.mcl import MCLConfig
    from tourbot.objects.estimator import Observation
    from tourbot.objects.runtime import ObjectsEstimator
    from tourbot.objects.viewpoint import inspect_object
    from tourbot.sim.object_scenes import door_tour_site
    from tourbot.snapshot import NavMode

    t0 = time.perf_counter()
    site = door_tour_site()
    settings = SimulationSettings(crowd="empty", seed=seed, mcl=MCLConfig().with_samples(300), objects=True)
    settings = replace(settings, sim=replace(settings.sim, dynamic_objects=False))
    robot = simulated_runtime(site, settings, start=(3.0, 9.0, 0.0), record=False)
    opening = float(np.random.default_rng(seed).uniform(0.15, 0.85))
    robot.simulator.objects.set_states({0: opening})
    rt = robot.runtime
    rt.run(max_time=1.0)
    (objects,) = [e for e in rt.estimators if isinstance(e, ObjectsEstimator)]
    truth = float(robot.simulator.objects.states()[0][0])
    figures = {"opening_deg": abs(math.degrees(truth))}
    snap = rt.snapshot()
    view = (
        inspect_object(
            objects.estimator, robot.navigator, "south-door", snap.pose.pose, robot.simulator.laser.geometry
        )
        if snap.pose is not None
        else None
    )
    figures["discrimination"] = view.discrimination if view is not None else math.nan
    seen = len(objects.history)
    start = rt.snapshot().time
    final = rt.run(max_time=60.0, until=lambda s: s.navigation.mode == NavMode.FINISHED)
    arrived = view is not None and final.navigation.mode == NavMode.FINISHED
    figures["arrived"] = 1.0 if arrived else 0.0
    figures["travel_s"] = final.time - start if arrived else math.nan
    rt.run(max_time=2.0)  # looking from there
    there = [e for h in objects.history[seen:] for e in h if e.name == "south-door"][-10:]
    figures["observed_last10"] = sum(e.quality.status == Observation.OBSERVED for e in there) / max(
        1, len(there)
    )
    est = objects.estimator.beliefs[0].estimate
    figures["angle_err_deg"] = abs(math.degrees(est.state[0] - truth))
    return Trial(figures, time.perf_counter() - t0)


TARGETS = {
    "doors": "angle_err_deg <= 1, ms_per_update <= 5",
    "ushape": "pos_err_cm <= 3, angle_err_deg <= 2, ms_per_update <= 20, turn_found = 1",
    "desks": "pos_err_cm <= 3 (desks 1, 2, 4), desk3_wrong_found = 0, desk3_final_poor = 1",
    "real": "angle_err_deg <= 1, ms_per_update <= 5",
    "changed": "estimated_err_cm <= unchanged_err_cm, estimated_fail_pct <= unchanged_fail_pct",
    "tours": "estimated_completed >= static_completed, estimated_lost_s < static_lost_s",
    "viewpoint": "arrived = 1, observed_last10 >= 0.7, angle_err_deg <= 5 (the test's)",
}


def register(bench: typer.Typer) -> None:
    @bench.command("objects")
    def objects(
        seeds: Annotated[int, typer.Option(help="Seeds per scenario (>= 5 for the intervals).")] = 5,
        first_seed: Annotated[
            int, typer.Option(help="The first seed (a long run split over several invocations).")
        ] = 0,
        scenarios: Annotated[
            str, typer.Option(help="Comma-separated: doors, ushape, desks, real, changed, tours, viewpoint.")
        ] = ",".join(SCENARIOS),
        share: Annotated[str, typer.Option(help="Scan share: alternate (Table 1), all, or both.")] = "both",
        figures: Annotated[
            Path | None, typer.Option(help="Folder for one picture per scenario and share (seed 0).")
        ] = Path("docs/results/objects"),
        output: Annotated[
            Path | None, typer.Option("-o", "--output", help="JSON file (default bench-results/).")
        ] = None,
    ) -> None:
        """Doors, the U-shaped object and desks (Schulz & Burgard 2001, Sec. 4) and a real overlaid log."""
        from rich.console import Console

        from tourbot.bench.localization import mean_ci
        from tourbot.errors import TourbotError
        from tourbot.interfaces import ScanShare

        names = [s.strip() for s in scenarios.split(",") if s.strip()]
        bad = [n for n in names if n not in SCENARIOS]
        if bad:
            raise TourbotError(f"unknown --scenarios {', '.join(bad)}; choose from {', '.join(SCENARIOS)}")
        shares = {
            "both": [ScanShare.ALTERNATE, ScanShare.ALL],
            "alternate": [ScanShare.ALTERNATE],
            "all": [ScanShare.ALL],
        }.get(share)
        if shares is None:
            raise TourbotError(f"unknown --share {share!r}; choose alternate, all or both")
        if seeds < 1:
            raise TourbotError("--seeds must be at least 1")
        if first_seed < 0:
            raise TourbotError(f"--first-seed must be >= 0, not {first_seed}")
        console = Console()
        report = BenchReport("objects", ["scenario", "share", "figure", "mean", "ci95"])
        report.notes += [f"targets, {k}: {v}" for k, v in TARGETS.items() if k in names]
        report.meta["seeds"] = seeds
        report.meta["first_seed"] = first_seed
        report.meta["targets"] = TARGETS
        for name in names:
            for sh in [ScanShare.ALL] if name in SINGLE_SHARE else shares:
                trials = []
                for seed in range(first_seed, first_seed + seeds):
                    fig = figures / f"{name}-{sh}.png" if figures is not None and seed == 0 else None
                    trial = _run(name, seed, sh, fig)
                    trials.append(trial)
                    shown = ", ".join(f"{k} {v:.2f}" for k, v in trial.figures.items())
                    console.print(
                        f"{name} {sh} seed {seed}: {shown} ({trial.seconds:.0f} s)", highlight=False
                    )
                for key in trials[0].figures:
                    m, h = mean_ci([t.figures[key] for t in trials])
                    report.add(scenario=name, share=str(sh), figure=key, mean=m, ci95=h)
                report.meta.setdefault("per_seed", {})[f"{name}/{sh}"] = [t.figures for t in trials]
        report.finish(output, console)
