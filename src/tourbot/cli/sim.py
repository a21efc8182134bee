"""``tourbot simulate``: run the simulator and write its sensor stream as a CARMEN log, with ground truth."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path
from typing import Annotated

import typer

from tourbot.cli._checks import McapOpt

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
        camera: Annotated[
            list[str] | None,
            typer.Option(
                help="Cameras the robot carries and uses (repeat or comma list): 'ceiling' (upward, 1 Hz, "
                "fused into MCL; to LOG.ceiling.npz), 'forward' (obstacle camera, 5 Hz, its vision obstacles "
                "in the navigator's costmap; to LOG.forward.npz).",
            ),
        ] = None,
        mcap: McapOpt = None,
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
        from tourbot.app.simulated import SimulationSettings, camera_names, simulated_runtime
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
        cameras = camera_names(camera or [], field="--camera")
        if mcap is not None:
            from tourbot.io.mcap_out import check_mcap_output

            check_mcap_output(mcap, force=force)
        console = Console()
        the_site = load_site(site_path(site))
        mcl = LocalizationProfile.for_site(site_path(site), config)[0].mcl
        # the robot carries the cameras asked for, and uses them: the ceiling camera inside MCL, the
        # forward camera's obstacle detector beside the laser; the images it took are written
        settings = SimulationSettings(
            crowd=crowd,
            seed=seed,
            mcl=mcl,
            sim=SimConfig(record=True),
        ).carrying(cameras)
        robot = simulated_runtime(the_site, settings, start=start_pose_for(the_site, tour), record=False)
        rt = robot.runtime
        rt.start_tour(tour)
        with Progress(console=console) as progress, ExitStack() as stack:
            if mcap is not None:
                from tourbot.app.ros2_publishing import McapRecorder

                rt.add_sink(stack.enter_context(McapRecorder(mcap, rt)))
            task = progress.add_task("simulating", total=duration)
            while rt.snapshot().time < duration:
                snap = rt.step()
                if snap is None:
                    break
                progress.update(task, completed=min(snap.time, duration))
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
        for name in cameras:
            from tourbot.io.images import write_image_stream

            images = sim.image_history.get(name, [])
            write_image_stream(
                f"{stem}.{name}.npz", [i.timestamp for i in images], [i.pixels for i in images]
            )
            console.print(f"wrote {stem}.{name}.npz ({len(images)} {name} images with their times)")
        console.print(
            f"wrote {write_log} ({len(sim.truth_times)} scans), {stem}.truth.tum, {stem}.people.json"
        )
        if mcap is not None:
            console.print(f"wrote {mcap}: the run as MCAP (ROS 2 messages)")
