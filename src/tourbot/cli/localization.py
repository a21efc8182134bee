"""``tourbot localize``: run a localizer over a robot log and write the trajectory it estimates."""

from __future__ import annotations

import enum
import math
import time
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Protocol

import typer

from tourbot.cli._checks import ForceOpt, McapOpt
from tourbot.cli.logs import OdometryOpt, OdometryStream

if TYPE_CHECKING:
    from numpy.typing import ArrayLike
    from rich.console import Console

    from tourbot.io.mcap_out import McapRun
    from tourbot.localization.beam_filters import BeamFilter
    from tourbot.localization.estimate import LocalizationEstimate
    from tourbot.localization.profile import LocalizationProfile
    from tourbot.maps.grid import OccupancyGrid
    from tourbot.records import Scan

__all__ = ["register"]


class Method(enum.StrEnum):
    MCL = "mcl"
    GRID = "grid"


class FilterChoice(enum.StrEnum):
    NONE = "none"
    ENTROPY = "entropy"
    NOVELTY = "novelty"


def _parse_pose(text: str) -> tuple[float, float, float]:
    from tourbot.errors import InputError

    parts = text.replace(" ", "").split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise InputError(f"expected X,Y,THETA (metres, metres, radians), got {text!r}", field="--start")
    return values[0], values[1], values[2]


