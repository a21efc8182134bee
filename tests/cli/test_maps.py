"""``tourbot map from-poses`` and ``tourbot show``: from a log to a map and a picture in two commands."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.cli.test_logs import _run
from tourbot.io.mapserver import read_map
from tourbot.io.tum import write_tum
from tourbot.records import RobotLog


def test_from_log_to_map_and_picture_in_two_commands(
    fhw_log_path: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    real_log: Callable[[str], RobotLog],
) -> None:
    map_yaml = tmp_path / "maps" / "fhw.yaml"
    assert _run(["map", "from-poses", str(fhw_log_path), "-o", str(map_yaml), "--no-quality"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "wrote" in out
    grid = read_map(map_yaml)
    assert grid.resolution == 0.05
    assert grid.occupied().sum() > 5000

    traj = tmp_path / "shifted.txt"
    log = real_log("fhw")
    write_tum(traj, log.times, log.reference_poses + np.array([1.0, 0.0, 0.0]))
    picture = tmp_path / "fhw.png"
    args = ["show", str(fhw_log_path), "--map", str(map_yaml), "--trajectory", str(traj), "--odometry"]
    assert _run([*args, "-o", str(picture)]) == 0
    with Image.open(picture) as img:
        width, height = img.size
        pixels = np.asarray(img.convert("RGB"))
    assert width > 500
    assert height > 500
    # the reference path is drawn in its blue, the trajectory in orange
    assert (np.abs(pixels.astype(int) - [0, 114, 178]).sum(axis=2) < 40).sum() > 500
    assert (np.abs(pixels.astype(int) - [213, 94, 0]).sum(axis=2) < 40).sum() > 500


def test_map_needs_reference_poses(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = shared_data / "leg_tracker" / "positive_1.bag"
    assert _run(["map", "from-poses", str(bag), "-o", str(tmp_path / "m.yaml")]) == 2
    assert "no reference poses" in capsys.readouterr().err


def test_map_info_and_bad_map(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "m.yaml"
    bad.write_text("image: m.pgm\nresolution: 0.05\norigin: [0, 0]\n")
    assert _run(["map", "info", str(bad)]) == 2
    assert "origin must be [x, y, yaw]" in capsys.readouterr().err


def test_map_info_of_a_folder_says_so(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _run(["map", "info", str(tmp_path)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"{tmp_path}: a folder, not a map YAML file" in err
    assert "Traceback" not in err


def test_show_refuses_an_unknown_picture_format_first(
    tmp_path: Path, fhw_log_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "fhw.xyz"
    assert _run(["show", str(fhw_log_path), "-o", str(out)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"{out} (field --output): cannot write a .xyz picture" in err
    assert ".png" in err
    assert "Traceback" not in err


def test_log_tum_creates_the_output_folder(tmp_path: Path, fhw_log_path: Path) -> None:
    out = tmp_path / "new" / "deeper" / "ref.txt"
    assert _run(["log", "tum", str(fhw_log_path), "-o", str(out)]) == 0
    assert len(out.read_text().splitlines()) == 489  # header + one pose per scan


def test_map_modes_from_the_command_line(
    fhw_log_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["map", "from-poses", str(fhw_log_path), "--no-quality"]
    assert _run([*base, "-o", str(tmp_path / "t.yaml")]) == 0
    assert _run([*base, "-o", str(tmp_path / "r.yaml"), "--map-mode", "raw"]) == 0
    capsys.readouterr()
    trinary, raw = read_map(tmp_path / "t.yaml"), read_map(tmp_path / "r.yaml")
    np.testing.assert_array_equal(trinary.occupied(), raw.occupied())
    np.testing.assert_array_equal(trinary.free(), raw.free())
    # what trinary called unknown, raw partly keeps as known occupancy between the thresholds
    between = ~(raw.occupied() | raw.free() | raw.unknown())
    assert between.sum() > 0
    assert _run(["map", "info", str(tmp_path / "r.yaml")]) == 0
    assert f"between the thresholds {int(between.sum())}" in capsys.readouterr().out
    assert _run([*base, "-o", str(tmp_path / "x.yaml"), "--map-mode", "gray"]) == 2
    err = capsys.readouterr().err
    assert "--map-mode" in err
    assert "trinary, scale, raw" in err
    assert not (tmp_path / "x.yaml").exists()


def test_show_names_the_picture_it_wrote(
    fhw_log_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "part.log"
    from tourbot.io import load_log, write_carmen

    full = load_log(fhw_log_path)
    full.scans = full.scans[:20]
    full.odometry = []
    write_carmen(full, log)
    assert _run(["show", str(log), "-o", str(tmp_path / "picture")]) == 0
    assert f"wrote {tmp_path / 'picture.png'}" in capsys.readouterr().out
    assert (tmp_path / "picture.png").is_file()
    assert _run(["show", str(log), "-o", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err
