"""``tourbot ceiling locate``: hypotheses and a picture from one image; bad input in one line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.cli.test_logs import _run
from tourbot.ceiling.rig import CeilingCamera
from tourbot.io.images import write_png
from tourbot.sim.camera import CeilingCameraSim
from tourbot.site.default import site_path
from tourbot.site.model import load_site


@pytest.fixture(scope="module")
def domus_image(tmp_path_factory: pytest.TempPathFactory) -> Path:
    site = load_site(site_path("domus"))
    path = tmp_path_factory.mktemp("ceiling") / "frame.png"
    write_png(path, CeilingCameraSim(site, CeilingCamera(), seed=0).frame(0.0, (6.0, -7.0, 0.5)).image)
    return path


def test_locate_prints_the_pose_and_draws_the_lights(
    domus_image: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    picture = tmp_path / "out" / "locate.png"
    assert _run(["ceiling", "locate", str(domus_image), "--site", "domus", "--picture", str(picture)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "hypothesis 1: x 5.9" in out or "hypothesis 1: x 6.0" in out
    assert "y -7.0" in out or "y -6.9" in out
    with Image.open(picture) as img:
        rgb = np.asarray(img.convert("RGB"))
    assert rgb.shape == (480, 640, 3)
    red = (rgb[..., 0] > 200) & (rgb[..., 1] < 50) & (rgb[..., 2] < 50)
    green = (rgb[..., 1] > 200) & (rgb[..., 2] < 50) & (rgb[..., 0] < 50)
    assert red.sum() > 50
    assert green.sum() > 50


def _error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err
    assert len(err.splitlines()) == 1
    return err


def test_wrong_image_size_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    small = tmp_path / "small.png"
    write_png(small, np.zeros((240, 320), dtype=np.uint8))
    assert _run(["ceiling", "locate", str(small), "--picture", str(tmp_path / "p.png")]) == 2
    err = _error_line(capsys)
    assert "small.png" in err
    assert "image.size" in err


def test_calibration_not_fitting_the_image_is_one_line(
    domus_image: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cam = tmp_path / "cam.yaml"
    cam.write_text("model: pajdla-bakstein\nu0: 1500\nv0: 240\n")
    assert (
        _run(
            [
                "ceiling",
                "locate",
                str(domus_image),
                "--camera",
                str(cam),
                "--picture",
                str(tmp_path / "p.png"),
            ]
        )
        == 2
    )
    err = _error_line(capsys)
    assert "cam.yaml" in err
    assert "field model" in err


def test_site_without_lights_is_one_line(
    domus_image: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    site = tmp_path / "bare.yaml"
    site.write_text("name: bare\nmap:\n  walls:\n  - [[0, 0], [5, 0], [5, 5]]\n")
    assert (
        _run(
            ["ceiling", "locate", str(domus_image), "--site", str(site), "--picture", str(tmp_path / "p.png")]
        )
        == 2
    )
    err = _error_line(capsys)
    assert "bare.yaml" in err
    assert "ceiling_lights" in err


def test_missing_image_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _run(["ceiling", "locate", str(tmp_path / "none.png"), "--picture", str(tmp_path / "p.png")]) == 2
    assert "none.png" in _error_line(capsys)


def test_simulate_writes_a_ceiling_image_stream(tmp_path: Path) -> None:
    from tourbot.ceiling.detection import detect_lights
    from tourbot.io.images import read_image_stream

    log = tmp_path / "sim.log.gz"
    args = [
        "simulate",
        "--site",
        "domus",
        "--tour",
        "hall",
        "--duration",
        "3",
        "--camera",
        "ceiling",
        "--write-log",
        str(log),
    ]
    assert _run(args) == 0
    times, images = read_image_stream(tmp_path / "sim.ceiling.npz")
    assert images.shape == (3, 480, 640)
    assert np.allclose(np.diff(times), 1.0)  # 1 Hz
    assert len(detect_lights(images[0], CeilingCamera())) >= 3
