"""``tourbot objects``: the states of a site's doors and furniture over a log (Schulz & Burgard 2001)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from tourbot.cli.logs import LenientOpt, LogArg

if TYPE_CHECKING:
    from tourbot.io.mcap_out import McapRun
    from tourbot.maps.grid import OccupancyGrid
    from tourbot.maps.objects import ObjectShape
    from tourbot.objects.pipeline import ObjectRun
    from tourbot.records import RobotLog
    from tourbot.site.model import Site

__all__ = ["check_frame", "check_objects", "register", "site_shapes"]


def site_shapes(site: Site, path: Path) -> list[ObjectShape]:
    """The site's doors and furniture as shapes; an impossible geometry names the file and field."""
    from tourbot.maps.grid import MapError
    from tourbot.maps.objects import door_shape, furniture_shape
    from tourbot.site.model import SiteError

    shapes = []
    for section, items, build in (
        ("doors", site.doors, door_shape),
        ("furniture", site.furniture, furniture_shape),
    ):
        for i, item in enumerate(items):
            try:
                shapes.append(build(item))  # type: ignore[arg-type]
            except MapError as exc:
                raise SiteError(str(exc), path=path, field=f"{section}.{i}") from None
    return shapes


def check_objects(shapes: list[ObjectShape], grid: OccupancyGrid, path: Path) -> None:
    """Every object must lie inside the map: its hinge (door) or its site pose (furniture)."""
    import numpy as np

    from tourbot.site.model import SiteError

    doors = sum(1 for s in shapes if s.kind == "door")
    for i, s in enumerate(shapes):
        x, y = s.hinge if s.kind == "door" else s.nominal[:2]
        rc = grid.world_to_cell(np.array([[x, y]]))[0]
        if not (0 <= rc[0] < grid.shape[0] and 0 <= rc[1] < grid.shape[1]):
            field = f"doors.{i}.hinge" if s.kind == "door" else f"furniture.{i - doors}.poses"
            raise SiteError(
                f"object {s.name!r} at ({x:.2f}, {y:.2f}) is outside the map", path=path, field=field
            )


def check_frame(log: RobotLog, grid: OccupancyGrid, path: Path) -> None:
    """The log's reference poses must lie on the map's free space (the site's frame)."""
    import numpy as np

    from tourbot.errors import InputError

    if not log.has_reference:
        return
    ref = log.reference_poses
    rc = grid.world_to_cell(ref[:, :2])
    inside = (rc[:, 0] >= 0) & (rc[:, 0] < grid.shape[0]) & (rc[:, 1] >= 0) & (rc[:, 1] < grid.shape[1])
    free = np.zeros(len(ref), dtype=bool)
    free[inside] = ~grid.occupied()[rc[inside, 0], rc[inside, 1]]
    if free.mean() < 0.8:
        raise InputError(
            f"the log is not in the site's frame: only {free.mean() * 100:.0f} % of its reference poses "
            "lie on "
            "the map's free space",
            path=path,
        )