def register(app: typer.Typer) -> None:
    @app.command("localize")
    def localize(
        log: Annotated[Path, typer.Argument(help="Robot log: CARMEN (.log, .log.gz) or ROS bag.")],
        map_yaml: Annotated[Path, typer.Option("--map", help="map_server map (YAML + PGM) to localize in.")],
        output: Annotated[Path, typer.Option("-o", "--output", help="Trajectory to write (TUM format).")],
        method: Annotated[Method, typer.Option(help="Monte Carlo (samples) or grid Markov localization.")] = (
            Method.MCL
        ),
        beam_filter: Annotated[
            FilterChoice | None,
            typer.Option(
                "--filter",
                help="Beam filter of Fox et al. 1998: none, entropy (Eq. 3-4), novelty (Eq. 5-6) "
                "(default: the configuration's).",
            ),
        ] = None,
        particles: Annotated[
            int | None,
            typer.Option(
                help="MCL: most samples held while tracking (KLD-sampling may use fewer; default: the "
                "configuration's sampling.max_samples)."
            ),
        ] = None,
        config: Annotated[
            Path | None, typer.Option("--config", help="Localization profile (YAML; tourbot config show).")
        ] = None,
        global_: Annotated[
            bool, typer.Option("--global", help="Start lost: global localization from the whole free space.")
        ] = False,
        start: Annotated[
            str | None, typer.Option(help="Tracking: start pose X,Y,THETA in the map frame (m, m, rad).")
        ] = None,
        start_from_reference: Annotated[
            bool,
            typer.Option(
                "--start-from-reference",
                help="Tracking: start at the first scan's reference pose (experiments on corrected logs).",
            ),
        ] = False,
        seed: Annotated[int, typer.Option(help="Random seed (MCL).")] = 0,
        table_cache: Annotated[
            Path | None,
            typer.Option(
                help="Grid: directory where expected-range tables are kept between runs "
                "(default ~/.cache/tourbot/grid-tables, or under $XDG_CACHE_HOME)."
            ),
        ] = None,
        cache_table: Annotated[
            bool,
            typer.Option(help="Grid: read / keep the expected-range table in --table-cache."),
        ] = True,
        odometry_stream: OdometryOpt = OdometryStream.rebuilt,
        mcap: McapOpt = None,
        camera: Annotated[
            Path | None,
            typer.Option(
                "--camera",
                help="Upward ceiling-camera images fused into MCL: an image stream .npz (as `simulate "
                "--camera ceiling` writes) or a ROS bag's camera topic; needs --site for the ceiling lights.",
            ),
        ] = None,
        site: Annotated[
            str | None,
            typer.Option(
                "--site", help="With --camera: the site (name or file) whose ceiling lights are seen."
            ),
        ] = None,
        force: ForceOpt = False,
        keep_partial: Annotated[
            bool,
            typer.Option(
                "--keep-partial", help="On Ctrl-C, write the trajectory of the scans localized so far."
            ),
        ] = False,
    ) -> None:
        """Localize a robot from its log's odometry and scans; write one pose per scan, in log order.

        Only the raw odometry and the scans are used. The start must be chosen explicitly: a pose
        (--start), the first scan's reference pose (--start-from-reference: the paper's tracking
        experiments know where the robot starts), or none at all (--global). When the log has
        reference poses, the errors against them are reported at the end (metrics only).
        """

        import numpy as np
        from rich.console import Console

        from tourbot.cli._checks import check_before_work, log_problems, map_problem
        from tourbot.errors import InputError, TourbotError
        from tourbot.io import load_log
        from tourbot.io.mapserver import read_map
        from tourbot.io.progress import ScanProgress
        from tourbot.io.tum import write_tum
        from tourbot.localization.beam_filters import BeamFilter

        chosen = sum([global_, start is not None, start_from_reference])
        if chosen != 1:
            raise TourbotError(
                "choose exactly one start: --start X,Y,THETA, --start-from-reference (the first scan's "
                "reference pose), or --global (start lost)"
            )
        if particles is not None and particles < 1:
            raise InputError(f"must be at least 1, got {particles}", field="--particles")
        from tourbot.localization.profile import LocalizationProfile

        if mcap is not None:
            from tourbot.io.mcap_out import check_mcap_output

            check_mcap_output(mcap, force=force)
        profile = LocalizationProfile.load(config)
        ceiling = _ceiling_images(camera, site, method)
        console = Console(stderr=True)
        with console.status(f"reading {log}"):
            robot_log = load_log(log, odometry=odometry_stream.value)
            grid = read_map(map_yaml)
        if not robot_log.scans:
            raise InputError("the log has no laser scan", path=log)
        missing = [i for i, s in enumerate(robot_log.scans) if s.odom is None]
        if missing:
            raise InputError(f"scan {missing[0]} has no odometry pose (a localizer needs odometry)", path=log)
        for warning in robot_log.warnings:
            console.print(f"[yellow]warning:[/] {warning}", highlight=False, soft_wrap=True)
        problems = log_problems(robot_log)
        with console.status(f"checking {map_yaml} against the log"):
            misfit = map_problem(robot_log, grid)
        if misfit is not None:
            problems.append(misfit)
        for warning in check_before_work(problems, path=log, force=force):
            console.print(f"[yellow]warning:[/] {warning}", highlight=False, soft_wrap=True)
        pose0: tuple[float, float, float] | None = None
        if start is not None:
            pose0 = _parse_pose(start)
        elif start_from_reference:
            ref0 = robot_log.scans[0].reference
            if ref0 is None:
                raise InputError("--start-from-reference: the first scan has no reference pose", path=log)
            pose0 = ref0

        default_filter = profile.grid.beam_filter if method == Method.GRID else profile.mcl.sensor.beam_filter
        kind = default_filter if beam_filter is None else BeamFilter(beam_filter.value)
        localizer = _make_localizer(method, grid, kind, particles, seed, profile)
        if pose0 is None:
            localizer.reset_global()
        else:
            std = profile.grid.tracking_std if method == Method.GRID else profile.mcl.sampling.tracking_std
            localizer.reset_tracking(pose0, np.diag(np.square(std)))

        if method == Method.GRID:
            _prepare_grid(localizer, robot_log.scans[0].geometry.max_range, table_cache, cache_table, console)
        fuse = None if ceiling is None else _ImageFeed(ceiling, grid, robot_log, seed)

        poses = np.zeros((len(robot_log.scans), 3))
        used = np.zeros(len(robot_log.scans))
        start_time = time.perf_counter()
        done = 0
        times = robot_log.times
        try:
            with (
                ScanProgress(f"localize ({method.value} + {kind.value})", len(robot_log.scans)) as progress,
                _mcap_run(mcap) as run,
            ):
                if run is not None:
                    run.write_map(grid, float(times[0]))
                for i, scan in enumerate(robot_log.scans):
                    assert scan.odom is not None
                    if fuse is not None:
                        fuse.until(scan.timestamp, localizer, run)
                    est = localizer.update(scan.odom, scan)
                    if run is not None:
                        _record(run, scan, scan.odom, est, localizer)
                    poses[i] = est.pose
                    used[i] = est.n_used_beams / max(1, scan.geometry.num_beams)
                    done = i + 1
                    progress.advance()
        except KeyboardInterrupt:
            if keep_partial and done > 0:
                write_tum(output, times[:done], poses[:done])
                console.print(f"interrupted: wrote {output} with the {done} poses localized so far")
            raise
        took = time.perf_counter() - start_time
        write_tum(output, times, poses)
        if mcap is not None:
            console.print(f"wrote {mcap}: the run as MCAP (ROS 2 messages)", highlight=False)
        span, why = robot_log.duration()
        speed = (
            f"{span / took:.0f}x real time" if span is not None and took > 0 else f"real time unknown ({why})"
        )
        console.print(
            f"wrote {output}: {len(poses)} poses; {1000 * took / len(poses):.1f} ms per scan, {speed}; "
            f"{100 * used.mean():.0f}% of the beams integrated",
            highlight=False,
        )
        if fuse is not None:
            console.print(
                f"ceiling camera: {fuse.used} images fused ({fuse.resets} restarts of the track from "
                f"the ceiling), {fuse.outside} outside the log's time span ignored",
                highlight=False,
            )
        if robot_log.has_reference:
            from tourbot.metrics import failure_rate, pose_errors

            err, head_rad = pose_errors(poses, robot_log.reference_poses)
            head = np.degrees(head_rad)
            console.print(
                f"against the reference poses: mean error {100 * err.mean():.1f} cm, "
                f"median {100 * np.median(err):.1f} cm, heading {head.mean():.2f} deg, "
                f"{100 * failure_rate(err):.2f}% of scans > 45 cm off",
                highlight=False,
            )


