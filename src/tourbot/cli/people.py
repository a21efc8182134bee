"""``tourbot track``: people tracks of a recorded log or bag, written as CSV."""

from __future__ import annotations

import math
from collections.abc import Sequence
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from tourbot.cli._checks import McapOpt
from tourbot.cli.logs import OdometryOpt, OdometryStream
from tourbot.errors import InputError

if TYPE_CHECKING:
    from tourbot.mapping.ego_motion import ScanMatchedPoses
    from tourbot.maps.grid import OccupancyGrid
    from tourbot.people.sjpdaf import SJPDAFConfig
    from tourbot.records import Scan

__all__ = [
    "CSV_HEADER",
    "TRAINED_MODEL",
    "LegModelOpt",
    "PoseSource",
    "choose_pose_source",
    "register",
    "tracker_config",
]

TRAINED_MODEL = Path("leg-model.json")  # where train-legs writes without -o: the current folder

LegModelOpt = Annotated[
    Path | None,
    typer.Option(
        "--leg-model",
        help="Leg model JSON written by 'tourbot train-legs' (default: the model shipped with tourbot).",
    ),
]


def tracker_config(leg_model: Path | None) -> SJPDAFConfig:
    """The people tracker's configuration with the leg model of ``--leg-model`` (None: the shipped
    one); a missing or bad file is a :class:`~tourbot.people.leg_classifier.LegModelError`."""
    from dataclasses import replace

    from tourbot.people.leg_classifier import LegModel, LegModelError
    from tourbot.people.legs import LegConfig
    from tourbot.people.sjpdaf import SJPDAFConfig

    if leg_model is None:
        return SJPDAFConfig()
    if not leg_model.is_file():
        what = "is a folder, not a leg model file" if leg_model.is_dir() else "no such leg model file"
        raise LegModelError(what, path=leg_model, field="--leg-model")
    return SJPDAFConfig(legs=replace(LegConfig(), model=LegModel.load(leg_model)))


class PoseSource(StrEnum):
    """Where the robot's pose at each scan comes from (tracks are in that pose's frame)."""

    auto = "auto"
    odom = "odom"
    scan_matching = "scan-matching"
    reference = "reference"
    none = "none"


