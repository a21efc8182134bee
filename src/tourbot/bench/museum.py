"""``tourbot bench museum``: several robots touring one museum, and how the one crowd treats each.

As ``tourbot serve --robots N`` runs them (WebFAIR's several robots in one museum): each robot's
simulator on the fleet's shared memory (:mod:`tourbot.sim.fleet`), the museum's world stepping the
one crowd with every robot's pose (:class:`tourbot.sim.world.MuseumWorld`), here all stepped in
turn in one process (the world, then each robot) so that a seed gives one run. Robot *k* starts
at exhibit *k* and runs a tour of its own (the site's tours in turn). Per robot and seed: the
closest any visitor came to it (centre to centre), the collisions its simulator counted (with a
visitor, with another robot), how many visitors stood within 3 m of it on average, and how many
the crowd had drawn to it (standing in its ring or following it) on average.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

__all__ = ["register"]


def museum_run(
    robots: int, crowd: str, seed: int, seconds: float, samples: int = 300
) -> list[dict[str, float | int | str]]:
    """One run of ``robots`` robots touring FHW in ``crowd`` for ``seconds``: a row per robot."""
    from tourbot.app.simulated import SimulationSettings, crowd_config, simulated_runtime
    from tourbot.localization.mcl import MCLConfig
    from tourbot.sim.fleet import FleetPoses
    from tourbot.sim.world import MuseumWorld
    from tourbot.site.default import default_site

    site = default_site()
    config = crowd_config(crowd)
    if config is None:
        raise typer.BadParameter(f"the crowd {crowd!r} is empty: nobody to measure")
    fleet = FleetPoses(robots)
    try:
        runs = []
        for i in range(robots):
            s = SimulationSettings(crowd=crowd, seed=seed + i, mcl=MCLConfig().with_samples(samples))
            start = site.exhibits[i % len(site.exhibits)].viewing_pose
            runs.append(simulated_runtime(site, s, start=start, record=False, fleet=(fleet, i)))
        world = MuseumWorld(site, config, fleet, seed=seed, wait=1.0)
        tours = [site.tours[i % len(site.tours)].name for i in range(robots)]
        for run, tour in zip(runs, tours, strict=True):
            run.runtime.start_tour(tour)
        closest = np.full(robots, math.inf)
        near, drawn = np.zeros(robots), np.zeros(robots)
        steps = 0
        while world.time < seconds - 1e-9:
            world.step()
            for run in runs:
                run.runtime.step()
            people = world.crowd.positions
            at = world.crowd.robot_of
            for k, run in enumerate(runs):
                x, y, _ = run.simulator.robot.pose
                d = np.hypot(people[:, 0] - x, people[:, 1] - y)
                closest[k] = min(closest[k], float(d.min()))
                near[k] += int((d < 3.0).sum())
                drawn[k] += int((at == k).sum())
            steps += 1
        rows: list[dict[str, float | int | str]] = []
        for k, run in enumerate(runs):
            c = run.simulator.collisions
            rows.append(
                {
                    "robot": k + 1,
                    "seed": seed,
                    "tour": tours[k],
                    "visitors": world.crowd.num_people,
                    "closest_m": float(closest[k]),
                    "person_collisions": c.person,
                    "robot_collisions": c.robot,
                    "within_3m": float(near[k] / max(steps, 1)),
                    "drawn": float(drawn[k] / max(steps, 1)),
                }
            )
        for run in runs:
            run.runtime.close()
        return rows
    finally:
        fleet.close()


def register(bench: typer.Typer) -> None:
    @bench.command("museum")
    def museum_cmd(
        robots: Annotated[int, typer.Option(min=1, help="Robots in the museum.")] = 2,
        crowd: Annotated[str, typer.Option(help="Crowd preset or number of visitors.")] = "peak",
        seeds: Annotated[int, typer.Option(min=1, help="Seeds (runs).")] = 3,
        seconds: Annotated[float, typer.Option(min=1.0, help="Simulated seconds per run.")] = 120.0,
        output: Annotated[Path | None, typer.Option("-o", "--output", help="JSON file.")] = None,
    ) -> None:
        """Several robots touring one museum: closest visitor, collisions and visitors drawn, per robot."""
        from rich.progress import Progress

        from tourbot.bench._report import BenchReport

        report = BenchReport(
            "museum",
            [
                "robot",
                "seed",
                "tour",
                "closest_m",
                "person_collisions",
                "robot_collisions",
                "within_3m",
                "drawn",
            ],
            meta={"robots": robots, "crowd": crowd, "seeds": seeds, "seconds": seconds, "site": "fhw"},
        )
        with Progress() as progress:
            task = progress.add_task("runs", total=seeds)
            for seed in range(seeds):
                for row in museum_run(robots, crowd, seed, seconds):
                    report.add(**row)
                progress.advance(task)
        for k in range(1, robots + 1):
            mine = [r for r in report.rows if r["robot"] == k]
            report.notes.append(
                f"robot {k}: closest visitor {min(float(r['closest_m']) for r in mine):.2f} m, "
                f"{sum(int(r['person_collisions']) for r in mine)} collisions with visitors, "
                f"{np.mean([float(r['drawn']) for r in mine]):.1f} visitors drawn to it on average"
            )
        report.finish(output)
