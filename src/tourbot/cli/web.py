"""``tourbot serve`` (the tele-presence server) and ``tourbot site ...`` (authoring the content)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:
    from tourbot.web.db import Database

__all__ = ["register"]

DatabaseOpt = Annotated[
    str | None, typer.Option("--database", help="SQLAlchemy URL; default $DATABASE_URL or ./tourbot-SITE.db")
]
SiteOpt = Annotated[str, typer.Option("--site", help="a shipped site name (fhw) or a site file or folder")]
FoxgloveOpt = Annotated[
    int | None,
    typer.Option(
        "--foxglove",
        metavar="PORT",
        help="Also serve the robot's channels live to Foxglove (ws://HOST:PORT; robot k on PORT + k).",
    ),
]
# the staff password, never in argv (every user of the machine can read a command line): also
# taken by `demo`, with read_staff_password
StaffPasswordFileOpt = Annotated[
    Path | None,
    typer.Option(
        help="a file whose first line is the password of user 'staff' (or set $TOURBOT_STAFF_PASSWORD)"
    ),
]
AskStaffPasswordOpt = Annotated[
    bool, typer.Option("--ask-staff-password", help="ask for the password of user 'staff' (hidden)")
]


def _db(database: str | None, site: str) -> Database:
    """The site database; a SQLite file that did not exist is created, and the user told so (a
    mistyped ``--database`` would otherwise put their work in a new, empty database unnoticed)."""

    from tourbot.web.db import default_url, open_database, sqlite_file

    name = Path(site).stem if site.endswith((".yaml", ".yml")) else Path(site).name
    url = database or default_url(name)
    file = sqlite_file(url)
    new = file is not None and not file.exists()
    db = open_database(url, site=name)
    if new:
        typer.echo(f"created a new database {file}", err=True)
    return db


def read_staff_password(file: Path | None, ask: bool) -> str | None:
    """The staff password from one of: ``$TOURBOT_STAFF_PASSWORD``, the first line of ``file``, a
    hidden prompt (``ask``); None when none is given. Never from the command line, which every
    user of the machine can read (``ps``)."""
    import os

    from tourbot.errors import InputError

    env = os.environ.get("TOURBOT_STAFF_PASSWORD")
    given = [name for name, on in [("$TOURBOT_STAFF_PASSWORD", env), ("--staff-password-file", file),
                                   ("--ask-staff-password", ask)] if on]  # fmt: skip
    if len(given) > 1:
        raise InputError(f"give the staff password one way, not {' and '.join(given)}", field=given[1])
    if file is not None:
        try:
            lines = file.read_text().splitlines()
        except OSError as exc:
            raise InputError(
                f"cannot read {file}: {exc.strerror or exc}", field="--staff-password-file"
            ) from None
        if not lines or not lines[0]:
            raise InputError(f"{file}: the first line (the password) is empty", field="--staff-password-file")
        return lines[0]
    if ask:
        return str(typer.prompt("staff password", hide_input=True, confirmation_prompt=True))
    return env or None


def register(app: typer.Typer) -> None:
    site_app = typer.Typer(
        help="Author a site's exhibits and tours (the web database).", no_args_is_help=True
    )
    app.add_typer(site_app, name="site")
    from tourbot.cli.site_new import add_new

    add_new(site_app)

    @app.command()
    def serve(
        site: SiteOpt = "fhw",
        host: Annotated[str, typer.Option(help="address to listen on")] = "127.0.0.1",
        port: Annotated[int, typer.Option(help="TCP port")] = 8000,
        database: DatabaseOpt = None,
        robots: Annotated[
            int,
            typer.Option(
                min=1,
                max=8,
                help="simulated robots in one museum (one world: one crowd), each with its queue",
            ),
        ] = 1,
        crowd: Annotated[str, typer.Option(help="visitors: empty, sparse, peak or a number")] = "sparse",
        seed: Annotated[int, typer.Option(help="simulation seed")] = 0,
        slot_minutes: Annotated[float, typer.Option(help="length of a control slot")] = 10.0,
        staff_password_file: StaffPasswordFileOpt = None,
        ask_staff_password: AskStaffPasswordOpt = False,
        certfile: Annotated[Path | None, typer.Option(help="TLS certificate (PEM): serve HTTPS")] = None,
        keyfile: Annotated[Path | None, typer.Option(help="TLS private key (PEM) of --certfile")] = None,
        trusted_proxy: Annotated[
            list[str] | None,
            typer.Option(help="address of a reverse proxy whose X-Forwarded-For is believed (repeatable)"),
        ] = None,
        robot_process: Annotated[
            bool,
            typer.Option(
                "--robot-process/--robot-in-server",
                help="run each simulated robot in its own process (the default), or in the server's",
            ),
        ] = True,
        config: Annotated[
            Path | None,
            typer.Option(
                "--config",
                help="Localization profile of the robots (YAML; default: the site's localization.yaml "
                "when it ships one, else the papers' values).",
            ),
        ] = None,
        foxglove: FoxgloveOpt = None,
        broker: Annotated[
            str | None,
            typer.Option(
                help="publish the robots' state on this Redis broker (redis://HOST:PORT/DB) "
                "for follower servers"
            ),
        ] = None,
        camera: Annotated[
            list[str] | None,
            typer.Option(
                help="cameras the simulated robots carry and use (repeat or comma list): 'ceiling' (fused "
                "into MCL), 'forward' (its vision obstacles in the navigator's costmap and on the map)",
            ),
        ] = None,
        follow: Annotated[
            str | None,
            typer.Option(
                help="run no robots: show those a server publishes on this Redis broker "
                "(control stays on that server)"
            ),
        ] = None,
    ) -> None:
        """Serve the tele-presence site: visitor page, on-board screen, staff pages, live stream.

        Several servers can share the viewers of the same robots: one runs them with ``--broker``,
        the others show them with ``--follow`` (the same site, and best the same ``--database``).
        """
        from tourbot.app.simulated import camera_names, crowd_config
        from tourbot.errors import InputError
        from tourbot.localization.profile import LocalizationProfile
        from tourbot.site.default import site_path
        from tourbot.web.db import check_staff_password
        from tourbot.web.serve import ServeSettings, build_site_app, run

        # checked before the database is opened (and the site imported into it)
        if not slot_minutes > 0:
            raise InputError(f"must be positive (minutes), got {slot_minutes}", field="--slot-minutes")
        if not 0 <= port <= 65535:
            raise InputError(f"must be a TCP port (0-65535), got {port}", field="--port")
        if foxglove is not None and not 0 < foxglove <= 65535 - robots:
            raise InputError(f"must be a TCP port (1-{65535 - robots}), got {foxglove}", field="--foxglove")
        crowd_config(crowd)
        cameras = camera_names(camera or [], field="--camera")
        if broker and follow:
            raise InputError(
                "give --broker (publish) or --follow (show another server's), not both", field="--follow"
            )
        if (certfile is None) != (keyfile is None):
            raise InputError(
                "TLS needs both --certfile and --keyfile", field="--keyfile" if certfile else "--certfile"
            )
        for name, path in (("--certfile", certfile), ("--keyfile", keyfile)):
            if path is not None and not path.is_file():
                raise InputError(f"{path}: no such file", field=name)
        staff_password = read_staff_password(staff_password_file, ask_staff_password)
        if staff_password is not None:
            check_staff_password(staff_password)

        proxies = tuple(trusted_proxy or ())
        settings = ServeSettings(
            site=site, database=database, robots=robots, crowd=crowd, seed=seed, host=host, port=port,
            slot_minutes=slot_minutes, staff_password=staff_password, robot_process=robot_process,
            mcl=LocalizationProfile.for_site(site_path(site), config)[0].mcl,
            certfile=certfile, keyfile=keyfile, trusted_proxies=proxies, foxglove=foxglove,
            broker=broker, follow=follow, cameras=cameras,
        )  # fmt: skip
        web, _ = build_site_app(settings)
        run(web, host, port, certfile=certfile, keyfile=keyfile, trusted_proxies=proxies)

    @site_app.command("import")
    def import_(
        site: SiteOpt = "fhw",
        database: DatabaseOpt = None,
        replace: Annotated[bool, typer.Option(help="overwrite exhibits and tours edited since")] = False,
    ) -> None:
        """Copy a site file's exhibits (at their viewing poses) and tours into the database."""
        from tourbot.site.default import site_path
        from tourbot.site.model import load_site
        from tourbot.web.sitedata import import_site

        db = _db(database, site)
        exhibits, tours = import_site(load_site(site_path(site)), db, replace=replace)
        typer.echo(f"{exhibits} exhibits and {tours} tours written to {db.url}")

    @site_app.command("list")
    def list_(site: SiteOpt = "fhw", database: DatabaseOpt = None) -> None:
        """The exhibits and tours in the database, with visit counts."""
        from rich.console import Console
        from rich.table import Table

        db = _db(database, site)
        visits = db.visit_counts()
        table = Table(title="exhibits")
        for col in ("slug", "name", "x", "y", "theta", "visits"):
            table.add_column(col)
        for e in db.exhibits():
            table.add_row(
                e.slug, e.name, f"{e.x:.2f}", f"{e.y:.2f}", f"{e.theta:.2f}", str(visits.get(e.slug, 0))
            )
        console = Console()
        console.print(table)
        for t in db.tours():
            console.print(f"tour [bold]{t.slug}[/] ({t.name}): {' -> '.join(t.exhibits)}")

    @site_app.command("exhibit")
    def exhibit(
        slug: Annotated[str, typer.Argument(help="short name, e.g. minoan-fresco")],
        x: Annotated[float, typer.Option(help="where the robot stands to present it (m)")],
        y: Annotated[float, typer.Option(help="and y of that viewing pose (m)")],
        theta: Annotated[float, typer.Option(help="heading at the viewing pose (rad)")] = 0.0,
        name: Annotated[str | None, typer.Option(help="display name")] = None,
        text: Annotated[str, typer.Option(help="the exhibit's text")] = "",
        summary: Annotated[str, typer.Option(help="what the robot says on arrival")] = "",
        picture: Annotated[list[str] | None, typer.Option(help="picture URL (repeatable)")] = None,
        link: Annotated[list[str] | None, typer.Option(help="link URL (repeatable)")] = None,
        site: SiteOpt = "fhw",
        database: DatabaseOpt = None,
    ) -> None:
        """Add an exhibit, or replace one with the same slug."""
        from tourbot.errors import InputError
        from tourbot.web.db import DatabaseError, check_link_url
        from tourbot.web.sitedata import title

        for option, urls in (("--picture", picture or []), ("--link", link or [])):
            for url in urls:  # before a database is opened (or created)
                try:
                    check_link_url(url)
                except DatabaseError as exc:
                    raise InputError(str(exc), field=option) from None
        db = _db(database, site)
        saved = db.save_exhibit(
            slug, name or title(slug), x=x, y=y, theta=theta, text=text, summary=summary,
            pictures=[(u, "") for u in picture or []], links=[(u, "") for u in link or []],
        )  # fmt: skip
        typer.echo(f"exhibit {saved.slug} at ({saved.x:.2f}, {saved.y:.2f}, {saved.theta:.2f})")

    @site_app.command("place")
    def place(
        slug: Annotated[str, typer.Argument(help="the exhibit's short name")],
        x: Annotated[float, typer.Argument(help="new viewing pose x (m)")],
        y: Annotated[float, typer.Argument(help="new viewing pose y (m)")],
        theta: Annotated[float | None, typer.Option(help="new heading (rad)")] = None,
        site: SiteOpt = "fhw",
        database: DatabaseOpt = None,
    ) -> None:
        """Move an exhibit's viewing pose."""
        saved = _db(database, site).place_exhibit(slug, x, y, theta)
        typer.echo(f"exhibit {saved.slug} at ({saved.x:.2f}, {saved.y:.2f}, {saved.theta:.2f})")

    @site_app.command("remove")
    def remove(
        slug: Annotated[str, typer.Argument(help="the exhibit's short name")],
        site: SiteOpt = "fhw",
        database: DatabaseOpt = None,
    ) -> None:
        """Remove an exhibit (and it from every tour)."""
        _db(database, site).delete_exhibit(slug)
        typer.echo(f"removed {slug}")

    @site_app.command("tour")
    def tour(
        slug: Annotated[str, typer.Argument(help="the tour's short name, e.g. highlights")],
        exhibits: Annotated[list[str], typer.Argument(help="exhibit slugs in visiting order")],
        name: Annotated[str | None, typer.Option(help="display name")] = None,
        description: Annotated[str, typer.Option(help="what the tour is about")] = "",
        site: SiteOpt = "fhw",
        database: DatabaseOpt = None,
    ) -> None:
        """Add or replace a tour."""
        from tourbot.web.sitedata import title

        saved = _db(database, site).save_tour(slug, name or title(slug), exhibits, description)
        typer.echo(f"tour {saved.slug}: {' -> '.join(saved.exhibits)}")

    @site_app.command("staff")
    def staff(
        username: Annotated[str, typer.Argument(help="login name")],
        password: Annotated[
            str | None,
            typer.Option(
                prompt=True,
                hide_input=True,
                confirmation_prompt=True,
                show_default=False,
                help="asked for (twice, hidden) if not given",
            ),
        ] = None,
        site: SiteOpt = "fhw",
        database: DatabaseOpt = None,
    ) -> None:
        """Create a staff login (or change its password)."""
        from tourbot.web.db import check_staff_password

        check_staff_password(password or "")  # before a database is opened (or created)
        _db(database, site).set_staff(username, password or "")
        typer.echo(f"staff user {username} saved")
