"""``tourbot lines``: a line-feature map of a log (Burgard et al. Sec. 2.2) beside ``tourbot slam``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from tourbot.cli._checks import ForceOpt
from tourbot.cli.logs import LenientOpt, LogArg, OdometryOpt, OdometryStream

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    @app.command("lines")
    def lines(
        log: LogArg,
        output: Annotated[
            Path, typer.Option("-o", "--output", help="The line map to write (.geojson, or .svg).")
        ],
        svg: Annotated[Path | None, typer.Option("--svg", help="Also draw the line map as SVG.")] = None,
        grid: Annotated[
            Path | None,
            typer.Option(
                "--map", help="Also write the occupancy grid drawn from the lines (ROS map_server YAML)."
            ),
        ] = None,
        walls: Annotated[
            Path | None,
            typer.Option(
                "--walls", help="Also write the lines as a site's wall polygons (YAML, a site's map.walls)."
            ),
        ] = None,
        trajectory: Annotated[
            Path | None, typer.Option("--trajectory", help="Also write the path as a TUM trajectory.")
        ] = None,
        iterations: Annotated[int, typer.Option(help="Most EM iterations (E-step and M-step).")] = 5,
        resolution: Annotated[float, typer.Option(help="Cell size of --map, metres.")] = 0.05,
        lenient: LenientOpt = False,
        odometry_stream: OdometryOpt = OdometryStream.rebuilt,
        force: ForceOpt = False,
    ) -> None:
        """Map a log with line segments and corners: EM with a Rauch-Tung-Striebel smoother, loops
        closed by hypotheses started at corners (Burgard et al. Sec. 2.2).

        Uses only the raw odometry and the scans; the path starts at the first odometry pose.
        Suits structured places (walls, corridors); `tourbot slam` maps any shape.
        """
        import yaml

        from tourbot.cli._checks import check_before_work, log_problems
        from tourbot.io import load_log
        from tourbot.io.line_map import write_line_map
        from tourbot.io.mapserver import check_map_output, write_map
        from tourbot.io.output import check_output, write_text_whole
        from tourbot.io.progress import ScanProgress
        from tourbot.io.tum import write_tum
        from tourbot.mapping.features import FeatureMapper, FeatureMappingParams
        from tourbot.mapping.incremental import MappingError
        from tourbot.mapping.new_site import require_odometry
        from tourbot.site.model import segment_walls, walls_grid

        if iterations < 1:
            raise MappingError(f"--iterations must be at least 1, got {iterations}")
        if not resolution > 0:
            raise MappingError(f"--resolution must be positive, got {resolution}")
        if output.suffix.lower() not in (".geojson", ".json", ".svg"):
            raise MappingError(f"{output}: the line map is written as .geojson or .svg")
        if svg is not None and svg.suffix.lower() != ".svg":
            raise MappingError(f"{svg}: --svg needs a .svg file name")
        check_output(output)
        for extra, option in ((svg, "--svg"), (walls, "--walls"), (trajectory, "--trajectory")):
            if extra is not None:
                check_output(extra, option)
        if grid is not None:
            check_map_output(grid)
        robot_log = load_log(log, lenient=lenient, odometry=odometry_stream.value)
        for warning in robot_log.warnings:
            typer.echo(f"warning: {warning}", err=True)
        if len(robot_log.scans) < 2:
            raise MappingError(f"{log}: {len(robot_log.scans)} laser scans; a map needs at least 2")
        require_odometry(robot_log, str(log))
        for warning in check_before_work(log_problems(robot_log), path=log, force=force):
            typer.echo(f"warning: {warning}", err=True)
        mapper = FeatureMapper(FeatureMappingParams(iterations=iterations))
        with ScanProgress(f"line map of {log.name}", len(robot_log.scans)) as progress:
            result = mapper.run(robot_log.scans, progress=progress.advance)
        segments = result.segments()
        if len(segments) == 0:
            raise MappingError(f"{log}: no wall seen by enough scans to make a line map")
        observations = [len(line.obs) for line in result.lines]
        path = result.poses[:, :2]
        write_line_map(output, segments, result.corners, path, observations)
        typer.echo(f"line map: {output} ({len(segments)} walls, {len(result.corners)} corners)")
        if svg is not None:
            write_line_map(svg, segments, result.corners, path)
            typer.echo(f"picture: {svg}")
        polygons = segment_walls(segments)
        if grid is not None:
            write_map(walls_grid(polygons, resolution), grid)
            typer.echo(f"map: {grid}")
        if walls is not None:
            doc = {"walls": [[list(p) for p in poly] for poly in polygons]}
            write_text_whole(walls, yaml.safe_dump(doc, default_flow_style=None, sort_keys=False))
            typer.echo(f"walls: {walls}")
        if trajectory is not None:
            write_tum(trajectory, robot_log.times, result.poses)
            typer.echo(f"trajectory: {trajectory}")
        typer.echo(f"EM iterations: {result.iterations}; loops closed at corners: {len(result.closures)}")
