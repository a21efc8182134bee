"""``tourbot crowd``: lay a crowd of museum visitors (and optionally kidnappings) over a real log."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from tourbot.cli._checks import ForceOpt
from tourbot.cli.logs import LenientOpt, LogArg, OdometryOpt, OdometryStream


def register(app: typer.Typer) -> None:
    @app.command("crowd")
    def crowd(
        log: LogArg,
        map_yaml: Annotated[Path, typer.Option("--map", help="The building's map_server map (YAML).")],
        output: Annotated[
            Path, typer.Option("-o", "--output", help="Crowded CARMEN log to write (.log or .log.gz).")
        ],
        preset: Annotated[
            str, typer.Option(help="Crowd preset: sparse (museum closed) or peak (peak hours).")
        ] = "peak",
        seed: Annotated[int, typer.Option(help="Seed of the crowd, the range noise and the kidnaps.")] = 0,
        kidnap: Annotated[
            bool, typer.Option(help="Also kidnap the robot (0.005 per metre, Fox et al. 1998).")
        ] = False,
        lenient: LenientOpt = False,
        odometry_stream: OdometryOpt = OdometryStream.rebuilt,
        force: ForceOpt = False,
        objects: Annotated[
            Path | None,
            typer.Option(
                "--objects",
                help="A site file whose doors and furniture are written into the log first, in states "
                "changing over time (truth in NAME.objects.json).",
            ),
        ] = None,
    ) -> None:
        """Visitors walk through a corrected log; beams hitting them are shortened. Writes the new log
        and, beside it, NAME.truth.json (corrupted beams per scan, kidnaps); with --objects, the
        site's doors and furniture too (NAME.objects.json: their true states per scan)."""
        from rich.console import Console

        from tourbot.cli._checks import check_before_work, map_problem
        from tourbot.io import load_log, write_carmen
        from tourbot.io.mapserver import read_map
        from tourbot.io.progress import ScanProgress
        from tourbot.sim.crowd import PRESETS
        from tourbot.sim.overlay import OverlayConfig, OverlayError, overlay_crowd, truth_path, write_truth

        if preset not in PRESETS:
            raise OverlayError(f"unknown --preset {preset!r}; choose one of {', '.join(PRESETS)}")
        console = Console()
        with console.status(f"reading {log} and {map_yaml}"):
            robot_log = load_log(log, lenient=lenient, odometry=odometry_stream.value)
            grid = read_map(map_yaml)
        misfit = map_problem(robot_log, grid)
        warnings = [
            *robot_log.warnings,
            *check_before_work([misfit] if misfit else [], path=log, force=force),
        ]
        for warning in warnings:
            console.print(f"[yellow]warning:[/] {warning}", highlight=False, soft_wrap=True)
        object_truth = None
        if objects is not None:
            from tourbot.cli.objects import check_frame, check_objects, site_shapes
            from tourbot.sim.object_overlay import overlay_objects
            from tourbot.site.model import load_site

            site = load_site(objects)
            shapes = site_shapes(site, objects)
            check_objects(shapes, grid, objects)
            check_frame(robot_log, grid, log)
            poses: list[list[tuple[float, float, float]]] = [[] for _ in site.doors] + [
                f.poses for f in site.furniture
            ]
            robot_log, object_truth = overlay_objects(robot_log, shapes, poses, seed=seed)
        config = OverlayConfig.preset(preset, kidnap=kidnap)
        with ScanProgress(f"{preset} crowd over {log.name}", len(robot_log.scans)) as progress:
            result = overlay_crowd(
                robot_log,
                grid,
                config,
                seed=seed,
                preset=preset,
                progress=lambda done, _total: progress.advance(done - progress.done),
            )
        write_carmen(result.log, output)
        truth = truth_path(output)
        write_truth(result.truth, truth)
        if object_truth is not None:
            from tourbot.sim.object_overlay import object_truth_path, write_object_truth

            write_object_truth(object_truth, object_truth_path(output))
            console.print(
                f"{len(object_truth.names)} objects written in: {sum(object_truth.changed)} beams shortened; "
                f"their states in {object_truth_path(output).name}",
                highlight=False,
            )
        f = result.truth.fraction
        console.print(
            f"wrote {output} and {truth.name}: {result.truth.people} visitors; corrupted beams per scan "
            f"mean {f.mean() * 100:.1f} %, median {float(sorted(f)[len(f) // 2]) * 100:.1f} %, "
            f"{(f > 0.5).mean() * 100:.0f} % of scans above 50 % (longest stretch "
            f"{result.truth.longest_above(0.5):.0f} s); {len(result.truth.kidnaps)} kidnaps",
            highlight=False,
        )
