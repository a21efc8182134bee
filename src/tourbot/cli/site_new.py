"""``tourbot site new LOG --name NAME -o sites/NAME/``: a site from one robot log."""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path
from typing import Annotated

import typer

from tourbot.io.output import PARTIAL_PREFIX

__all__ = ["add_new"]


def add_new(site_app: typer.Typer) -> None:
    """Add ``new`` to the ``tourbot site`` commands."""

    @site_app.command("new")
    def new(
        log: Annotated[
            Path, typer.Argument(help="A robot log with odometry (CARMEN .log/.log.gz or a ROS bag).")
        ],
        name: Annotated[str, typer.Option(help="The site's name.")],
        output: Annotated[
            Path, typer.Option("-o", "--output", help="The site folder to create (must not exist).")
        ],
        seed: Annotated[int, typer.Option(help="Seed of the people tracker.")] = 0,
        lenient: Annotated[bool, typer.Option(help="Skip malformed records instead of stopping.")] = False,
    ) -> None:
        """Map the log (graph SLAM, people filtered; a line map beside it), suggest doors, write
        map.yaml, lines.geojson, lines.svg and site.yaml."""
        import yaml

        from tourbot.errors import InputError
        from tourbot.io import load_log
        from tourbot.io.line_map import write_line_map
        from tourbot.io.mapserver import write_map
        from tourbot.mapping.new_site import check_log, line_map_log, map_log, site_document, tour_stops
        from tourbot.maps.doors import suggest_doorways
        from tourbot.site.model import load_site

        if not name.strip():
            raise InputError("must not be empty", field="--name")
        if output.exists() and (not output.is_dir() or any(output.iterdir())):
            raise InputError("exists already; give a new folder for the site", path=output, field="--output")
        t0 = time.perf_counter()
        robot_log = load_log(log, lenient=lenient)
        for warning in robot_log.warnings:
            typer.echo(f"warning: {warning}", err=True)
        check_log(robot_log, str(log))
        grid, slam = map_log(robot_log, seed=seed)
        lines = line_map_log(robot_log)
        mapped = time.perf_counter() - t0
        doorways = suggest_doorways(grid)
        walls = lines.segments()
        output.parent.mkdir(parents=True, exist_ok=True)
        partial = output.with_name(f"{PARTIAL_PREFIX}{os.getpid()}-{output.name}")
        try:  # written beside, checked, then renamed: never a half-made site folder
            partial.mkdir()
            write_map(grid, partial / "map.yaml")
            if len(walls):
                path = lines.poses[:, :2]
                write_line_map(partial / "lines.geojson", walls, lines.corners, path)
                write_line_map(partial / "lines.svg", walls, lines.corners, path)
            else:
                typer.echo("warning: no wall was seen by enough scans to make a line map", err=True)
            doc = site_document(name, log.name, doorways, tour_stops(slam.poses))
            (partial / "site.yaml").write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
            load_site(partial / "site.yaml").grid  # noqa: B018 - the site and its map read back
            if output.exists():
                output.rmdir()
            os.replace(partial, output)
        except BaseException:
            shutil.rmtree(partial, ignore_errors=True)
            raise
        typer.echo(
            f"site {name}: {output / 'site.yaml'} ({len(robot_log.scans)} scans mapped in {mapped:.1f} s, "
            f"{len(slam.closures)} loop closures, {len(walls)} walls in the line map, "
            f"{len(doorways)} doors suggested; "
            f"{time.perf_counter() - t0:.1f} s in all)"
        )
