"""``tourbot slam``: a map and the robot's path from a log, by incremental scan matching."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from tourbot.cli._checks import ForceOpt
from tourbot.cli.logs import OdometryOpt, OdometryStream
from tourbot.cli.maps import MapModeOpt, check_map_mode
from tourbot.cli.people import LegModelOpt, tracker_config

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    @app.command("slam")
    def slam(
        log: Annotated[Path, typer.Argument(help="A CARMEN log (.log, .log.gz) or a ROS bag with odometry.")],
        output: Annotated[
            Path, typer.Option("-o", "--output", help="The map to write (ROS map_server YAML).")
        ],
        trajectory: Annotated[
            Path | None, typer.Option("--trajectory", help="Also write the path as a TUM trajectory.")
        ] = None,
        people_filter: Annotated[
            bool,
            typer.Option(
                "--people-filter/--no-people-filter",
                help="Track people and leave them out of the alignment and the map (Burgard et al. Sec. 5).",
            ),
        ] = False,
        people_mode: Annotated[
            str,
            typer.Option(
                help="With --people-filter: checked (the default: the paper's filter, the space seen "
                "between beams cleared, far person-sized blobs left out, and the finished map checked: "
                "left-out beams other scans confirm given back, specks it sees free floor around and "
                "behind cleared) or paper (tracks and person features only, Burgard et al. Sec. 5)."
            ),
        ] = "checked",
        loop_closure: Annotated[
            bool,
            typer.Option(
                "--loop-closure/--no-loop-closure",
                help="Close loops: a pose graph over the scan matcher, optimised with GTSAM (graph SLAM).",
            ),
        ] = True,
        resolution: Annotated[float, typer.Option(help="Cell size of the map, metres.")] = 0.05,
        lenient: Annotated[bool, typer.Option(help="Skip malformed records instead of stopping.")] = False,
        seed: Annotated[int, typer.Option(help="Seed of the people tracker's particle filters.")] = 0,
        map_mode: MapModeOpt = "trinary",
        leg_model: LegModelOpt = None,
        odometry_stream: OdometryOpt = OdometryStream.rebuilt,
        force: ForceOpt = False,
        keep_partial: Annotated[
            bool,
            typer.Option(
                "--keep-partial", help="On Ctrl-C, write the map and trajectory of the scans mapped so far."
            ),
        ] = False,
    ) -> None:
        """Build a map by incremental scan matching (Burgard et al. Sec. 2.1) and, by default, close
        its loops (graph SLAM), with progress.

        Uses only the raw odometry and the scans; the path starts at the first odometry pose.
        """
        import numpy as np

        from tourbot.cli._checks import check_before_work, log_problems
        from tourbot.io import load_log
        from tourbot.io.mapserver import check_map_output, write_map
        from tourbot.io.output import check_output
        from tourbot.io.progress import ScanProgress
        from tourbot.io.tum import write_tum
        from tourbot.mapping.graph_slam import GraphSlam, GraphSlamParams
        from tourbot.mapping.incremental import IncrementalMapper, MapperParams, MappingError
        from tourbot.mapping.people_filter import (
            FILTER_MODES,
            PeopleFilteredMapper,
            PeopleFilterParams,
            PeopleMappingConfig,
        )

        if not resolution > 0:
            raise MappingError(f"--resolution must be positive, got {resolution}")
        if people_mode not in FILTER_MODES:
            raise MappingError(f"--people-mode must be one of {', '.join(FILTER_MODES)}, got {people_mode!r}")
        if leg_model is not None and not people_filter:
            raise MappingError("--leg-model is used only with --people-filter")
        check_map_mode(map_mode)
        config = tracker_config(leg_model) if people_filter else None  # a bad model: before mapping
        check_map_output(output)  # before the mapping, which can take minutes
        if trajectory is not None:
            check_output(trajectory, "--trajectory")
        robot_log = load_log(log, lenient=lenient, odometry=odometry_stream.value)
        for warning in robot_log.warnings:
            typer.echo(f"warning: {warning}", err=True)
        if not robot_log.scans:
            raise MappingError(f"{log}: the log has no laser scans")
        missing = sum(s.odom is None for s in robot_log.scans)
        if missing:
            raise MappingError(
                f"{log}: {missing} of {len(robot_log.scans)} scans have no odometry pose; mapping needs "
                "the odometry of every scan"
            )
        for warning in check_before_work(log_problems(robot_log), path=log, force=force):
            typer.echo(f"warning: {warning}", err=True)
        params = MapperParams(resolution=resolution)
        filtered = (
            PeopleFilteredMapper.create(
                PeopleMappingConfig(
                    mapper=params, tracker=config, filter=PeopleFilterParams.mode(people_mode)
                ),
                seed=seed,
            )
            if config is not None
            else None
        )
        mapper = filtered.mapper if filtered is not None else IncrementalMapper(params)
        graph = GraphSlam(GraphSlamParams(mapper=params), people=filtered) if loop_closure else None
        if graph is not None:
            mapper = graph.front
        done = 0
        try:
            with ScanProgress(f"mapping {log.name}", len(robot_log.scans)) as progress:
                for scan in robot_log.scans:
                    if graph is not None:
                        graph.add_scan(scan)
                    elif filtered is not None:
                        filtered.add_scan(scan)
                    else:
                        mapper.add_scan(scan)
                    done += 1
                    progress.advance()
        except KeyboardInterrupt:
            if keep_partial and done > 0:
                # the scan matcher's map and path so far (loops not closed: the graph is not finished)
                write_map(mapper.grid(), output, mode=map_mode)  # type: ignore[arg-type]
                if trajectory is not None:
                    write_tum(trajectory, robot_log.times[:done], np.asarray(mapper.poses)[:done])
                typer.echo(
                    f"interrupted: wrote the map of the {done} scans mapped so far: {output}", err=True
                )
            raise
        if graph is not None:
            poses = graph.finish()
            grid = graph.grid()
        else:
            if filtered is not None:
                filtered.finish()
            grid = filtered.grid() if filtered is not None else mapper.grid()
            poses = np.asarray(mapper.poses)
        write_map(grid, output, mode=map_mode)  # type: ignore[arg-type]
        typer.echo(f"map: {output}")
        if graph is not None:
            typer.echo(f"loop closures: {len(graph.closures)} accepted, {graph.rejected} rejected")
        if filtered is not None:
            typer.echo(f"beams left out as people: {filtered.removed_beams}")
            if filtered.params.consistency is not None and graph is None:
                typer.echo(f"cells cleared as specks the map contradicts: {filtered.cleared_cells}")
        if trajectory is not None:
            write_tum(trajectory, robot_log.times, poses)
            typer.echo(f"trajectory: {trajectory}")
