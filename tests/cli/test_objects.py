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


def test_objects_writes_the_run_as_mcap(files: dict[str, Any], tmp_path: Path) -> None:
    """Every channel decoded back: the log's scans and odometry, MCL's estimate with its spread, TF
    composing to it, the map, and the objects drawn in the states the CSV gives."""
    import numpy as np

    from tests.io.test_mcap_out import _decode, _pose, _tf_pose
    from tourbot.cli.objects import site_shapes
    from tourbot.geometry import compose
    from tourbot.io import load_log
    from tourbot.io.ros2_messages import grid_cells
    from tourbot.site.model import load_site

    out, mcap = tmp_path / "states.csv", tmp_path / "run.mcap"
    main(["objects", str(files["log"]), "--site", str(files["site"]), "-o", str(out), "--mcap", str(mcap)])
    log = load_log(files["log"])
    site = load_site(files["site"])
    shapes = site_shapes(site, files["site"])
    msgs = _decode(mcap)
    assert set(msgs) == {"/map", "/scan", "/odom", "/tf", "/estimate", "/objects"}
    stamps = [round(s.timestamp * 1e9) for s in log.scans]
    assert [s for s, _ in msgs["/scan"]] == stamps == [s for s, _ in msgs["/odom"]]
    ((_, m),) = msgs["/map"]
    assert np.array_equal(m.data, grid_cells(site.grid))
    # MCL's estimate: at (nearly) every scan, near the reference, with a spread
    est_stamps = [s for s, _ in msgs["/estimate"]]
    assert set(est_stamps) <= set(stamps)
    assert len(est_stamps) >= len(stamps) - 1
    est = np.array([_pose(m.pose.pose) for _, m in msgs["/estimate"]])
    ref = log.reference_poses[[stamps.index(s) for s in est_stamps]]
    assert np.hypot(*(est[:, :2] - ref[:, :2]).T).max() < 0.3
    cov = np.array([m.pose.covariance.reshape(6, 6) for _, m in msgs["/estimate"]])
    assert (cov[:, 0, 0] > 0).all()
    assert (cov[:, 5, 5] > 0).all()
    at: dict[tuple[int, str], np.ndarray] = {}
    for stamp, m in msgs["/tf"]:
        for tf in m.transforms:
            at[(stamp, tf.child_frame_id)] = _tf_pose(tf)
    for stamp, e in zip(est_stamps, est, strict=True):
        chain = compose(at[(stamp, "odom")], at[(stamp, "base_link")])
        np.testing.assert_allclose(chain[:2], e[:2], atol=1e-9)
    # the objects: one set per scan that updated any, each object in its latest state (the CSV's)
    rows = [r.split(",") for r in out.read_text().splitlines()[1:]]
    scans = sorted({int(r[1]) for r in rows})
    assert [s for s, _ in msgs["/objects"]] == [stamps[k] for k in scans]
    last: dict[str, list[str]] = {}
    for r in rows:
        last[r[2]] = r
    names = [s.name for s in shapes]
    clear, *markers = msgs["/objects"][-1][1].markers
    assert clear.action == 3
    outlines = [mk for mk in markers if mk.ns == "objects"]
    labels = [mk for mk in markers if mk.ns == "names"]
    assert sorted(names[mk.id] for mk in outlines) == sorted(last) != names  # D-4 never updated: not drawn
    for mk, label in zip(outlines, labels, strict=True):
        shape = shapes[mk.id]
        row = last[shape.name]
        state = [float(v) for v in row[4 : 4 + shape.dim]]
        expected = shape.polygons(np.array([state]))[0]
        pts = np.array([(p.x, p.y) for p in mk.points])
        assert mk.type == 4
        assert mk.header.frame_id == "map"
        np.testing.assert_allclose(pts, np.vstack([expected, expected[:1]]), atol=1e-4)
        rgb = (1.0, 0.55) if row[10] == "observed" else (0.6, 0.6)
        assert (mk.color.r, mk.color.g) == pytest.approx(rgb)
        assert (label.id, label.type, label.text) == (mk.id, 9, shape.name)
    assert any(last[n][10] == "observed" for n in last)


def test_objects_refuses_an_existing_mcap_before_the_work(
    files: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mcap, out = tmp_path / "run.mcap", tmp_path / "x.csv"
    mcap.write_text("kept")
    err = _error_line(
        capsys,
        ["objects", str(files["log"]), "--site", str(files["site"]), "-o", str(out), "--mcap", str(mcap)],
    )
    assert "--mcap" in err
    assert "--force" in err
    assert mcap.read_text() == "kept"
    assert not out.exists()
