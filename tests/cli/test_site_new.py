from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from tests.mapping.conftest import building, drive
from tourbot.cli.main import main
from tourbot.io.carmen import write_carmen
from tourbot.io.line_map import read_line_map
from tourbot.site.model import load_site


def _log(tmp_path: Path, n: int) -> Path:
    log = drive(building(), n=n)
    log.odometry = []
    path = tmp_path / "hall.log"
    write_carmen(log, path)
    return path


def test_site_new_writes_a_valid_site(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "sites" / "hall"
    main(["site", "new", str(_log(tmp_path, 80)), "--name", "hall", "-o", str(out)])
    site = load_site(out / "site.yaml")
    assert site.name == "hall"
    assert site.grid.occupied().sum() > 200
    assert "site hall:" in capsys.readouterr().out
    assert sorted(p.name for p in (tmp_path / "sites").iterdir()) == ["hall"]  # nothing half-made beside
    assert [e.name for e in site.exhibits] == site.tour("highlights").exhibits
    # the line map beside the grid, in the grid's frame: its walls lie on the grid's walls
    walls = read_line_map(out / "lines.geojson")
    assert len(walls) >= 4
    along = np.linspace(0.0, 1.0, 11)[None, :, None]
    points = (walls[:, :1] + along * (walls[:, 1:] - walls[:, :1])).reshape(-1, 2)
    cells = site.grid.world_to_cell(points)
    inside = site.grid.inside(cells)
    assert inside.mean() > 0.95
    to_wall = ndimage.distance_transform_edt(~site.grid.occupied()) * site.grid.resolution
    assert float(np.median(to_wall[cells[inside, 0], cells[inside, 1]])) < 0.15
    assert (out / "lines.svg").read_text().lstrip().startswith("<")
    # the simulator accepts it at once
    main(["simulate", "--site", str(out), "--duration", "3", "--crowd", "empty",
          "--write-log", str(tmp_path / "sim" / "s.log.gz")])  # fmt: skip
    assert (tmp_path / "sim" / "s.log.gz").exists()


def test_too_few_scans_is_one_line_and_no_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "sites" / "tiny"
    with pytest.raises(SystemExit) as exc:
        main(["site", "new", str(_log(tmp_path, 10)), "--name", "tiny", "-o", str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "10 laser scans" in err
    errors = [line for line in err.splitlines() if not line.startswith("warning:")]
    assert len(errors) == 1  # one line (the reader's warnings aside), no traceback
    assert not out.exists()
    assert not (tmp_path / "sites").exists() or not any((tmp_path / "sites").iterdir())


def test_an_existing_site_folder_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "taken"
    out.mkdir()
    (out / "site.yaml").write_text("name: x\n")
    with pytest.raises(SystemExit):
        main(["site", "new", str(_log(tmp_path, 60)), "--name", "x", "-o", str(out)])
    assert "exists already" in capsys.readouterr().err
    assert (out / "site.yaml").read_text() == "name: x\n"