def register(app: typer.Typer) -> None:
    @app.command("objects")
    def objects(
        log: LogArg,
        site_file: Annotated[
            Path, typer.Option("--site", help="The site file with the doors and furniture.")
        ],
        output: Annotated[Path, typer.Option("-o", "--output", help="CSV of the states over time.")],
        map_yaml: Annotated[
            Path | None, typer.Option("--map", help="A map_server map instead of the site's own map.")
        ] = None,
        trajectory: Annotated[
            str | None,
            typer.Option(
                help="Take the robot's poses from here instead of localizing: 'reference' (the log's "
                "corrected poses) or a TUM file."
            ),
        ] = None,
        share: Annotated[
            str, typer.Option(help="Scans for the objects: alternate (Table 1) or all.")
        ] = "all",
        seed: Annotated[int, typer.Option(help="Seed of the estimators.")] = 0,
        lenient: LenientOpt = False,
        mcap: Annotated[
            Path | None,
            typer.Option(
                "--mcap",
                help="Also write the run as MCAP (ROS 2 messages: scans, odometry, TF, the map, the "
                "robot's estimate, the objects' outlines in their estimated states on /objects) for "
                "Foxglove; an existing file is replaced only with --force.",
            ),
        ] = None,
        force: Annotated[bool, typer.Option("--force", help="Replace an existing --mcap file.")] = False,
    ) -> None:
        """Localize along LOG (or take a trajectory) and estimate every door and piece of furniture of
        the site; writes the states over time (CSV) and a picture beside it (same name, .png)."""
        import numpy as np
        from rich.console import Console
        from rich.progress import Progress

        from tourbot.errors import InputError
        from tourbot.interfaces import ScanShare
        from tourbot.io import load_log
        from tourbot.io.output import check_output, write_text_whole
        from tourbot.objects.picture import draw_objects_figure
        from tourbot.objects.pipeline import estimate_log
        from tourbot.sim.object_overlay import object_truth_path, read_object_truth
        from tourbot.site.model import load_site

        if share not in ("alternate", "all"):
            raise InputError(f"unknown --share {share!r}; choose alternate or all")
        check_output(output)
        if mcap is not None:
            from tourbot.io.mcap_out import check_mcap_output

            check_mcap_output(mcap, force=force)
        console = Console()
        site = load_site(site_file)
        if map_yaml is not None:
            from tourbot.io.mapserver import read_map

            grid = read_map(map_yaml)
        else:
            grid = site.grid
        shapes = site_shapes(site, site_file)
        if not shapes:
            raise InputError("the site has no doors and no furniture", path=site_file, field="doors")
        check_objects(shapes, grid, site_file)
        with console.status(f"reading {log}"):
            robot_log = load_log(log, lenient=lenient)
        check_frame(robot_log, grid, log)
        poses = None
        if trajectory == "reference":
            if not robot_log.has_reference:
                raise InputError("--trajectory reference: the log has no reference poses", path=log)
            poses = robot_log.reference_poses
        elif trajectory is not None:
            from tourbot.io.tum import read_tum

            times, tum = read_tum(trajectory)
            if len(times) < 2:
                raise InputError("a trajectory needs at least two poses", path=trajectory)
            poses = np.column_stack([np.interp(robot_log.times, times, tum[:, i]) for i in range(3)])
            poses[:, 2] = np.interp(robot_log.times, times, np.unwrap(tum[:, 2]))
        truth = None
        truth_file = object_truth_path(log)
        if truth_file.exists():
            truth = read_object_truth(truth_file)
        with Progress(console=console) as progress:
            task = progress.add_task(f"objects over {log.name}", total=len(robot_log.scans))
            run = estimate_log(
                robot_log,
                shapes,
                grid,
                share=ScanShare(share),
                trajectory=poses,
                seed=seed,
                progress=lambda done, _n: progress.update(task, completed=done),
            )
        header = "time,scan,object,kind,s0,s1,s2,std0,std1,std2,status,beams,explained,occluded"
        if truth is not None:
            header += ",true0,true1,true2"
        lines = [header]
        for k, e in run.updates:
            st = list(e.state) + [""] * (3 - len(e.state))
            sd = list(e.std) + [""] * (3 - len(e.std))
            q = e.quality
            row = [f"{e.time:.3f}", str(k), e.name, e.kind, *(f"{v:.5f}" if v != "" else "" for v in st)]
            row += [f"{v:.5f}" if v != "" else "" for v in sd]
            row += [str(q.status), str(q.beams), str(q.explained), str(q.occluded)]
            if truth is not None and k < len(truth.times) and e.name in truth.names:
                tv = truth.states[truth.names.index(e.name)][k].tolist()
                row += [f"{v:.5f}" for v in tv] + [""] * (3 - len(tv))
            lines.append(",".join(row))
        write_text_whole(output, "\n".join(lines) + "\n")
        picture = output.with_suffix(".png")
        final_truth = truth.at(len(robot_log.scans) - 1) if truth is not None else None
        draw_objects_figure(
            picture,
            grid,
            shapes,
            run.final,
            np.array([p[1:] for p in run.path]).reshape(-1, 3),
            truth=final_truth,
            title=f"{log.name}: objects",
            reference=robot_log.reference_poses if robot_log.has_reference else None,
        )
        if mcap is not None:
            from tourbot.io.mcap_out import McapRun

            with McapRun(mcap) as recording:
                _record(recording, robot_log, shapes, grid, run)
        for e in run.final:
            state = ", ".join(f"{v:.3f}" for v in e.state)
            console.print(f"{e.name}: {state} ({e.quality.status}, {e.updates} updates)", highlight=False)
        console.print(f"wrote {output} ({len(run.updates)} estimates) and {picture}", highlight=False)
        if mcap is not None:
            console.print(
                f"wrote {mcap}: the run as MCAP (ROS 2 messages; the objects on /objects)", highlight=False
            )


def _record(
    recording: McapRun, log: RobotLog, shapes: list[ObjectShape], grid: OccupancyGrid, run: ObjectRun
) -> None:
    """The replay into the MCAP file: the map, then per scan the scan, its odometry, the robot's
    estimate (where it has one) and, after a scan that updated objects, every object estimated so
    far in its latest state."""
    import numpy as np

    from tourbot.objects.estimator import Observation

    recording.write_map(grid, log.scans[0].timestamp)
    pose_of = {k: i for i, k in enumerate(run.path_scans)}
    updates: dict[int, list[int]] = {}
    for u, (k, _) in enumerate(run.updates):
        updates.setdefault(k, []).append(u)
    index = {s.name: i for i, s in enumerate(shapes)}
    latest: dict[int, tuple[tuple[float, ...], bool]] = {}
    for k, scan in enumerate(log.scans):
        recording.write_scan(scan)
        i = pose_of.get(k)
        pose = None if i is None else np.asarray(run.path[i][1:], dtype=np.float64)
        odom = scan.odom if scan.odom is not None else pose  # no odometry: map -> odom the identity
        if odom is not None:
            recording.write_odometry(odom, scan.timestamp)
        if i is not None and pose is not None and odom is not None:
            recording.write_estimate(pose, run.path_covariances[i], odom, scan.timestamp)
        if k in updates:
            for u in updates[k]:
                est = run.updates[u][1]
                latest[index[est.name]] = (est.state, est.quality.status == Observation.OBSERVED)
            shown = sorted(latest)
            recording.write_objects(
                [shapes[j] for j in shown],
                [latest[j][0] for j in shown],
                [latest[j][1] for j in shown],
                scan.timestamp,
                ids=shown,
            )