def register(app: typer.Typer) -> None:
    _register_train(app)

    @app.command("track")
    def track(
        log: Annotated[Path, typer.Argument(help="A CARMEN log or a ROS bag.")],
        output: Annotated[Path, typer.Option("-o", "--output", help="The CSV of tracks to write.")],
        map_path: Annotated[
            Path | None, typer.Option("--map", help="ROS map_server YAML: legs on the map are furniture.")
        ] = None,
        scan_topic: Annotated[str | None, typer.Option(help="LaserScan topic of a bag.")] = None,
        pose: Annotated[
            PoseSource,
            typer.Option(
                help="Robot pose per scan: odometry (or tf), scan-to-map matching (Burgard Sec. 2.1), the "
                "log's reference pose, or none (robot still); a source the log lacks is an error. auto: "
                "odometry if the log has it, else scan matching while its steps stay plausible, else none "
                "(the choice is printed)."
            ),
        ] = PoseSource.auto,
        tentative: Annotated[bool, typer.Option(help="Also write tracks not yet confirmed.")] = False,
        seed: Annotated[int, typer.Option(help="Seed of the particle filters.")] = 0,
        plot: Annotated[Path | None, typer.Option(help="Also draw the tracks in this PNG.")] = None,
        leg_model: LegModelOpt = None,
        odometry_stream: OdometryOpt = OdometryStream.rebuilt,
        mcap: McapOpt = None,
        force: Annotated[bool, typer.Option("--force", help="Replace an existing --mcap file.")] = False,
    ) -> None:
        """Track people (SJPDAF, Burgard et al. Sec. 4). CSV: one row per track and scan (a scan
        with no track has one row with the track columns empty): scan, time, the robot pose used
        (robot_x, robot_y, robot_theta), track, its position x, y and velocity vx, vy in the world
        frame, and its position x_robot, y_robot in the robot's frame."""
        from tourbot.io import load_log, log_kind
        from tourbot.io.mapserver import read_map
        from tourbot.io.output import check_output
        from tourbot.io.rosbag import read_bag

        check_output(output)
        if plot is not None:
            check_output(plot, "--plot")
        if mcap is not None:
            from tourbot.io.mcap_out import check_mcap_output

            check_mcap_output(mcap, force=force)
        config = tracker_config(leg_model)  # a bad model file is refused before reading the log
        if log_kind(log) == "rosbag" and log.exists():
            robot_log = read_bag(log, scan_topic=scan_topic)
        else:
            robot_log = load_log(log, odometry=odometry_stream.value)
        grid = read_map(map_path) if map_path is not None else None
        requested = pose
        pose = choose_pose_source(robot_log.scans, requested, log)
        scans, companions = list(robot_log.scans), []
        lasers: dict[str, list[Scan]] = {}
        if pose is PoseSource.scan_matching:
            typer.echo(
                "robot pose from scan-matching (the log has no odometry or tf; each matched step is "
                "checked for a plausible speed and turn rate, the scans of each laser for how well "
                "they fit the map)"
            )
            lasers = _all_lasers(log, scans) if log_kind(log) == "rosbag" else {}
            if len(lasers) > 1:
                scans, companions = (
                    lasers[scans[0].sensor],
                    [s for name, stream in lasers.items() if name != scans[0].sensor for s in stream],
                )
        elif requested is PoseSource.auto:
            typer.echo(f"robot pose from {pose.value}")
        try:
            ids, rows, paths, ego = _track_log(
                scans, pose, config, grid, seed, tentative, output, log, mcap, companions
            )
        except _UnverifiedPosesError as exc:
            if requested is not PoseSource.auto:
                raise InputError(
                    f"scan matching failed its check at scan {exc.scan}: {exc.reason}; "
                    "try --pose none (robot still)",
                    path=log,
                    field="--pose",
                ) from None
            typer.echo(
                f"scan matching failed its check at scan {exc.scan}: {exc.reason}; "
                "robot pose from none (the robot taken as still)"
            )
            ids, rows, paths, ego = _track_log(
                robot_log.scans, PoseSource.none, config, grid, seed, tentative, output, log, mcap
            )
        if ego is not None and companions:
            _say_laser_paths(lasers, ego)
        typer.echo(f"{len(robot_log.scans)} scans, {len(ids)} tracks, {rows} rows -> {output}")
        if mcap is not None:
            typer.echo(f"the run as MCAP (ROS 2 messages; the tracks on /people) -> {mcap}")
        if plot is not None:
            _plot_tracks(paths, plot, f"{log.name}: {len(ids)} tracks")
            typer.echo(f"picture -> {plot}")


def choose_pose_source(scans: Sequence[Scan], requested: PoseSource, log: Path) -> PoseSource:
    """The pose source to use for ``scans`` of ``log``: ``auto`` is odometry (or tf, which the bag
    reader turns into odometry) when every scan has it, else scan matching; a requested source the
    log lacks is an :class:`~tourbot.errors.InputError` naming the file and what is missing."""
    has_odom = bool(scans) and all(s.odom is not None for s in scans)
    if requested is PoseSource.auto:
        return PoseSource.odom if has_odom else PoseSource.scan_matching
    lacking = {
        PoseSource.odom: (
            sum(s.odom is None for s in scans),
            "odometry (no odometry readings, no Odometry topic and no odom -> base_link transform on /tf)",
        ),
        PoseSource.reference: (
            sum(s.reference is None for s in scans),
            "reference pose (only CARMEN logs carry one, in their FLASER lines)",
        ),
    }
    if requested in lacking:
        missing, what = lacking[requested]
        if missing or not scans:
            raise InputError(
                f"--pose {requested.value}, but {missing} of {len(scans)} scans have no {what}",
                path=log,
                field="--pose",
            )
    return requested


