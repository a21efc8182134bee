"""``tourbot slam``: a map and the robot's path from a log, by incremental scan matching."""

from __future__ import annotations

from contextlib import nullcontext
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from tourbot.cli._checks import ForceOpt
from tourbot.cli.logs import OdometryOpt, OdometryStream
from tourbot.cli.maps import MapModeOpt, check_map_mode
from tourbot.cli.people import LegModelOpt, tracker_config

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from tourbot.io.mcap_out import McapRun
    from tourbot.mapping.graph_slam import GraphSlam
    from tourbot.mapping.incremental import IncrementalMapper
    from tourbot.mapping.people_filter import PeopleFilteredMapper
    from tourbot.maps.grid import OccupancyGrid
    from tourbot.records import Scan

    FloatArray = NDArray[np.float64]

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
        mcap: Annotated[
            Path | None,
            typer.Option(
                "--mcap",
                help="Also write the run as MCAP (ROS 2 messages: scans, odometry, TF, the SLAM pose as "
                "the estimate, the map as it grows (--mcap-map-every) and finished; with --people-filter "
                "the people tracked) for Foxglove; an existing file is replaced only with --force.",
            ),
        ] = None,
        mcap_map_every: Annotated[
            int,
            typer.Option(
                "--mcap-map-every",
                help="With --mcap: the scan matcher's map so far every this many scans (0: the finished "
                "map only).",
            ),
        ] = 50,
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
        from tourbot.errors import InputError
        from tourbot.io import load_log
        from tourbot.io.mapserver import check_map_output, write_map
        from tourbot.io.mcap_out import McapRun, check_mcap_output
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
        if mcap_map_every < 0:
            raise InputError(f"must be 0 or more, got {mcap_map_every}", field="--mcap-map-every")
        config = tracker_config(leg_model) if people_filter else None  # a bad model: before mapping
        check_map_output(output)  # before the mapping, which can take minutes
        if trajectory is not None:
            check_output(trajectory, "--trajectory")
        if mcap is not None:
            check_mcap_output(mcap, force=force)
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
            with (
                ScanProgress(f"mapping {log.name}", len(robot_log.scans)) as progress,
                McapRun(mcap) if mcap is not None else nullcontext() as run,
            ):
                for scan in robot_log.scans:
                    if graph is not None:
                        pose = graph.add_scan(scan)
                    elif filtered is not None:
                        pose = filtered.add_scan(scan)
                    else:
                        pose = np.asarray(mapper.add_scan(scan).pose)
                    done += 1
                    if run is not None:
                        _record_scan(run, scan, pose, filtered)
                        if mcap_map_every and done % mcap_map_every == 0:
                            run.write_map(mapper.grid(), scan.timestamp)
                    progress.advance()
                poses, grid = _finish(graph, filtered, mapper)
                if run is not None:
                    run.write_map(grid, robot_log.scans[-1].timestamp)
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
        write_map(grid, output, mode=map_mode)  # type: ignore[arg-type]
        typer.echo(f"map: {output}")
        if mcap is not None:
            typer.echo(
                f"the run as MCAP (ROS 2 messages; the SLAM pose on /estimate, the map on /map): {mcap}"
            )
        if graph is not None:
            typer.echo(f"loop closures: {len(graph.closures)} accepted, {graph.rejected} rejected")
        if filtered is not None:
            typer.echo(f"beams left out as people: {filtered.removed_beams}")
            if filtered.params.consistency is not None and graph is None:
                typer.echo(f"cells cleared as specks the map contradicts: {filtered.cleared_cells}")
        if trajectory is not None:
            write_tum(trajectory, robot_log.times, poses)
            typer.echo(f"trajectory: {trajectory}")


def _finish(
    graph: GraphSlam | None, filtered: PeopleFilteredMapper | None, mapper: IncrementalMapper
) -> tuple[FloatArray, OccupancyGrid]:
    """The finished path (loops closed, with a graph) and map."""
    import numpy as np

    if graph is not None:
        poses = graph.finish()
        return poses, graph.grid()
    if filtered is not None:
        filtered.finish()
        return np.asarray(mapper.poses), filtered.grid()
    return np.asarray(mapper.poses), mapper.grid()


def _record_scan(run: McapRun, scan: Scan, pose: FloatArray, filtered: PeopleFilteredMapper | None) -> None:
    """One scan into the MCAP file: the scan, its odometry, the SLAM pose after it as the estimate
    (SLAM gives no covariance: the matrix is zero) and, with the people filter, the confirmed tracks."""
    import numpy as np

    from tourbot.snapshot import PersonState

    assert scan.odom is not None  # checked before mapping
    run.write_scan(scan)
    run.write_odometry(scan.odom, scan.timestamp)
    run.write_estimate(pose, np.zeros((3, 3)), scan.odom, scan.timestamp)
    if filtered is not None:
        tracks = [t for t in filtered.tracker.tracks() if t.confirmed]
        run.write_people(
            [PersonState(t.id, *t.position, *t.velocity, t.confirmed) for t in tracks], scan.timestamp
        )
