"""Serving a site: the simulated (or real) robots, the database, the app, uvicorn.

``tourbot serve`` and ``tourbot demo --serve`` both call :func:`build_site_app` then
:func:`run`.
"""

from __future__ import annotations

import secrets
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from fastapi import FastAPI
from rich.console import Console

from tourbot.errors import TourbotError
from tourbot.web.app import WebConfig, create_app
from tourbot.web.db import Database, default_url, open_database
from tourbot.web.guard import GuardConfig
from tourbot.web.link import RobotLink
from tourbot.web.sitedata import import_site

if TYPE_CHECKING:
    from tourbot.site.model import Site

__all__ = ["ServeSettings", "build_site_app", "run"]


@dataclass(frozen=True)
class ServeSettings:
    """What ``tourbot serve`` is told: site, database, robots, simulation, network."""

    site: str = "fhw"
    database: str | None = None
    robots: int = 1
    crowd: str = "sparse"
    seed: int = 0
    particles: int = 300
    host: str = "127.0.0.1"
    port: int = 8000
    slot_minutes: float = 10.0
    staff_password: str | None = None
    speech_dir: Path = Path(".tourbot-speech")


def _robot_names(n: int) -> list[str]:
    # The TOURBOT and WebFAIR robots' names (Lefkos at FHW, Albert at Hannover, Rhino in Bonn).
    names = ["lefkos", "albert", "rhino", "minerva"]
    return [names[i] if i < len(names) else f"robot{i + 1}" for i in range(n)]


def simulated_links(site: Site, settings: ServeSettings) -> dict[str, RobotLink]:
    """One simulated runtime per robot (different seeds), each behind a :class:`RuntimeLink`."""
    try:
        from tourbot.runtime.simulated import SimulationSettings, simulated_runtime
    except ImportError as exc:  # the simulator runtime is part of another work package
        raise TourbotError(f"the simulator runtime is not available: {exc}") from None
    from tourbot.web.runtime_link import RuntimeLink

    links: dict[str, RobotLink] = {}
    tours = frozenset(t.name for t in site.tours)
    for i, name in enumerate(_robot_names(settings.robots)):
        sim_settings = SimulationSettings(
            crowd=settings.crowd, seed=settings.seed + i, particles=settings.particles
        )
        robot = simulated_runtime(site, sim_settings, record=False)
        links[name] = RuntimeLink(robot.runtime, period=float(robot.simulator.dt), site_tours=tours)
    return links


def build_site_app(
    settings: ServeSettings,
    links: dict[str, RobotLink] | None = None,
    console: Console | None = None,
) -> tuple[FastAPI, Database]:
    """The server of ``settings.site``; its exhibits and tours are imported on first start."""
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site

    console = console or Console()
    site = load_site(site_path(settings.site))
    db = open_database(settings.database or default_url(site.name), site=site.name)
    if not db.exhibits():
        exhibits, tours = import_site(site, db)
        console.print(f"imported {exhibits} exhibits and {tours} tours from the site file into {db.url}")
    if settings.staff_password:
        db.set_staff("staff", settings.staff_password)
    elif not db.has_staff():
        password = secrets.token_urlsafe(9)
        db.set_staff("staff", password)
        console.print(f"staff login created: user [bold]staff[/], password [bold]{password}[/]")
    if links is None:
        links = simulated_links(site, settings)
    base = WebConfig()
    config = WebConfig(
        site_name=site.description.split(":")[0] if site.description else site.name,
        slots=replace(base.slots, slot_length=settings.slot_minutes * 60.0),
        speech_dir=settings.speech_dir,
        guard=GuardConfig(),
    )
    return create_app(links, db, site.grid, config), db


def run(app: FastAPI, host: str, port: int, console: Console | None = None) -> None:
    """Serve until interrupted; prints the addresses first."""
    import uvicorn

    console = console or Console()
    base = f"http://{host}:{port}"
    console.print(f"visitor page: [bold]{base}/[/]   on-board screen: {base}/onboard   staff: {base}/admin")
    # Frames larger than 64 kB are refused by the protocol layer before any parsing.
    uvicorn.run(
        app, host=host, port=port, log_level="warning", ws_max_size=65536, ws_per_message_deflate=True
    )
