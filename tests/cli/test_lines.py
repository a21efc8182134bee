from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from tests.mapping.conftest import building, drive
from tourbot.cli.main import main
from tourbot.io.carmen import write_carmen
from tourbot.io.line_map import read_line_map
from tourbot.io.mapserver import read_map
from tourbot.io.tum import read_tum
from tourbot.site.model import MapSpec


@pytest.fixture(scope="module")
def hall_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    log = drive(building(), n=60)
    log.odometry = []  # the scans carry their odometry poses
    path = tmp_path_factory.mktemp("lines") / "hall.log"
    write_carmen(log, path)
    return path


def test_lines_writes_every_output(
    hall_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = tmp_path / "out"
    out, svg, grid, walls, traj = (d / n for n in ("l.geojson", "l.svg", "map.yaml", "walls.yaml", "p.tum"))
    main(["lines", str(hall_log), "-o", str(out), "--svg", str(svg), "--map", str(grid),
          "--walls", str(walls), "--trajectory", str(traj)])  # fmt: skip
    printed = capsys.readouterr().out
    assert "line map:" in printed
    assert "EM iterations" in printed
    segments = read_line_map(out)
    assert len(segments) >= 4
    doc = json.loads(out.read_text())
    assert doc["type"] == "FeatureCollection"
    assert "<svg" in svg.read_text()
    assert read_map(grid).occupied().sum() > 100
    spec = MapSpec(walls=yaml.safe_load(walls.read_text())["walls"])  # a site's map accepts them
    assert len(spec.walls) == len(segments)
    times, poses = read_tum(traj)
    assert len(times) == 60
    assert np.all(np.isfinite(poses))
    assert not list(out.parent.glob(".partial-*"))


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["-o", "lines.txt"], ".geojson or .svg"),
        (["-o", "lines.geojson", "--iterations", "0"], "--iterations"),
        (["-o", "lines.geojson", "--svg", "x.png"], "--svg"),
    ],
)
def test_lines_bad_options_say_so_in_one_line(
    hall_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], needle: str
) -> None:
    args = [a if not a.endswith((".txt", ".geojson", ".png")) else str(tmp_path / a) for a in args]
    with pytest.raises(SystemExit) as exc:
        main(["lines", str(hall_log), *args])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert needle in err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_lines_missing_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["lines", str(tmp_path / "nope.log"), "-o", str(tmp_path / "l.geojson")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "nope.log" in err
    assert "Traceback" not in err