def _ceiling_images(camera: Path | None, site: str | None, method: Method) -> tuple[Any, Any, Any] | None:
    """``--camera`` and ``--site`` checked before any work: (the images' times, the images, the site)."""
    from tourbot.errors import InputError

    if camera is None:
        if site is not None:
            raise InputError("--site gives the ceiling lights of --camera: give --camera too", field="--site")
        return None
    if method != Method.MCL:
        raise InputError(
            "the ceiling camera is fused into Monte Carlo localization: use --method mcl", field="--camera"
        )
    if site is None:
        raise InputError(
            "--camera needs --site: the site whose ceiling lights the camera sees", field="--site"
        )
    from tourbot.io.images import read_camera_images
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site

    the_site = load_site(site_path(site))
    if not the_site.ceiling_lights:
        raise InputError(
            f"site {the_site.name!r} has no ceiling lights", path=site_path(site), field="ceiling_lights"
        )
    times, images = read_camera_images(camera)
    from tourbot.ceiling.rig import CeilingCamera

    rig = CeilingCamera()
    if images.ndim != 3 or images.shape[1:] != (rig.height, rig.width):
        raise InputError(
            f"images of shape {tuple(images.shape[1:])}; the camera's calibration is for "
            f"{rig.height} rows x {rig.width} columns",
            path=camera,
            field="images",
        )
    return times, images, the_site


class _ImageFeed:
    """The ``--camera`` images fed to MCL in time order, each at the odometry of its own time."""

    def __init__(self, ceiling: tuple[Any, Any, Any], grid: Any, log: Any, seed: int) -> None:
        import numpy as np

        from tourbot.ceiling.likelihood import CeilingSensor
        from tourbot.ceiling.rig import CeilingCamera
        from tourbot.geometry import interpolate_poses

        times, self.images, site = ceiling
        lights = np.array([light.position for light in site.ceiling_lights], dtype=np.float64)
        self.sensor = CeilingSensor(CeilingCamera(), lights, grid, seed=seed)
        scan_t = np.asarray(log.times, dtype=np.float64)
        inside = (times >= scan_t[0]) & (times <= scan_t[-1])
        self.outside = int((~inside).sum())
        self.order = np.flatnonzero(inside)[np.argsort(times[inside], kind="stable")]
        self.times = times
        odom = np.array([s.odom for s in log.scans], dtype=np.float64)
        self.odom = interpolate_poses(scan_t, odom, times)
        self._next = 0
        self.used = 0
        self.resets = 0

    def until(self, t: float, mcl: Any, run: McapRun | None) -> None:
        """Fuse every image taken up to time ``t`` (before the scan of that time); into ``run`` too."""
        while self._next < len(self.order) and self.times[self.order[self._next]] <= t:
            k = self.order[self._next]
            self._next += 1
            if run is not None:
                from tourbot.records import Image

                run.write_image(Image(float(self.times[k]), self.images[k], camera="ceiling"))
            if mcl.last_estimate is None:
                continue  # the first scan comes first
            m = self.sensor.fuse(mcl, self.images[k], self.odom[k])
            self.used += 1
            self.resets += m.reset is not None


