"""``tourbot simulate --camera forward`` writes the forward images; ``tourbot vision LOG`` the map of
vision obstacles and the Fig. 3 picture; bad input in one line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.cli.test_logs import _run
from tourbot.io.images import read_image_stream
from tourbot.io.mapserver import read_map


def _error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err
    assert len(err.splitlines()) == 1
    return err


@pytest.mark.slow
def test_simulate_forward_and_ceiling_then_vision(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "sim.log.gz"
    args = ["simulate", "--tour", "short", "--crowd", "empty", "--duration", "4", "--write-log", str(log)]
    assert _run([*args, "--camera", "forward,ceiling"]) == 0
    times, images = read_image_stream(tmp_path / "sim.forward.npz")
    assert images.shape == (20, 480, 640)
    assert np.allclose(np.diff(times), 0.2)  # 5 Hz
    assert read_image_stream(tmp_path / "sim.ceiling.npz")[1].shape[0] == 4
    out = tmp_path / "vision-map.yaml"
    assert _run(["vision", str(log), "-o", str(out)]) == 0
    grid = read_map(out)
    assert grid.shape[0] > 0
    printed = " ".join(capsys.readouterr().out.split())
    assert "vision obstacle cells" in printed
    if "and" in printed.split("pairs/s)")[-1]:
        with Image.open(out.with_suffix(".png")) as img:
            assert img.size == (3 * 640 + 16, 480)


def test_unknown_camera_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = _run(
        ["simulate", "--duration", "1", "--camera", "sideways", "--write-log", str(tmp_path / "a.log.gz")]
    )
    assert code == 2
    assert "--camera" in _error_line(capsys)


def test_vision_without_images_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "a.log"
    log.write_text("")
    assert _run(["vision", str(log), "-o", str(tmp_path / "m.yaml")]) == 2
    assert "forward images" in _error_line(capsys)
