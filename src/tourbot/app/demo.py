"""Running a simulated tour with a live terminal view; shared by ``tourbot demo`` and ``tourbot simulate``."""

from __future__ import annotations

import json
import math
import time
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path

from rich.console import Console
from rich.live import Live
from rich.table import Table

from tourbot.app.ros2_publishing import McapRecorder, RunPublisher
from tourbot.app.simulated import SimulatedRobot, SimulationSettings, simulated_runtime
from tourbot.errors import TourbotError
from tourbot.io.output import write_text_whole
from tourbot.localization.mcl.config import MCLConfig
from tourbot.site.default import site_path
from tourbot.site.model import Site, load_site
from tourbot.snapshot import NavMode, StateSnapshot

__all__ = ["TerminalView", "run_tour", "start_pose_for"]


class TerminalView:
    """A sink showing the tour's progress in the terminal, refreshed a few times a second."""

    def __init__(self, live: Live, title: str, every: float = 0.25) -> None:
        self.live = live
        self.title = title
        self.every = every
        self._last = 0.0

    def on_snapshot(self, s: StateSnapshot) -> None:
        now = time.perf_counter()
        if now - self._last < self.every and s.navigation.mode != NavMode.FINISHED:
            return
        self._last = now
        self.live.update(self.render(s))

    def render(self, s: StateSnapshot) -> Table:
        nav = s.navigation
        table = Table(title=self.title, show_header=False, min_width=60)
        table.add_column("what", style="bold")
        table.add_column("value")
        table.add_row("time", f"{s.time:7.1f} s simulated   speed-up {s.realtime_factor:5.1f}x")
        exhibit = nav.current_exhibit or "-"
        table.add_row("exhibit", f"{exhibit}  ({len(nav.visited)}/{nav.exhibits_total} visited)")
        table.add_row("doing", f"{nav.mode.value}  {nav.message}")
        table.add_row("blocked", f"now {nav.blocked_time:5.1f} s   total {nav.total_blocked_time:6.1f} s")
        if s.truth is not None:
            x, y, _ = s.truth.pose
            near = sum(1 for p in s.truth.people if math.hypot(p.x - x, p.y - y) < 2.0)
            table.add_row("people", f"{near} within 2 m, {len(s.truth.people)} in the museum")
            table.add_row("collisions", str(s.truth.collisions))
        err = s.position_error
        std = s.pose.position_std if s.pose is not None else math.nan
        table.add_row(
            "localization", f"error {100 * err:5.1f} cm   std {100 * std:5.1f} cm" if err is not None else "-"
        )
        return table

    def close(self) -> None:
        pass


def start_pose_for(site: Site, tour: str) -> tuple[float, float, float]:
    """Where the robot waits before a tour: 1 m behind the first exhibit's viewing pose, if free."""
    first = site.exhibit(site.tour(tour).exhibits[0]).viewing_pose
    x, y, th = first
    from tourbot.navigation.planner import CostMap

    cm = CostMap(site.grid)
    for back in (1.0, 0.7, 0.4, 0.0):
        cand = (x - back * math.cos(th), y - back * math.sin(th), th)
        if cm.traversable(cand):
            return cand
    return first


def run_tour(
    *,
    site: str,
    tour: str,
    crowd: str,
    seed: int,
    duration: float,
    speedup: float,
    mcl: MCLConfig,
    dwell_scale: float,
    out: Path,
    animation: bool,
    mcap: Path | None = None,
    foxglove: int | None = None,
    console: Console | None = None,
) -> SimulatedRobot:
    console = console or Console()
    the_site = load_site(site_path(site))
    the_site.tour(tour)  # a clear error before anything starts
    settings = SimulationSettings(crowd=crowd, seed=seed, mcl=mcl, speedup=speedup or None, objects=True)
    settings = replace(settings, navigation=replace(settings.navigation, dwell_scale=dwell_scale))
    t0 = time.perf_counter()
    with console.status("building the simulated museum (first run compiles the kernels)..."):
        robot = simulated_runtime(the_site, settings, start=start_pose_for(the_site, tour))
    console.print(
        f"set up in {time.perf_counter() - t0:.1f} s: site {the_site.name}, tour {tour}, crowd {crowd}"
    )
    rt = robot.runtime
    rt.start_tour(tour)
    title = f"tourbot demo: {the_site.name} / {tour} / crowd {crowd} / seed {seed}"
    with Live(console=console, refresh_per_second=4, transient=False) as live, ExitStack() as stack:
        rt.add_sink(TerminalView(live, title))
        if mcap is not None:
            rt.add_sink(stack.enter_context(McapRecorder(mcap, rt)))
        if foxglove is not None:
            from tourbot.io.foxglove_live import FoxgloveLive

            live_view = stack.enter_context(FoxgloveLive(foxglove))
            console.print(f"foxglove: ws://127.0.0.1:{live_view.port} (open it in Foxglove)")
            rt.add_sink(RunPublisher(live_view, rt))
        final = rt.run(
            max_time=duration,
            until=lambda s: s.navigation.mode in (NavMode.FINISHED, NavMode.FAILED),
        )
    wall = time.perf_counter() - t0
    metrics = robot.metrics.metrics
    out.mkdir(parents=True, exist_ok=True)
    summary = {
        "site": the_site.name,
        "tour": tour,
        "crowd": crowd,
        "seed": seed,
        "wall_seconds": wall,
        "realtime_factor": final.realtime_factor,
        **metrics.as_dict(),
        "skipped": [
            e
            for e in the_site.tour(tour).exhibits
            if e not in metrics.visited and final.navigation.mode == NavMode.FINISHED
        ],
    }
    write_text_whole(out / "summary.json", json.dumps(summary, indent=2, default=str) + "\n")
    if robot.recorder is not None:
        robot.recorder.path = out / "recording.jsonl.gz"
        robot.recorder.close()
        console.print(f"recording: {robot.recorder.path}")
    if animation and robot.recorder is not None and robot.recorder.snapshots:
        from tourbot.runtime.animation import animate

        with console.status("drawing the animation..."):
            gif = animate(
                robot.recorder.snapshots,
                the_site.grid,
                out / "tour.gif",
                title=f"{the_site.name} {tour}",
                exhibits=[(e.name, e.position[0], e.position[1]) for e in the_site.exhibits],
            )
        console.print(f"animation: {gif}")
    console.print(f"summary: {out / 'summary.json'}")
    if mcap is not None:
        console.print(f"mcap: {mcap} (the run as ROS 2 messages)")
    verdict = "completed" if metrics.success else "NOT completed"
    console.print(
        f"tour {verdict}: {len(metrics.visited)}/{metrics.exhibits_total} exhibits "
        f"in {metrics.duration:.0f} s, "
        f"{metrics.collisions} collisions, blocked {metrics.total_blocked_time:.0f} s, "
        f"localization within 15 cm {100 * metrics.fraction_within(0.15):.1f} % of the time"
    )
    if final.navigation.mode == NavMode.FAILED:
        raise TourbotError(f"the tour failed: {final.navigation.message}")
    return robot
