"""``tourbot demo``: the best end-to-end thing that exists so far (a real log to a map and a picture)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def register(app: typer.Typer) -> None:
    @app.command("demo")
    def demo(
        out: Annotated[Path, typer.Option(help="Folder for the results.")] = Path("out"),
    ) -> None:
        """Build the FHW museum's map from its corrected log (cached) and draw it with the robot's path."""
        from rich.console import Console

        from tourbot.data import find_data
        from tourbot.io import read_carmen
        from tourbot.io.mapserver import read_map, write_map
        from tourbot.maps.reference import build_reference_map, map_quality
        from tourbot.plotting import show_log

        console = Console()
        log_path = find_data("carmen/fhw-corrected.log.gz")
        with console.status(f"reading {log_path.name}"):
            log = read_carmen(log_path)
        map_yaml = out / "maps" / "fhw.yaml"
        if map_yaml.exists() and map_yaml.stat().st_mtime >= log_path.stat().st_mtime:
            grid = read_map(map_yaml)
            console.print(f"map: {map_yaml} (cached)")
        else:
            with console.status("building the reference map"):
                grid = build_reference_map(log)
            write_map(grid, map_yaml)
            console.print(f"map: {map_yaml}")
        with console.status("measuring the map"):
            quality = map_quality(grid, log)
        note = f"median |ray cast - measured| {quality['median_abs_error'] * 100:.1f} cm"
        picture = show_log(
            log,
            out / "demo" / "fhw.png",
            grid=grid,
            odometry=True,
            title="Foundation of the Hellenic World, Athens: reference map and the robot's path",
            map_note=note,
        )
        console.print(f"picture: {picture}")
        console.print(note)