def _mcap_run(path: Path | None) -> AbstractContextManager[McapRun | None]:
    """The MCAP recording of ``--mcap`` (nothing without it)."""
    if path is None:
        return nullcontext()
    from tourbot.io.mcap_out import McapRun

    return McapRun(path)


def _record(
    run: McapRun, scan: Scan, odom: tuple[float, float, float], est: LocalizationEstimate, localizer: object
) -> None:
    """One update into the MCAP file: the scan, the odometry used, the estimate, samples and beams."""
    from tourbot.localization.mcl import MonteCarloLocalization

    run.write_scan(scan)
    run.write_odometry(odom, scan.timestamp)
    run.write_estimate(est.pose, est.covariance, odom, scan.timestamp)
    if isinstance(localizer, MonteCarloLocalization):
        run.write_particles(localizer.samples, scan.timestamp)
    if est.updated:
        run.write_beams(scan, est.used_beams)


def _prepare_grid(
    localizer: object, max_range: float, table_cache: Path | None, use_cache: bool, console: Console
) -> None:
    """Build (with a progress bar) or read from the cache the grid's expected-range table, and say so."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    from tourbot.localization.grid_markov import GridMarkovLocalization, default_table_cache

    assert isinstance(localizer, GridMarkovLocalization)
    lat = localizer.lattice
    n_angles = round(2 * math.pi / localizer.config.table_angle_step)
    mbytes = 2 * lat.n_free * n_angles / 1e6
    cache = (table_cache or default_table_cache()) if use_cache else None
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    with Progress(*columns, console=console, transient=True) as progress:
        task = progress.add_task(
            f"expected-range table: {lat.n_free} cells x {n_angles} directions ({mbytes:.0f} MB)",
            total=lat.n_free,
        )
        t0 = time.perf_counter()
        localizer.prepare(
            max_range, progress=lambda done, _total: progress.update(task, completed=done), cache=cache
        )
    console.print(
        f"expected-range table ({lat.n_free} cells x {n_angles} directions, {mbytes:.0f} MB): "
        f"{localizer.table_source} in {time.perf_counter() - t0:.1f} s",
        highlight=False,
    )


class _Localizer(Protocol):
    def reset_global(self) -> None: ...

    def reset_tracking(self, pose: ArrayLike, cov: ArrayLike) -> None: ...

    def update(self, odom_pose: ArrayLike, scan: Scan) -> LocalizationEstimate: ...


def _make_localizer(
    method: Method,
    grid: OccupancyGrid,
    kind: BeamFilter,
    particles: int | None,
    seed: int,
    profile: LocalizationProfile,
) -> _Localizer:
    """The localizer for ``--method`` (imported lazily: numba kernels load only when used)."""
    from dataclasses import replace

    if method == Method.GRID:
        from tourbot.localization.grid_markov import GridMarkovLocalization

        return GridMarkovLocalization(grid, replace(profile.grid, beam_filter=kind))
    from tourbot.localization.mcl import MonteCarloLocalization

    cfg = profile.mcl.with_filter(kind)
    if particles is not None:
        cfg = cfg.with_samples(particles)
        # Ten times the tracking budget to start lost (Nav2 AMCL: 500-2000 samples tracking, the
        # global start as many as allowed), never more than the configured global count.
        glob = cfg.global_
        cfg = replace(cfg, global_=replace(glob, samples=max(particles, min(glob.samples, 10 * particles))))
    return MonteCarloLocalization(grid, cfg, seed=seed)
