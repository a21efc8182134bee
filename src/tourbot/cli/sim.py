"""``tourbot simulate``: run the simulator and write its sensor stream as a CARMEN log, with ground truth."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:
    from types import TracebackType

    from tourbot.app.simulated import SimulatedRobot
    from tourbot.io.mcap_out import McapRun
    from tourbot.runtime.localizers import MCLLocalizer

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    @app.command("simulate")
    def simulate(
        site: str = typer.Option("fhw", help="Shipped site name or site file."),
        tour: str = typer.Option("highlights", help="Tour the robot guides while the log is recorded."),
        crowd: str = typer.Option("sparse", help="Crowd: empty, sparse, peak, or a number of visitors."),
        seed: int = typer.Option(0, help="Seed."),
        duration: float = typer.Option(120.0, help="Simulated seconds."),
        write_log: str = typer.Option(
            "out/sim/sim.log.gz", "--write-log", help="CARMEN log to write (true pose as reference)."
        ),
        config: Annotated[
            Path | None,
            typer.Option(
                "--config",
                help="Localization profile (YAML; default: the site's localization.yaml, else the papers' "
                "values).",
            ),
        ] = None,
        camera: bool = typer.Option(
            False, help="Also render the upward ceiling camera (1 Hz) to LOG.ceiling.npz."
        ),
        mcap: Annotated[
            Path | None,
            typer.Option(
                "--mcap",
                help="Also write the run as MCAP (ROS 2 messages: scans, odometry, TF, map, estimate, "
                "particles) for Foxglove; an existing file is replaced only with --force.",
            ),
        ] = None,
        force: Annotated[bool, typer.Option("--force", help="Replace an existing --mcap file.")] = False,
    ) -> None:
        """Simulate a tour and write the sensor stream as a CARMEN log, plus ground truth beside it.

        Beside LOG: ``.truth.tum`` (the true robot pose per scan) and ``.people.json`` (per scan:
        people's positions, doors' open fractions, furniture poses).
        """
        import json

        import numpy as np
        from rich.console import Console
        from rich.progress import Progress

        from tourbot.app.demo import start_pose_for
        from tourbot.app.simulated import SimulationSettings, simulated_runtime
        from tourbot.errors import InputError
        from tourbot.io.carmen import write_carmen
        from tourbot.io.output import write_text_whole
        from tourbot.io.tum import write_tum
        from tourbot.localization.profile import LocalizationProfile
        from tourbot.sim.simulator import SimConfig
        from tourbot.site.default import site_path
        from tourbot.site.model import load_site

        if not duration > 0:
            raise InputError(f"must be positive (simulated seconds), got {duration}", field="--duration")
        if mcap is not None:
            from tourbot.io.mcap_out import check_mcap_output

            check_mcap_output(mcap, force=force)
        console = Console()
        the_site = load_site(site_path(site))
        mcl = LocalizationProfile.for_site(site_path(site), config)[0].mcl
        settings = SimulationSettings(crowd=crowd, seed=seed, mcl=mcl, sim=SimConfig(record=True))
        robot = simulated_runtime(the_site, settings, start=start_pose_for(the_site, tour), record=False)
        rt = robot.runtime
        rt.start_tour(tour)
        ceiling_sim = None
        frames: tuple[list[float], list[np.ndarray]] = ([], [])
        if camera:
            from tourbot.ceiling.rig import CeilingCamera
            from tourbot.sim.camera import CeilingCameraSim

            ceiling_sim = CeilingCameraSim(the_site, CeilingCamera(), seed=seed)
        with Progress(console=console) as progress, _McapRecorder(mcap, robot) as recorder:
            task = progress.add_task("simulating", total=duration)
            while rt.snapshot().time < duration:
                snap = rt.step()
                if snap is None:
                    break
                recorder.after_step()
                progress.update(task, completed=min(snap.time, duration))
                if ceiling_sim is not None and ceiling_sim.due(snap.time):
                    s = robot.simulator
                    frame = ceiling_sim.frame(snap.time, s.robot.pose, s.people_positions())
                    frames[0].append(frame.time)
                    frames[1].append(frame.image)
        sim = robot.simulator
        log_path = Path(write_log)
        log_path.parent.mkdir(parents=True, exist_ok=True)
        write_carmen(sim.to_robot_log(), log_path)
        stem = str(write_log).removesuffix(".gz").removesuffix(".log")
        write_tum(stem + ".truth.tum", sim.truth_times, sim.truth_poses)
        people = {
            "times": sim.truth_times,
            "positions": [np.round(p, 4).tolist() for p in sim.people_history],
            "doors": [[d.open_fraction for d in doors] for doors, _ in sim.objects_history],
            "furniture": [[(f.x, f.y, f.theta) for f in items] for _, items in sim.objects_history],
        }
        write_text_whole(stem + ".people.json", json.dumps(people))
        if ceiling_sim is not None:
            from tourbot.io.images import write_image_stream

            write_image_stream(stem + ".ceiling.npz", *frames)
            console.print(f"wrote {stem}.ceiling.npz ({len(frames[0])} ceiling images with their times)")
        console.print(
            f"wrote {write_log} ({len(sim.truth_times)} scans), {stem}.truth.tum, {stem}.people.json"
        )
        if mcap is not None:
            console.print(f"wrote {mcap}: the run as MCAP (ROS 2 messages)")


class _McapRecorder:
    """``--mcap``: after each runtime step, the new scans (with the odometry pose each was taken at)
    and any new estimate.

    An estimate is written at the time of the scan it integrated, with that scan's odometry pose
    (for the map -> odom transform) and the localizer's samples. The beams are not written: the
    runtime localizer integrates a decimated scan and does not hand out which beams it used.
    """

    def __init__(self, path: Path | None, robot: SimulatedRobot) -> None:
        self.path = path
        self.robot = robot
        self.run: McapRun | None = None
        self.localizer: MCLLocalizer | None = None
        self._seen = 0
        self._updates = 0

    def __enter__(self) -> _McapRecorder:
        from tourbot.io.mcap_out import McapRun
        from tourbot.runtime.localizers import MCLLocalizer

        if self.path is not None:
            localizer = self.robot.runtime.localizer
            if not isinstance(localizer, MCLLocalizer):
                raise TypeError(f"--mcap needs the simulator's MCL localizer, got {type(localizer).__name__}")
            self.localizer = localizer
            self.run = McapRun(self.path).__enter__()
            self.run.write_map(localizer.mcl.grid, self.robot.simulator.time)
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None
    ) -> None:
        if self.run is not None:
            self.run.__exit__(kind, value, tb)

    def after_step(self) -> None:
        from tourbot.records import Scan

        run, localizer = self.run, self.localizer
        if run is None or localizer is None:
            return
        records = self.robot.simulator.records
        for r in records[self._seen :]:
            if isinstance(r, Scan) and r.odom is not None:
                run.write_scan(r)
                run.write_odometry(r.odom, r.timestamp)
        self._seen = len(records)
        last = localizer.last_update
        est = localizer.mcl.last_estimate
        if localizer.updates != self._updates and last is not None and est is not None:
            self._updates = localizer.updates
            stamp, odom = last
            run.write_estimate(est.pose, est.covariance, odom, stamp)
            run.write_particles(localizer.mcl.samples, stamp)
