"""``tourbot vision``: the map of obstacles the laser cannot see, from a log and its forward images."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    @app.command("vision")
    def vision(
        log: Annotated[
            Path,
            typer.Argument(
                help="CARMEN log with LOG.forward.npz beside it (tourbot simulate --camera forward)."
            ),
        ],
        output: Annotated[
            Path, typer.Option("-o", "--output", help="Vision map (map_server YAML + PGM).")
        ] = Path("vision-map.yaml"),
        site: Annotated[
            str, typer.Option(help="Shipped site name or site file (its map localizes).")
        ] = "fhw",
        picture: Annotated[
            Path | None, typer.Option(help="Picture of the inconsistencies (default: beside the map, .png).")
        ] = None,
        seed: Annotated[int, typer.Option(help="Seed of the localization.")] = 0,
    ) -> None:
        """Replay LOG with Monte Carlo localization on the site's map, pair its forward images, find
        where they disagree with the laser's 2.5D model (Burgard et al., Sec. 3) and write the
        occupancy map of those obstacles, with a picture like the paper's Fig. 3 (image t-1,
        image t, inconsistencies crossed on image t) for the pair with the most detections."""
        import numpy as np
        from rich.console import Console

        from tourbot.errors import InputError
        from tourbot.io import load_log
        from tourbot.io.images import read_image_stream
        from tourbot.io.mapserver import check_map_output, write_map
        from tourbot.localization.mcl import MonteCarloLocalization
        from tourbot.localization.mcl.config import MCLConfig
        from tourbot.records import Image
        from tourbot.runtime.localizers import MCLLocalizer, UpdatePolicy
        from tourbot.runtime.loop import Runtime
        from tourbot.runtime.sources import LogSource
        from tourbot.runtime.vision import VisionObstacleEstimator
        from tourbot.site.default import site_path
        from tourbot.site.model import load_site
        from tourbot.vision.camera import ForwardCamera

        console = Console()
        check_map_output(output)
        stem = str(log).removesuffix(".gz").removesuffix(".log")
        images_path = Path(stem + ".forward.npz")
        if not images_path.is_file():
            raise InputError(
                "no forward images beside the log (tourbot simulate --camera forward)", path=images_path
            )
        times, images = read_image_stream(images_path)
        the_log = load_log(log)
        source = LogSource(the_log, name=str(log))
        the_site = load_site(site_path(site))
        rig = ForwardCamera()
        if images.shape[1:] != (rig.height, rig.width):
            raise InputError(
                f"images are {images.shape[2]}x{images.shape[1]}, "
                f"the forward camera's {rig.width}x{rig.height}",
                path=images_path,
            )
        scans = the_log.scans
        if not scans or scans[0].reference is None:
            raise InputError("the log's first scan has no reference pose to start tracking from", path=log)
        mcl = MonteCarloLocalization(the_site.grid, MCLConfig(), seed=seed)
        mcl.reset_tracking(scans[0].reference)  # the docking station: a known start, as in the simulator
        estimator = VisionObstacleEstimator(the_site.grid, rig)
        runtime = Runtime(
            _WithImages(source, times, images),
            MCLLocalizer(mcl, UpdatePolicy(), seed=seed),
            estimators=[estimator],
        )
        best: tuple[int, object] | None = None
        with console.status("replaying"):
            while runtime.step() is not None:
                if estimator.last is not None and (
                    best is None or len(estimator.last[2].obstacles) > best[0]
                ):
                    best = (len(estimator.last[2].obstacles), estimator.last)
        write_map(estimator.map.grid(), output)
        pic = picture or output.with_suffix(".png")
        if best is not None:
            _figure(pic, best[1])
        cells = int(estimator.map.occupied().sum())
        rate = estimator.pairs / estimator.seconds if estimator.seconds > 0 else float("nan")
        console.print(
            f"wrote {output} ({cells} vision obstacle cells from {estimator.pairs} image pairs, "
            f"{rate:.1f} pairs/s)" + (f" and {pic}" if best is not None else "")
        )
        del np, Image


class _WithImages:
    """A log source with the forward images merged in at their times (odometry: the latest reading)."""

    def __init__(self, source, times, images) -> None:  # type: ignore[no-untyped-def]
        self.source = source
        self.name = source.name
        self._times = times
        self._images = images
        self._k = 0
        self._odom: tuple[float, float, float] | None = None

    @property
    def time(self) -> float:
        return float(self.source.time)

    def poll(self):  # type: ignore[no-untyped-def]
        from tourbot.records import Image, Odometry

        records = self.source.poll()
        if records is None:
            return None
        out = []
        for r in records:
            if isinstance(r, Odometry):
                self._odom = r.pose
            out.append(r)
        while self._k < len(self._times) and self._times[self._k] <= self.source.time + 1e-9:
            out.append(
                Image(float(self._times[self._k]), self._images[self._k], camera="forward", odom=self._odom)
            )
            self._k += 1
        return out


def _figure(path: Path, pair) -> None:  # type: ignore[no-untyped-def]
    """The paper's Fig. 3: image t-1, image t, and image t with the inconsistencies crossed."""
    from tourbot.vision.picture import inconsistency_figure

    inconsistency_figure(path, *pair)
