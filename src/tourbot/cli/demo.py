"""``tourbot demo``: the simulated crowded FHW museum served on the web, or one headless guided tour.

By default (what ``make demo`` runs) the demo is the whole tele-presence experience of Burgard et
al. (section 6) on the embedded default: the simulated museum with its crowd, MCL and the
navigator in the loop, and the web server with the visitor page, the on-board screen and the
staff pages at local addresses it prints. ``--record`` runs one guided tour headless instead and
writes a recording, a summary and a GIF.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from tourbot.cli._checks import McapOpt
from tourbot.cli.web import AskStaffPasswordOpt, FoxgloveOpt, StaffPasswordFileOpt, read_staff_password

if TYPE_CHECKING:
    from tourbot.localization.mcl.config import MCLConfig

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    @app.command("demo")
    def demo(
        record: bool = typer.Option(
            False,
            "--record",
            "--headless",
            help="Run one guided tour headless and write a recording, summary and GIF (no web server).",
        ),
        tour: str = typer.Option("highlights", help="Tour of the site to guide (--record)."),
        crowd: str = typer.Option("peak", help="Crowd: empty, sparse, peak, or a number of visitors."),
        seed: int = typer.Option(0, help="Seed: the same seed gives the same run."),
        duration: float = typer.Option(900.0, help="Stop after this many simulated seconds (--record)."),
        speedup: float = typer.Option(
            0.0,
            help="Pace to this many times real time (0: as fast as possible with --record, "
            "real time when serving).",
        ),
        particles: int | None = typer.Option(
            None, help="MCL samples (default: the configuration's sampling.max_samples)."
        ),
        config: Annotated[
            Path | None,
            typer.Option(
                "--config",
                help="Localization profile of the robot (YAML; tourbot config show; default: the site's "
                "localization.yaml when it ships one, else the papers' values).",
            ),
        ] = None,
        dwell_scale: float = typer.Option(0.5, help="Scale the exhibits' presentation times (--record)."),
        site: str = typer.Option("fhw", help="Shipped site name or site file."),
        out: str = typer.Option(
            "out/demo", help="Folder for the recording, summary and animation; when serving, the database."
        ),
        animation: bool = typer.Option(True, help="Write the tour's animation (GIF, --record)."),
        mcap: McapOpt = None,
        force: Annotated[bool, typer.Option("--force", help="Replace an existing --mcap file.")] = False,
        foxglove: FoxgloveOpt = None,
        host: str = typer.Option("127.0.0.1", help="Address the web server listens on."),
        port: int = typer.Option(8000, help="TCP port (a free one is chosen when it is taken)."),
        database: str | None = typer.Option(
            None, help="SQLAlchemy URL of the site database (default OUT/tourbot-SITE.db, never wiped)."
        ),
        staff_password_file: StaffPasswordFileOpt = None,
        ask_staff_password: AskStaffPasswordOpt = False,
    ) -> None:
        """The simulated crowded museum with its web pages (visitors, on-board screen, staff) until Ctrl-C.

        Without a staff password (a file, the environment or the prompt) a new one is printed at start.
        """
        from tourbot.errors import InputError

        if not duration > 0:
            raise InputError(f"must be positive (simulated seconds), got {duration}", field="--duration")
        if particles is not None and particles < 1:
            raise InputError(f"must be at least 1, got {particles}", field="--particles")
        if speedup < 0:
            raise InputError(f"must be 0 (as fast as possible) or positive, got {speedup}", field="--speedup")
        if dwell_scale < 0:
            raise InputError(f"must not be negative, got {dwell_scale}", field="--dwell-scale")
        if not 0 <= port <= 65535:
            raise InputError(f"must be a TCP port (0-65535), got {port}", field="--port")
        if foxglove is not None and not 0 < foxglove <= 65535:
            raise InputError(f"must be a TCP port (1-65535), got {foxglove}", field="--foxglove")
        from tourbot.localization.profile import LocalizationProfile
        from tourbot.site.default import site_path

        staff_password = None if record else read_staff_password(staff_password_file, ask_staff_password)
        if staff_password is not None:
            from tourbot.web.db import check_staff_password

            check_staff_password(staff_password)
        profile, profile_file = LocalizationProfile.for_site(site_path(site), config)
        mcl = profile.mcl
        applied = str(profile_file) if profile_file else "the papers' defaults"
        typer.echo(f"localization profile: {applied}", err=True)
        if particles is not None:
            mcl = mcl.with_samples(particles)
        if mcap is not None:
            if not record:
                raise InputError("is written by a recorded tour only: add --record", field="--mcap")
            from tourbot.io.mcap_out import check_mcap_output

            check_mcap_output(mcap, force=force)
        if record:
            from tourbot.app.demo import run_tour

            run_tour(
                site=site,
                tour=tour,
                crowd=crowd,
                seed=seed,
                duration=duration,
                speedup=speedup,
                mcl=mcl,
                dwell_scale=dwell_scale,
                out=Path(out),
                animation=animation,
                mcap=mcap,
                foxglove=foxglove,
            )
            return
        _serve(
            site,
            crowd,
            seed,
            speedup or 1.0,
            mcl,
            Path(out),
            host,
            port,
            database,
            staff_password,
            foxglove,
        )


def _serve(
    site: str,
    crowd: str,
    seed: int,
    speedup: float,
    mcl: MCLConfig,
    out: Path,
    host: str,
    port: int,
    database: str | None,
    staff_password: str | None,
    foxglove: int | None,
) -> None:
    """Build the simulated museum and its web server, then serve until Ctrl-C."""
    import time

    from rich.console import Console

    from tourbot.app.simulated import crowd_config
    from tourbot.web.serve import ServeSettings, build_site_app, run

    console = Console()
    crowd_config(crowd)  # a clear error before anything starts
    name = Path(site).stem if site.endswith((".yaml", ".yml")) else Path(site).name
    out.mkdir(parents=True, exist_ok=True)
    settings = ServeSettings(
        site=site, database=database or f"sqlite:///{out / f'tourbot-{name}.db'}", crowd=crowd, seed=seed,
        mcl=mcl, host=host, port=port, staff_password=staff_password,
        speech_dir=out / "speech", speedup=speedup, fresh_staff_password=True, foxglove=foxglove,
    )  # fmt: skip
    t0 = time.perf_counter()
    with console.status("building the simulated museum (the first run compiles the kernels)..."):
        app, db = build_site_app(settings, console=console)
    console.print(
        f"set up in {time.perf_counter() - t0:.1f} s: site {name}, crowd {crowd}, seed {seed}, "
        f"{speedup:g}x real time; database {db.url}",
        soft_wrap=True,
    )
    run(app, host, port, console, fallback=True)
