"""``tourbot objects`` and ``tourbot crowd --objects`` on a short simulated corridor."""

from __future__ import annotations

import copy
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
import yaml

from tourbot.cli.main import main
from tourbot.io.carmen import write_carmen
from tourbot.io.mapserver import write_map
from tourbot.sim.object_scenes import corridor_scene, run_scene


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    root = tmp_path_factory.mktemp("objects")
    scene = corridor_scene(states_deg=(0, 45, 90, 0))
    run = run_scene(replace(scene, drive=[(0.5, 0.0, 0.0), (8.0, 0.7, 0.0)]), seed=0)
    write_carmen(run.log, root / "corridor.log")
    site = scene.model.model_dump(mode="json", exclude={"base_dir"})
    write_map(scene.model.grid, root / "corridor-map.yaml")
    (root / "site.yaml").write_text(yaml.safe_dump(site))
    return {
        "root": root,
        "log": root / "corridor.log",
        "site": root / "site.yaml",
        "data": site,
        "map": root / "corridor-map.yaml",
        "truth": run.truth,
    }


def _error_line(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err
    assert "Traceback" not in err
    return err


def test_objects_writes_states_and_a_picture(files: dict[str, Any], tmp_path: Path) -> None:
    out = tmp_path / "states.csv"
    main(
        [
            "objects",
            str(files["log"]),
            "--site",
            str(files["site"]),
            "--trajectory",
            "reference",
            "-o",
            str(out),
        ]
    )
    lines = out.read_text().splitlines()
    assert lines[0].startswith("time,scan,object,kind,s0")
    rows = [r.split(",") for r in lines[1:]]
    assert len(rows) > 20
    observed = [r for r in rows if r[10] == "observed" and r[2] == "D-2"]
    assert observed
    # D-2 is 45 degrees open
    assert abs(abs(float(observed[-1][4])) - math.radians(45.0)) < math.radians(3.0)
    assert out.with_suffix(".png").stat().st_size > 1000


def test_objects_localizes_with_a_map(files: dict[str, Any], tmp_path: Path) -> None:
    out = tmp_path / "states.csv"
    main(
        [
            "objects",
            str(files["log"]),
            "--site",
            str(files["site"]),
            "--map",
            str(files["map"]),
            "-o",
            str(out),
        ]
    )
    assert len(out.read_text().splitlines()) > 10


def test_impossible_door_is_one_line(
    files: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = copy.deepcopy(files["data"])
    data["doors"][1]["opening_angle"] = 4.0
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    err = _error_line(
        capsys, ["objects", str(files["log"]), "--site", str(bad), "-o", str(tmp_path / "x.csv")]
    )
    assert "bad.yaml" in err
    assert "doors.1" in err
    assert "opening_angle" in err


def test_object_outside_the_map_is_one_line(
    files: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = copy.deepcopy(files["data"])
    data["doors"][2]["hinge"] = [500.0, 3.0]
    bad = tmp_path / "far.yaml"
    bad.write_text(yaml.safe_dump(data))
    err = _error_line(
        capsys, ["objects", str(files["log"]), "--site", str(bad), "-o", str(tmp_path / "x.csv")]
    )
    assert "doors.2.hinge" in err
    assert "outside the map" in err


def test_log_in_another_frame_is_one_line(
    files: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = copy.deepcopy(files["data"])
    for wall in data["map"]["walls"]:
        for p in wall:
            p[1] += 30.0
    for d in data["doors"]:
        d["hinge"][1] += 30.0
    moved = tmp_path / "moved.yaml"
    moved.write_text(yaml.safe_dump(data))
    err = _error_line(
        capsys, ["objects", str(files["log"]), "--site", str(moved), "-o", str(tmp_path / "x.csv")]
    )
    assert "not in the site's frame" in err
    assert "corridor.log" in err


def test_crowd_with_objects_writes_their_truth(files: dict[str, Any], tmp_path: Path) -> None:
    out = tmp_path / "crowded.log"
    main(
        [
            "crowd",
            str(files["log"]),
            "--map",
            str(files["map"]),
            "--objects",
            str(files["site"]),
            "--preset",
            "sparse",
            "-o",
            str(out),
        ]
    )
    assert (tmp_path / "crowded.objects.json").exists()
    assert (tmp_path / "crowded.truth.json").exists()
    states = tmp_path / "states.csv"
    main(["objects", str(out), "--site", str(files["site"]), "--trajectory", "reference", "-o", str(states)])
    header = states.read_text().splitlines()[0]
    assert header.endswith("true0,true1,true2")
