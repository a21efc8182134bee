"""``tourbot log``: look into robot logs (CARMEN, ROS bags) and convert them."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer

LogArg = Annotated[Path, typer.Argument(help="A CARMEN log (.log, .log.gz, .clf) or a ROS bag.")]
LenientOpt = Annotated[
    bool, typer.Option("--lenient", help="Skip malformed records (counted in a warning) instead of stopping.")
]


class OdometryStream(StrEnum):
    """How a re-anchored odometry stream (corrected CARMEN logs) is read."""

    rebuilt = "rebuilt"
    as_recorded = "as-recorded"


OdometryOpt = Annotated[
    OdometryStream,
    typer.Option(
        "--odometry-stream",
        help="A stream re-anchored to the corrected pose at every scan: rebuilt (raw odometry from its "
        "increments) or as-recorded (kept; it holds the reference's corrections).",
    ),
]


def register(app: typer.Typer) -> None:
    log_app = typer.Typer(help="Robot logs: summary, conversion to CARMEN and TUM.", no_args_is_help=True)

    @log_app.command("info")
    def info(
        log: LogArg, lenient: LenientOpt = False, odometry_stream: OdometryOpt = OdometryStream.rebuilt
    ) -> None:
        """Summary of a log: scans, beams, duration, path length, warnings."""
        import numpy as np
        from rich.console import Console
        from rich.table import Table

        from tourbot.io import load_log, log_kind
        from tourbot.plotting import align_rigid, path_length

        console = Console()
        with console.status(f"reading {log}"):
            robot_log = load_log(log, lenient=lenient, odometry=odometry_stream.value)
        # the file above the table, not as its title: a title wraps to the table's narrow width
        console.print(str(log), style="bold", highlight=False, soft_wrap=True)
        table = Table(show_header=False)
        table.add_column("what", style="bold")
        table.add_column("value")
        scans = robot_log.scans
        sensors = sorted({s.sensor for s in scans})
        beams = sorted({s.geometry.num_beams for s in scans})
        g = scans[0].geometry
        table.add_row("format", "ROS bag" if log_kind(log) == "rosbag" else "CARMEN log")
        table.add_row("laser", ", ".join(sensors))
        table.add_row("scans", str(len(scans)))
        table.add_row("beams per scan", ", ".join(map(str, beams)))
        table.add_row("field of view", f"{g.fov * 180 / 3.141592653589793:.1f} deg")
        table.add_row("max range", f"{g.max_range:.2f} m")
        span, why = robot_log.duration()
        table.add_row("duration", f"{span:.1f} s" if span is not None else f"unknown ({why})")
        table.add_row("odometry readings", str(len(robot_log.odometry)))
        if not all(s.odom is None for s in scans):
            table.add_row("path length (odometry)", f"{path_length(robot_log.odom_poses):.1f} m")
        if robot_log.has_reference:
            table.add_row("path length (reference)", f"{path_length(robot_log.reference_poses):.1f} m")
            if not np.isnan(robot_log.odom_poses).any():
                # the odometry moved onto the reference by the best rigid fit: its drift (evo's APE, aligned)
                moved = align_rigid(robot_log.odom_poses, robot_log.reference_poses)
                gap = np.hypot(*(moved[:, :2] - robot_log.reference_poses[:, :2]).T)
                table.add_row(
                    "odometry vs reference",
                    f"{np.sqrt(np.mean(gap**2)):.2f} m RMS (aligned), {gap.max():.2f} m max",
                )
        else:
            table.add_row("reference poses", "none")
        table.add_row("odometry", robot_log.odometry_kind)
        table.add_row("warnings", str(len(robot_log.warnings)))
        console.print(table)
        for note in robot_log.notes:
            console.print(f"[bold]inferred:[/] {note}", highlight=False)
        for warning in robot_log.warnings:
            console.print(f"[yellow]warning:[/] {warning}", highlight=False)

    @log_app.command("convert")
    def convert(
        log: LogArg,
        output: Annotated[
            Path,
            typer.Option(
                "-o",
                "--output",
                help="Log to write: CARMEN (.log, .log.gz), ROS 2 MCAP (.mcap), or a ROS 2 bag folder "
                "(sqlite3; a name without a suffix).",
            ),
        ],
        lenient: LenientOpt = False,
        odometry_stream: OdometryOpt = OdometryStream.rebuilt,
        force: Annotated[
            bool, typer.Option("--force", help="Replace an existing ROS 2 output (.mcap or bag folder).")
        ] = False,
    ) -> None:
        """Write a log (CARMEN or ROS bag) as a CARMEN log that reads back identically, or as a
        ROS 2 bag (scans and odometry; reference poses have no place in a bag)."""
        from tourbot.errors import InputError
        from tourbot.io import load_log, write_carmen

        ros2 = output.suffix in {".mcap", ""}
        if ros2:
            from tourbot.io.mcap_out import check_mcap_output, write_log_as_ros2

            if output.suffix == ".mcap":
                check_mcap_output(output, force=force, option="--output")
            elif output.exists() and not (force and (output / "metadata.yaml").exists()):
                raise InputError(
                    "exists; --force replaces a ROS 2 bag folder (never another folder or file)",
                    path=output,
                    field="--output",
                )
        robot_log = load_log(log, lenient=lenient, odometry=odometry_stream.value)
        if ros2:
            write_log_as_ros2(robot_log, output)
        else:
            write_carmen(robot_log, output)
        typer.echo(f"wrote {output} ({len(robot_log)} scans, {len(robot_log.odometry)} odometry readings)")

    @log_app.command("tum")
    def tum(
        log: LogArg,
        output: Annotated[Path, typer.Option("-o", "--output", help="TUM trajectory file to write.")],
        poses: Annotated[
            str, typer.Option(help="Which pose of each scan: 'reference' or 'odometry'.")
        ] = "reference",
        lenient: LenientOpt = False,
        odometry_stream: OdometryOpt = OdometryStream.rebuilt,
    ) -> None:
        """Write the pose of each scan, in log order, as a TUM trajectory (for evo)."""
        import numpy as np

        from tourbot.errors import TourbotError
        from tourbot.io import load_log
        from tourbot.io.tum import write_tum

        if poses not in ("reference", "odometry"):
            raise TourbotError(f"--poses must be 'reference' or 'odometry', got {poses!r}")
        robot_log = load_log(log, lenient=lenient, odometry=odometry_stream.value)
        values = robot_log.reference_poses if poses == "reference" else robot_log.odom_poses
        ok = ~np.isnan(values).any(axis=1)
        if not ok.any():
            raise TourbotError(f"{log}: no scan has a {poses} pose")
        write_tum(output, robot_log.times[ok], values[ok])
        typer.echo(f"wrote {output} ({int(ok.sum())} poses)")

    app.add_typer(log_app, name="log")
