"""``tourbot ceiling``: global localization from one upward fisheye image (Gamallo et al.)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    ceiling = typer.Typer(
        help="Localization from the ceiling lights (upward fisheye camera).", no_args_is_help=True
    )
    app.add_typer(ceiling, name="ceiling")

    @ceiling.command("locate")
    def locate(
        image: Annotated[Path, typer.Argument(help="The upward camera's image (8-bit, PNG/JPEG).")],
        site: Annotated[
            str, typer.Option(help="Shipped site name or site file (needs ceiling_lights).")
        ] = "domus",
        camera: Annotated[
            Path | None, typer.Option(help="Camera calibration YAML (default: the simulator's camera).")
        ] = None,
        picture: Annotated[
            Path, typer.Option(help="Picture of the detected and the projected lights.")
        ] = Path("out/ceiling/locate.png"),
        seed: Annotated[int, typer.Option(help="Seed of the particle minimization.")] = 0,
    ) -> None:
        """The pose hypotheses of IMAGE, best first, and a picture: detected lights (red circles) and
        the lights projected from the best pose (green crosses)."""
        import numpy as np
        from rich.console import Console

        from tourbot.ceiling.detection import detect_lights
        from tourbot.ceiling.minimize import CeilingLocalizer
        from tourbot.ceiling.rig import CeilingCamera, load_camera
        from tourbot.errors import InputError
        from tourbot.io.images import read_gray_image
        from tourbot.io.output import check_output
        from tourbot.site.default import site_path
        from tourbot.site.model import load_site

        check_output(picture, "--picture")
        path = site_path(site)
        the_site = load_site(path)
        if not the_site.ceiling_lights:
            raise InputError("the site has no ceiling lights", path=path, field="ceiling_lights")
        rig = load_camera(camera) if camera is not None else CeilingCamera()
        img = read_gray_image(image)
        rig.check_image(img.shape, path=image)
        lights = np.array([light.position for light in the_site.ceiling_lights])
        det = detect_lights(img, rig)
        result = CeilingLocalizer(rig, lights, the_site.grid).locate(
            det.centroids, np.random.default_rng(seed)
        )
        console = Console()
        console.print(f"{len(det)} lights detected ({det.rejected} blobs rejected at the rim or border)")
        if not result.hypotheses:
            console.print("no pose: no light could be associated")
        for k, h in enumerate(result.hypotheses):
            console.print(
                f"hypothesis {k + 1}: x {h.pose[0]:.3f} m, y {h.pose[1]:.3f} m, "
                f"heading {np.degrees(h.pose[2]):.2f} deg, merit {h.merit:.2f} px, {h.matched} lights"
            )
        if result.ambiguous:
            console.print("ambiguous: the ceiling looks alike from these poses")
        _picture(picture, img, rig, lights, det.centroids, result.best.pose if result.best else None)
        console.print(f"wrote {picture}")


def _picture(path: Path, img, rig, lights, detected, pose) -> None:  # type: ignore[no-untyped-def]
    import cv2
    import numpy as np

    from tourbot.io.images import write_png

    out = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    for u, v in detected:
        cv2.circle(out, (round(u), round(v)), 7, (0, 0, 255), 1, cv2.LINE_AA)
    if pose is not None:
        uv, seen = rig.project_lights(np.array([pose]), lights)
        for u, v in uv[0][seen[0]]:
            cv2.drawMarker(out, (round(u), round(v)), (0, 255, 0), cv2.MARKER_CROSS, 12, 1)
    write_png(path, out)
