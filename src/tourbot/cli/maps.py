"""``tourbot map``: reference maps from corrected logs; ``tourbot show``: the picture of a log."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from tourbot.cli.logs import LenientOpt, LogArg, OdometryOpt, OdometryStream

MapModeOpt = Annotated[
    str,
    typer.Option(
        "--map-mode",
        help="How the map image keeps occupancy (map_server's mode): trinary (occupied/free/unknown, "
        "the default), raw (every cell's probability to 1 %, PGM) or scale (the same, PNG with alpha).",
    ),
]


def check_map_mode(mode: str) -> None:
    """Refuse an unknown ``--map-mode`` before any work."""
    from tourbot.errors import InputError
    from tourbot.io.mapserver import MAP_MODES

    if mode not in MAP_MODES:
        raise InputError(f"must be one of {', '.join(MAP_MODES)}, got {mode!r}", field="--map-mode")


def register(app: typer.Typer) -> None:
    map_app = typer.Typer(help="Maps: build reference maps, look into map_server maps.", no_args_is_help=True)

    @map_app.command("from-poses")
    def from_poses(
        log: LogArg,
        output: Annotated[
            Path, typer.Option("-o", "--output", help="Map to write: DIR/NAME.yaml (+ NAME.pgm, or .png).")
        ],
        resolution: Annotated[float, typer.Option(help="Cell size in metres.")] = 0.05,
        hit: Annotated[
            str,
            typer.Option(help="Hit cell: 'crossing' (nearest cell entry, for ray casting) or 'endpoint'."),
        ] = "crossing",
        quality: Annotated[
            bool, typer.Option(help="Measure the map: ray casts from the reference poses vs the ranges.")
        ] = True,
        lenient: LenientOpt = False,
        map_mode: MapModeOpt = "trinary",
        odometry_stream: OdometryOpt = OdometryStream.rebuilt,
    ) -> None:
        """The reference map of a corrected log (log-odds occupancy, free space traced along beams)."""
        import time

        from rich.console import Console

        from tourbot.errors import TourbotError
        from tourbot.io import load_log
        from tourbot.io.mapserver import check_map_output, write_map
        from tourbot.maps.reference import ReferenceMapParams, build_reference_map, map_quality

        if hit not in ("crossing", "endpoint"):
            raise TourbotError(f"--hit must be 'crossing' or 'endpoint', got {hit!r}")
        if not resolution > 0:
            raise TourbotError(f"--resolution must be positive (metres), got {resolution}")
        check_map_mode(map_mode)
        check_map_output(output)
        console = Console()
        with console.status(f"reading {log}"):
            robot_log = load_log(log, lenient=lenient, odometry=odometry_stream.value)
        for warning in robot_log.warnings:
            console.print(f"[yellow]warning:[/] {warning}", highlight=False)
        if not any(s.reference is not None for s in robot_log.scans):
            raise TourbotError(f"{log}: no reference poses (a corrected log is needed to map from poses)")
        params = ReferenceMapParams(resolution=resolution, hit=hit)  # type: ignore[arg-type]
        start = time.perf_counter()
        with console.status(f"tracing {sum(s.geometry.num_beams for s in robot_log.scans)} beams"):
            grid = build_reference_map(robot_log, resolution, params)
        took = time.perf_counter() - start
        pgm = write_map(grid, output, mode=map_mode)  # type: ignore[arg-type]
        rows, cols = grid.shape
        console.print(
            f"wrote {output} and {pgm.name}: {cols} x {rows} cells of {resolution * 100:g} cm "
            f"({grid.width:.1f} m x {grid.height:.1f} m), built in {took:.1f} s",
            highlight=False,
        )
        if quality:
            with console.status("measuring the map"):
                q = map_quality(grid, robot_log)
            console.print(
                f"quality: median |ray cast - measured| {q['median_abs_error'] * 100:.2f} cm, "
                f"{q['within_10cm'] * 100:.0f}% of {q['beams']:.0f} beams within 10 cm",
                highlight=False,
            )

    @map_app.command("info")
    def info(map_yaml: Annotated[Path, typer.Argument(help="A map_server map (YAML).")]) -> None:
        """Size, resolution, origin and cell counts of a map (with raw or scale maps, also the cells
        known to lie between the free and occupied thresholds)."""
        from tourbot.io.mapserver import read_map

        grid = read_map(map_yaml)
        rows, cols = grid.shape
        occupied, free, unknown = (int(m.sum()) for m in (grid.occupied(), grid.free(), grid.unknown()))
        between = grid.prob.size - occupied - free - unknown
        typer.echo(
            f"{map_yaml}: {cols} x {rows} cells of {grid.resolution:g} m ({grid.width:.2f} m x "
            f"{grid.height:.2f} m), origin {grid.origin}; occupied {occupied}, free {free}, "
            f"unknown {unknown}" + (f", between the thresholds {between}" if between else "")
        )

    app.add_typer(map_app, name="map")

    @app.command("show")
    def show(
        log: LogArg,
        output: Annotated[
            Path,
            typer.Option("-o", "--output", help="Picture to write (.png, .pdf, .svg; .png if none given)."),
        ],
        map_yaml: Annotated[
            Path | None,
            typer.Option("--map", help="Map to draw (map_server YAML); default: the log's reference map."),
        ] = None,
        trajectory: Annotated[
            list[Path] | None, typer.Option("--trajectory", help="TUM trajectory to draw (repeatable).")
        ] = None,
        odometry: Annotated[
            bool, typer.Option(help="Also draw the raw odometry, from the first pose.")
        ] = False,
        lenient: LenientOpt = False,
        odometry_stream: OdometryOpt = OdometryStream.rebuilt,
    ) -> None:
        """Picture of a log: the map, the reference path and any trajectories, labelled."""
        from tourbot.errors import TourbotError
        from tourbot.io import load_log
        from tourbot.io.mapserver import read_map
        from tourbot.io.tum import read_tum
        from tourbot.maps.reference import build_reference_map
        from tourbot.plotting import Trajectory, show_log

        output = _check_picture_format(output)
        robot_log = load_log(log, lenient=lenient, odometry=odometry_stream.value)
        trajectories = []
        for path in trajectory or []:
            times, poses = read_tum(path)
            trajectories.append(Trajectory(path.stem, poses, times))
        note = None
        if map_yaml is not None:
            grid = read_map(map_yaml)
            note = f"map {map_yaml.name}"
        elif robot_log.has_reference:
            grid = build_reference_map(robot_log)
            note = "map built from the reference poses"
        elif all(s.odom is not None for s in robot_log.scans):
            grid = build_reference_map(robot_log, use_reference=False)
            note = "no reference poses: map built from the odometry (smeared by its drift)"
        else:
            raise TourbotError(f"{log}: nothing to draw (no reference or odometry poses); give --map")
        out = show_log(
            robot_log, output, grid=grid, trajectories=trajectories, odometry=odometry, map_note=note
        )
        typer.echo(f"wrote {out}")


def _check_picture_format(output: Path) -> Path:
    """The picture to write: ``.png`` added when the name has no extension (as matplotlib would,
    so that the file named on screen is the one written); refused, before any work, when matplotlib
    cannot write its extension or it is a folder."""
    from matplotlib.backend_bases import FigureCanvasBase

    from tourbot.errors import InputError
    from tourbot.io.output import check_output

    check_output(output)
    if not output.suffix:
        output = output.with_name(output.name + ".png")
    suffix = output.suffix.lower().lstrip(".")
    formats = FigureCanvasBase.get_supported_filetypes()
    if suffix and suffix not in formats:
        raise InputError(
            f"cannot write a .{suffix} picture; use one of {', '.join('.' + f for f in sorted(formats))}",
            path=output,
            field="--output",
        )
    return output
