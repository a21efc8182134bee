"""``tourbot demo``: a guided tour through the crowded FHW museum, simulated, with MCL in the loop."""

from __future__ import annotations

from pathlib import Path

import typer

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    @app.command("demo")
    def demo(
        tour: str = typer.Option("highlights", help="Tour of the site to guide."),
        crowd: str = typer.Option("peak", help="Crowd: empty, sparse, peak, or a number of visitors."),
        seed: int = typer.Option(0, help="Seed: the same seed gives the same run."),
        duration: float = typer.Option(900.0, help="Stop after this many simulated seconds."),
        speedup: float = typer.Option(
            0.0, help="Pace to this many times real time (0: as fast as possible)."
        ),
        particles: int = typer.Option(1000, help="MCL samples."),
        dwell_scale: float = typer.Option(0.5, help="Scale the exhibits' presentation times."),
        site: str = typer.Option("fhw", help="Shipped site name or site file."),
        out: str = typer.Option("out/demo", help="Folder for the recording, summary and animation."),
        animation: bool = typer.Option(True, help="Write the tour's animation (GIF)."),
    ) -> None:
        """Run a guided tour in the simulated crowded museum; live progress, then a recording and a GIF."""
        from tourbot.cli._tour_view import run_tour
        from tourbot.errors import InputError

        if not duration > 0:
            raise InputError(f"must be positive (simulated seconds), got {duration}", field="--duration")
        if particles < 1:
            raise InputError(f"must be at least 1, got {particles}", field="--particles")
        if speedup < 0:
            raise InputError(f"must be 0 (as fast as possible) or positive, got {speedup}", field="--speedup")
        if dwell_scale < 0:
            raise InputError(f"must not be negative, got {dwell_scale}", field="--dwell-scale")
        run_tour(
            site=site,
            tour=tour,
            crowd=crowd,
            seed=seed,
            duration=duration,
            speedup=speedup,
            particles=particles,
            dwell_scale=dwell_scale,
            out=Path(out),
            animation=animation,
        )
