"""``tourbot bench crowd``: the simulated visitors against real pedestrians, and the crowd at the robot.

Recordings: the ETH and UCY pedestrian trajectories of ``../shared/data/pedestrians`` (2.5 Hz,
metres). Simulation: the one crowd model (:mod:`tourbot.sim.crowd`) on the FHW site with its
exhibits as points of interest and the robot standing at the first exhibit, in the ``sparse`` and
``peak`` presets, sampled at the recordings' rate after a warm-up. Both are measured by
:mod:`tourbot.sim.crowd_stats`: walking speeds (steps faster than 0.2 m/s), distances to the
nearest neighbour, group sizes, the share of time standing and the length of standing bouts; the
Wasserstein-1 distance and Kolmogorov-Smirnov statistic of the speed and nearest-neighbour
distributions against each recording.

The crowd at the robot: the headless demo tour (``tourbot demo --record``, peak crowd) over the
seeds: visitors within 3 m of the robot (median and maximum over the tour), the share of all
visitors' nearest-neighbour distances between 0.55 and 0.70 m (the lattice the crowd used to
form), the time the robot was blocked; and the share of beams the ``peak`` crowd corrupts on the
FHW log (the overlay of ``tourbot crowd``), whose target is >= 40 % (Fox et al. 1998, peak hours).
Seeds give 95 % intervals (Student t).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
import typer
from numpy.typing import NDArray

from tourbot.bench._report import BenchReport

if TYPE_CHECKING:
    from tourbot.io.pedestrians import Trajectories

__all__ = ["RECORDINGS", "crowd_statistics", "demo_crowd", "register"]

RECORDINGS = ("biwi_eth", "biwi_hotel", "crowds_zara01", "crowds_zara02", "students001")
TARGET_CORRUPTED = 0.40
LATTICE = (0.55, 0.70)


def crowd_statistics(tr: Trajectories) -> dict[str, Any]:
    """The figures of one set of trajectories, with the samples kept for distances and plots."""
    from tourbot.sim import crowd_stats as cs

    v = cs.speeds(tr)
    walk = v[v >= cs.STANDING_SPEED]
    nn = cs.nearest_neighbour_distances(tr)
    groups = cs.group_sizes(tr)
    bouts = cs.standing_bouts(tr)
    people_in = np.bincount(np.minimum(groups, 3), weights=groups, minlength=4)[1:] / max(groups.sum(), 1)

    def q(a: NDArray[np.float64], p: float) -> float:
        return float(np.quantile(a, p)) if len(a) else math.nan

    return {
        "people": tr.people,
        "duration_s": tr.duration,
        "speed_median": q(walk, 0.5),
        "speed_iqr": q(walk, 0.75) - q(walk, 0.25),
        "nn_q10": q(nn, 0.1),
        "nn_median": q(nn, 0.5),
        "nn_q90": q(nn, 0.9),
        "nn_lattice": float(np.mean((nn >= LATTICE[0]) & (nn <= LATTICE[1]))) if len(nn) else math.nan,
        # share of people walking alone, in pairs, in groups of 3 or more
        "alone": float(people_in[0]),
        "pairs": float(people_in[1]),
        "groups3": float(people_in[2]),
        "group_sizes": np.bincount(groups).tolist(),
        "standing": cs.standing_share(tr),
        "bout_median_s": q(bouts, 0.5),
        "bout_q90_s": q(bouts, 0.9),
        "_walk": walk,
        "_nn": nn,
    }


def _simulated(preset: str, seed: int, duration: float, warmup: float) -> Trajectories:
    """The crowd of ``preset`` on the FHW site, robot standing at the first exhibit."""
    from tourbot.sim import crowd_stats as cs
    from tourbot.sim.crowd import Crowd, CrowdConfig
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site

    site = load_site(site_path("fhw"))
    cfg = replace(CrowdConfig.preset(preset), points_of_interest=tuple(e.position for e in site.exhibits))
    rng = np.random.default_rng(seed)
    pose = site.exhibits[0].viewing_pose
    crowd = Crowd(cfg, site.grid, rng, pose)
    for _ in range(round(warmup)):
        crowd.step(1.0, pose, rng)
    return cs.sample_crowd(crowd, duration, rng, pose)


def demo_crowd(seed: int, duration: float) -> dict[str, float]:
    """The headless demo tour (FHW, highlights, peak crowd): visitors within 3 m of the robot
    (median, max over snapshots every 0.5 s), the share of every visitor's nearest-neighbour
    distance in the lattice band, the time blocked, the exhibits visited."""
    from scipy.spatial import cKDTree

    from tourbot.app.demo import start_pose_for
    from tourbot.app.simulated import SimulationSettings, simulated_runtime
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site

    site = load_site(site_path("fhw"))
    settings = SimulationSettings(crowd="peak", seed=seed)
    settings = replace(settings, navigation=replace(settings.navigation, dwell_scale=0.5))
    robot = simulated_runtime(site, settings, start=start_pose_for(site, "highlights"), record=False)
    rt = robot.runtime
    rt.start_tour("highlights")
    crowd = robot.simulator.crowd
    assert crowd is not None
    within: list[int] = []
    nn: list[NDArray[np.float64]] = []
    next_sample = 0.0
    while rt.source.time < duration:
        if rt.step() is None:
            break
        if rt.source.time + 1e-9 >= next_sample:
            next_sample += 0.5
            pos = crowd.positions
            x, y, _ = robot.simulator.robot.pose
            within.append(int((np.hypot(pos[:, 0] - x, pos[:, 1] - y) < 3.0).sum()))
            nn.append(cKDTree(pos).query(pos, k=2)[0][:, 1])
    d = np.concatenate(nn)
    return {
        "within_3m_median": float(np.median(within)),
        "within_3m_max": float(np.max(within)),
        "nn_lattice": float(np.mean((d >= LATTICE[0]) & (d <= LATTICE[1]))),
        "nn_median": float(np.median(d)),
        "blocked_s": float(robot.navigator.total_blocked_time),
        "visited": float(len(robot.metrics.metrics.visited)),
        "duration_s": float(rt.source.time),
    }


def corrupted_share(seed: int) -> dict[str, float]:
    """The ``peak`` overlay on the FHW log over its reference map: corrupted beams per scan."""
    from tourbot.data import find_data
    from tourbot.io import read_carmen
    from tourbot.maps.reference import build_reference_map
    from tourbot.sim.overlay import OverlayConfig, overlay_crowd

    log = read_carmen(find_data("carmen/fhw-corrected.log.gz"))
    result = overlay_crowd(
        log, build_reference_map(log), OverlayConfig.preset("peak"), seed=seed, preset="peak"
    )
    f = result.truth.fraction
    return {
        "corrupted_mean": float(f.mean()),
        "above_50": float(np.mean(f > 0.5)),
        "longest_above_50_s": result.truth.longest_above(0.5),
        "people": float(result.truth.people),
    }


_STAT_COLUMNS = {
    "speed med": "speed_median",
    "speed IQR": "speed_iqr",
    "NN q10": "nn_q10",
    "NN med": "nn_median",
    "NN q90": "nn_q90",
    "NN .55-.70": "nn_lattice",
    "alone": "alone",
    "pairs": "pairs",
    "groups 3+": "groups3",
    "standing": "standing",
    "bout med s": "bout_median_s",
}


def _ci(values: list[float]) -> str:
    from tourbot.metrics import mean_ci

    m, h = mean_ci(values)
    return "-" if math.isnan(m) else f"{m:.2f} ± {h:.2f}"


def register(bench: typer.Typer) -> None:
    @bench.command("crowd")
    def crowd(
        seeds: Annotated[str, typer.Option(help="Seeds of the simulated crowds: '0-4', '0,3,5'.")] = "0-4",
        duration: Annotated[float, typer.Option(help="Simulated seconds sampled per crowd.")] = 300.0,
        warmup: Annotated[float, typer.Option(help="Seconds the crowd walks before sampling.")] = 60.0,
        demo_duration: Annotated[
            float, typer.Option(help="Seconds of the demo tour per seed (0: skip the demo).")
        ] = 180.0,
        overlay: Annotated[
            bool, typer.Option(help="Measure the peak overlay's corrupted beams on FHW.")
        ] = True,
        figure: Annotated[Path | None, typer.Option(help="Histograms, sim against recordings (PNG).")] = Path(
            "docs/results/crowd.png"
        ),
        output: Annotated[Path | None, typer.Option("-o", "--output", help="JSON file.")] = None,
    ) -> None:
        """Simulated visitors against the ETH/UCY pedestrians; the crowd at the robot in the demo."""
        from rich.progress import Progress

        from tourbot.bench.tracking import parse_seeds
        from tourbot.data import find_data
        from tourbot.errors import InputError
        from tourbot.io.pedestrians import read_pedestrians
        from tourbot.sim.crowd_stats import compare

        try:
            seed_list = parse_seeds(seeds)
        except ValueError:
            raise InputError(
                f"expected seeds like '0-4' or '0,3,5', got {seeds!r}", field="--seeds"
            ) from None
        if not duration > 0:
            raise InputError(f"must be positive, got {duration}", field="--duration")
        report = BenchReport("crowd", ["source", "seeds", *_STAT_COLUMNS, "W1 speed", "W1 NN"])
        report.meta.update({"seeds": seed_list, "duration": duration, "warmup": warmup})
        recorded = {
            name: crowd_statistics(read_pedestrians(find_data(f"pedestrians/{name}.txt")))
            for name in RECORDINGS
        }
        for name, st in recorded.items():
            report.add(source=name, seeds="-", **{c: st[k] for c, k in _STAT_COLUMNS.items()})
        sims: dict[str, list[dict[str, Any]]] = {}
        with Progress(transient=True) as progress:
            task = progress.add_task("crowds", total=2 * len(seed_list))
            for preset in ("sparse", "peak"):
                for seed in seed_list:
                    sims.setdefault(preset, []).append(
                        crowd_statistics(_simulated(preset, seed, duration, warmup))
                    )
                    progress.advance(task)
        per_recording: dict[str, dict[str, dict[str, list[float]]]] = {}
        for preset, runs in sims.items():
            row: dict[str, Any] = {"source": f"sim {preset}", "seeds": str(len(runs))}
            for c, k in _STAT_COLUMNS.items():
                row[c] = _ci([r[k] for r in runs])
            pooled_walk = np.concatenate([st["_walk"] for st in recorded.values()])
            pooled_nn = np.concatenate([st["_nn"] for st in recorded.values()])
            d = [(compare(r["_walk"], pooled_walk), compare(r["_nn"], pooled_nn)) for r in runs]
            row["W1 speed"] = _ci([x[0][0] for x in d])
            row["W1 NN"] = _ci([x[1][0] for x in d])
            row["pooled"] = {"ks_speed": [x[0][1] for x in d], "ks_nn": [x[1][1] for x in d]}
            report.add(**row)
            per_recording[preset] = {}
            for name, st in recorded.items():
                dd = [(compare(r["_walk"], st["_walk"]), compare(r["_nn"], st["_nn"])) for r in runs]
                per_recording[preset][name] = {
                    "w1_speed": [x[0][0] for x in dd],
                    "ks_speed": [x[0][1] for x in dd],
                    "w1_nn": [x[1][0] for x in dd],
                    "ks_nn": [x[1][1] for x in dd],
                }
            report.notes.append(
                f"sim {preset} against each recording, W1 speed / KS speed / W1 NN / KS NN (mean ± 95 %): "
                + "; ".join(
                    f"{name} {_ci(x['w1_speed'])} / {_ci(x['ks_speed'])} / "
                    f"{_ci(x['w1_nn'])} / {_ci(x['ks_nn'])}"
                    for name, x in per_recording[preset].items()
                )
            )
        report.meta["recordings"] = {n: _public(st) for n, st in recorded.items()}
        report.meta["simulated"] = {p: [_public(r) for r in runs] for p, runs in sims.items()}
        report.meta["distances_by_recording"] = per_recording
        report.notes.append(
            "speeds: steps between 0.4 s frames faster than 0.2 m/s; NN: distance to the nearest other "
            "person in the same frame; groups: pairs within 1.5 m walking within 30 deg of each other for "
            ">= 4 s (75 % of the time near), joined; sim rows: mean ± 95 % interval over the seeds; W1/KS of "
            "the sim rows are against the five recordings pooled, per recording below"
        )
        if demo_duration > 0:
            _demo_rows(report, seed_list, demo_duration)
        if overlay:
            _overlay_rows(report, seed_list)
        if figure is not None:
            _figure(figure, recorded, sims)
            report.notes.append(f"figure: {figure}")
        report.finish(output)


def _public(st: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in st.items() if not k.startswith("_")}


def _demo_rows(report: BenchReport, seeds: list[int], duration: float) -> None:
    runs = [demo_crowd(s, duration) for s in seeds]
    report.meta["demo"] = runs
    line = (
        f"demo tour (peak, {duration:.0f} s, {len(runs)} seeds): visitors within 3 m median "
        f"{_ci([r['within_3m_median'] for r in runs])} "
        f"(max over the tours {max(r['within_3m_max'] for r in runs):.0f}); "
        f"NN in 0.55-0.70 m {_ci([100 * r['nn_lattice'] for r in runs])} %; NN median "
        f"{_ci([r['nn_median'] for r in runs])} m; blocked {_ci([r['blocked_s'] for r in runs])} s; "
        f"exhibits visited {_ci([r['visited'] for r in runs])}"
    )
    report.notes.append(line)


def _overlay_rows(report: BenchReport, seeds: list[int]) -> None:
    from tourbot.metrics import mean_ci

    runs = [corrupted_share(s) for s in seeds]
    report.meta["corrupted"] = runs
    m, h = mean_ci([r["corrupted_mean"] for r in runs])
    verdict = "met" if m >= TARGET_CORRUPTED else "MISSED"
    report.notes.append(
        f"peak overlay on FHW ({len(runs)} seeds, {runs[0]['people']:.0f} visitors): corrupted beams "
        f"{100 * m:.1f} ± {100 * h:.1f} %, scans above 50 % {_ci([100 * r['above_50'] for r in runs])} %, "
        f"longest stretch above 50 % {_ci([r['longest_above_50_s'] for r in runs])} s; "
        f"target >= {100 * TARGET_CORRUPTED:.0f} %: {verdict}"
    )


def _figure(path: Path, recorded: dict[str, dict[str, Any]], sims: dict[str, list[dict[str, Any]]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tourbot.plotting import PATH_COLORS, save_figure

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    speed_bins = np.linspace(0.2, 3.0, 43)
    nn_bins = np.linspace(0.0, 4.0, 41)
    for k, (name, st) in enumerate(recorded.items()):
        style = {
            "histtype": "step",
            "density": True,
            "color": PATH_COLORS[(k + 2) % len(PATH_COLORS)],
            "lw": 1.0,
        }
        axes[0].hist(st["_walk"], bins=speed_bins, label=name, **style)
        axes[1].hist(st["_nn"], bins=nn_bins, label=name, **style)
    for preset, color in (("sparse", PATH_COLORS[0]), ("peak", PATH_COLORS[1])):
        runs = sims[preset]
        walk = np.concatenate([r["_walk"] for r in runs])
        nn = np.concatenate([r["_nn"] for r in runs])
        style = {"histtype": "stepfilled", "density": True, "color": color, "alpha": 0.35}
        axes[0].hist(walk, bins=speed_bins, label=f"sim {preset}", **style)
        axes[1].hist(nn, bins=nn_bins, label=f"sim {preset}", **style)
    axes[1].axvspan(*LATTICE, color="grey", alpha=0.15, lw=0)
    axes[0].set(xlabel="walking speed (m/s)", ylabel="density", title="speed (steps > 0.2 m/s)")
    axes[1].set(xlabel="distance to the nearest neighbour (m)", title="nearest neighbour (grey: 0.55-0.70 m)")
    names = [*recorded, "sim sparse", "sim peak"]
    shares = [[st["alone"], st["pairs"], st["groups3"]] for st in recorded.values()]
    shares += [
        [float(np.mean([r[k] for r in sims[p]])) for k in ("alone", "pairs", "groups3")]
        for p in ("sparse", "peak")
    ]
    s = np.array(shares)
    y = np.arange(len(names))
    for j, (label, color) in enumerate(zip(("alone", "pairs", "3+"), PATH_COLORS[2:5], strict=True)):
        axes[2].barh(y, s[:, j], left=s[:, :j].sum(axis=1), color=color, label=label)
    axes[2].set_yticks(y, names)
    axes[2].set(xlabel="share of people", title="walking alone / in pairs / in groups of 3+")
    axes[0].legend(fontsize=7)
    axes[2].legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)