def _all_lasers(log: Path, scans: list[Scan]) -> dict[str, list[Scan]]:
    """Every laser of the bag, each scan with its laser's mount on the robot (from tf, else from
    the scans, in the frame of the tracked laser); {} for a bag with one laser or lasers whose
    mounts the scans cannot tell (said)."""
    from tourbot.mapping.mounts import MountError, bag_lasers

    tracked = scans[0].sensor
    try:
        lasers, how = bag_lasers(log, tracked)
    except MountError as exc:
        typer.echo(
            f"the scans of {tracked} alone give the robot's pose (the other lasers are not used: {exc})"
        )
        return {}
    if len(lasers) == 1:
        return {}
    typer.echo(f"{len(lasers)} lasers matched on one map ({', '.join(lasers)}); {how}")
    return lasers


def _say_laser_paths(lasers: dict[str, list[Scan]], ego: ScanMatchedPoses) -> None:
    """The check that the lasers of one robot agree: each alone, and all but one, against the path
    of all of them on one map."""
    from tourbot.mapping.ego_motion import laser_agreement, path_length

    tracked = next(iter(lasers))
    shared = ego.path()
    fits = ego.mean_fit()
    typer.echo(
        f"path of the robot ({tracked}'s frame), all lasers on one map: {path_length(shared[1]):.1f} m; "
        "mean fit per beam: " + ", ".join(f"{name} {fit:.2f}" for name, fit in fits.items())
    )
    for row in laser_agreement(lasers, shared, ego.config):
        typer.echo(
            f"  {' + '.join(row.lasers)}{' alone' if len(row.lasers) == 1 else ''}: {row.length:.1f} m, "
            f"off it by {row.median_off:.2f} m (median) and {row.max_off:.2f} m, "
            f"{math.degrees(row.max_heading_off):.1f} deg at most; {row.implausible} scans failed the check"
        )


class _UnverifiedPosesError(Exception):
    """Scan matching produced a step no robot makes: its poses are not to be used."""

    def __init__(self, scan: int, reason: str) -> None:
        super().__init__(reason)
        self.scan = scan
        self.reason = reason


CSV_HEADER = (
    "scan",
    "time",
    "robot_x",
    "robot_y",
    "robot_theta",
    "track",
    "x",
    "y",
    "vx",
    "vy",
    "x_robot",
    "y_robot",
)


def _track_log(
    scans: Sequence[Scan],
    pose: PoseSource,
    config: SJPDAFConfig,
    grid: OccupancyGrid | None,
    seed: int,
    tentative: bool,
    output: Path,
    log: Path,
    mcap: Path | None = None,
    companions: Sequence[Scan] = (),
) -> tuple[set[int], int, dict[int, list[tuple[float, float]]], ScanMatchedPoses | None]:
    """Track ``scans`` with the robot poses of ``pose`` and write the CSV ``output`` whole (and the
    run as MCAP: each scan, the robot pose used as odometry and estimate, the tracks as ``/people``);
    the track ids, the number of track rows, each track's path and the scan matching (None without).
    Scan matching (on one map with the ``companions``, the scans of the robot's other lasers) raises
    :class:`_UnverifiedPosesError` at the first implausible step (nothing is written then)."""
    import csv
    from contextlib import nullcontext

    import numpy as np

    from tourbot.geometry import invert, transform_points
    from tourbot.io.mcap_out import McapRun
    from tourbot.io.output import output_file
    from tourbot.io.progress import ScanProgress
    from tourbot.mapping.ego_motion import ScanMatchedPoses
    from tourbot.people.sjpdaf import PeopleTracker
    from tourbot.snapshot import PersonState

    ego = ScanMatchedPoses(companions=companions) if pose is PoseSource.scan_matching else None
    tracker = PeopleTracker(config, grid_map=grid, rng=np.random.default_rng(seed), pose_source=ego)
    rows = 0
    ids: set[int] = set()
    paths: dict[int, list[tuple[float, float]]] = {}
    # written whole or not at all: an error or Ctrl-C mid-log keeps any previous CSV
    with (
        output_file(output) as tmp,
        tmp.open("w", newline="") as fh,
        ScanProgress(f"tracking {log.name}", len(scans)) as progress,
        McapRun(mcap) if mcap is not None else nullcontext() as run,
    ):
        writer = csv.writer(fh)
        writer.writerow(CSV_HEADER)
        if run is not None and grid is not None:
            run.write_map(grid, scans[0].timestamp if scans else 0.0)
        for k, scan in enumerate(scans):
            robot = None
            if ego is None:
                chosen = {PoseSource.odom: scan.odom, PoseSource.reference: scan.reference}.get(pose)
                robot = np.asarray(chosen if chosen is not None else (0.0, 0.0, 0.0), dtype=np.float64)
            tracks = [tr for tr in tracker.update(scan, robot) if tr.confirmed or tentative]
            if ego is not None and (reason := ego.implausible()) is not None:
                raise _UnverifiedPosesError(k, reason)
            used = tracker.last_pose
            head = [k, f"{scan.timestamp:.6f}", *(f"{v:.6f}" for v in used)]
            if not tracks:
                writer.writerow([*head, *[""] * 7])
            pts = np.array([tr.position for tr in tracks], dtype=np.float64).reshape(-1, 2)
            local = transform_points(invert(used), pts) if len(pts) else pts
            for tr, (lx, ly) in zip(tracks, local.tolist(), strict=True):
                writer.writerow([*head, tr.id, *(f"{v:.4f}" for v in (*tr.position, *tr.velocity, lx, ly))])
                rows += 1
                ids.add(tr.id)
                paths.setdefault(tr.id, []).append(tr.position)
            if run is not None:
                run.write_scan(scan)
                run.write_odometry(used, scan.timestamp)  # the pose used, as odom -> base_link
                run.write_estimate(used, np.zeros((3, 3)), used, scan.timestamp)  # map -> odom: identity
                people = [PersonState(tr.id, *tr.position, *tr.velocity, tr.confirmed) for tr in tracks]
                run.write_people(people, scan.timestamp)
            progress.advance()
    return ids, rows, paths, ego


def _register_train(app: typer.Typer) -> None:
    @app.command("train-legs")
    def train_legs(
        bags: Annotated[list[Path], typer.Argument(help="Annotated leg_tracker bags (*_extracted.bag).")],
        output: Annotated[
            Path,
            typer.Option(
                "-o",
                "--output",
                help=f"Model JSON to write (default: {TRAINED_MODEL} in the current folder); use it with "
                "'tourbot track --leg-model' and 'tourbot slam --leg-model'. The model shipped with "
                "tourbot is replaced only when named here.",
            ),
        ] = TRAINED_MODEL,
        match: Annotated[
            float, typer.Option(help="Metres within which a candidate is an annotated leg.")
        ] = 0.25,
    ) -> None:
        """Fit the leg model (P(leg) from a segment's shape) to annotated bags and write it as JSON."""
        from tourbot.io.errors import BagError
        from tourbot.io.output import check_output
        from tourbot.people.leg_training import train_leg_model

        check_output(output)  # before the training
        for bag in bags:
            if not bag.exists():
                raise BagError("no such bag", path=bag)
        model = train_leg_model(bags, match=match)
        model.save(output)  # written whole or not at all
        typer.echo(f"leg model ({model.trained_on}) -> {output}; use it with --leg-model {output}")


def _plot_tracks(paths: dict[int, list[tuple[float, float]]], out: Path, title: str) -> None:
    """Each track's path, one colour per id, in the world frame."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 7))
    for tid, pts in sorted(paths.items()):
        xy = list(zip(*pts, strict=True))
        ax.plot(xy[0], xy[1], lw=1.0)
        ax.annotate(str(tid), pts[-1], fontsize=6)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)
