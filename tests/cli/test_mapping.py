from __future__ import annotations

import contextlib
import math
from pathlib import Path

import numpy as np
import pytest

from tests.mapping.conftest import building, drive
from tourbot.cli.main import main
from tourbot.io.carmen import write_carmen
from tourbot.io.mapserver import read_map
from tourbot.io.tum import read_tum


def test_slam_writes_map_and_trajectory(tmp_path: Path) -> None:
    log = drive(building(), n=30)
    log.odometry = []  # the scans carry their odometry poses
    path = tmp_path / "hall.log"
    write_carmen(log, path)
    out = tmp_path / "out" / "map.yaml"
    traj = tmp_path / "out" / "path.tum"
    main(["slam", str(path), "-o", str(out), "--trajectory", str(traj)])
    grid = read_map(out)
    assert grid.occupied().sum() > 100
    times, poses = read_tum(traj)
    assert len(times) == 30
    assert np.all(np.isfinite(poses))


def test_slam_with_people_filter(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = drive(building(), n=20)
    log.odometry = []
    path = tmp_path / "hall.log"
    write_carmen(log, path)
    out = tmp_path / "map.yaml"
    main(["slam", str(path), "-o", str(out), "--people-filter"])
    assert read_map(out).occupied().sum() > 100
    assert "beams left out as people" in capsys.readouterr().out


def test_slam_missing_log_is_one_clear_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["slam", str(tmp_path / "nope.log"), "-o", str(tmp_path / "m.yaml")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "nope.log" in err
    assert "Traceback" not in err


@pytest.mark.parametrize("mode", ["paper", "checked"])
def test_slam_with_a_people_filter_mode(tmp_path: Path, mode: str) -> None:
    log = drive(building(), n=12)
    log.odometry = []
    path = tmp_path / "hall.log"
    write_carmen(log, path)
    out = tmp_path / "map.yaml"
    main(["slam", str(path), "-o", str(out), "--people-filter", "--people-mode", mode])
    assert read_map(out).occupied().sum() > 100


def test_slam_unknown_people_mode_is_one_clear_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = drive(building(), n=3)
    log.odometry = []
    path = tmp_path / "hall.log"
    write_carmen(log, path)
    with pytest.raises(SystemExit) as exc:
        main(["slam", str(path), "-o", str(tmp_path / "m.yaml"), "--people-filter", "--people-mode", "magic"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--people-mode" in err
    assert "Traceback" not in err


def test_slam_refuses_a_bad_map_name_before_mapping(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from tourbot.mapping.incremental import IncrementalMapper

    log = drive(building(), n=5)
    path = tmp_path / "hall.log"
    write_carmen(log, path)

    def never(*_args: object, **_kwargs: object) -> None:
        raise AssertionError("mapped although the output name is wrong")

    monkeypatch.setattr(IncrementalMapper, "add_scan", never)
    with pytest.raises(SystemExit) as exc:
        main(["slam", str(path), "-o", str(tmp_path / "map.pgm")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "map.pgm" in err
    assert "must end in .yaml" in err


def test_slam_without_odometry_names_the_log_before_mapping(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = shared_data / "leg_tracker" / "positive_1.bag"
    with pytest.raises(SystemExit) as exc:
        main(["slam", str(bag), "-o", str(tmp_path / "m.yaml")])
    assert exc.value.code == 2
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(lines) == 1
    assert "positive_1.bag: 400 of 400 scans have no odometry pose" in lines[0]
    assert not (tmp_path / "m.yaml").exists()


def test_slam_writes_a_raw_map(tmp_path: Path) -> None:
    log = drive(building(), n=10)
    log.odometry = []
    path = tmp_path / "hall.log"
    write_carmen(log, path)
    out = tmp_path / "map.yaml"
    main(["slam", str(path), "-o", str(out), "--map-mode", "raw"])
    assert (tmp_path / "map.pgm").exists()
    grid = read_map(out)
    assert grid.occupied().sum() > 50


def test_slam_people_filter_defaults_to_the_filter_s_own_default(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """One default whatever the entry point: the CLI's is the dataclass's."""
    from tourbot.mapping.people_filter import DEFAULT_MODE, PeopleFilterParams

    assert PeopleFilterParams.mode(DEFAULT_MODE) == PeopleFilterParams()
    monkeypatch.setenv("COLUMNS", "400")
    with contextlib.suppress(SystemExit):  # click ends --help with exit status 0
        main(["slam", "--help"])
    assert f"[default: {DEFAULT_MODE}]" in capsys.readouterr().out


def test_slam_people_filter_uses_the_given_leg_model(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from dataclasses import replace

    from tourbot.people.leg_classifier import LegModel, default_model
    from tourbot.people.sjpdaf import PeopleTracker

    shipped = default_model()
    assert shipped is not None
    mine = replace(shipped, bias=shipped.bias - 5.0, trained_on="mine")
    mine.save(tmp_path / "mine.json")
    seen: list[LegModel | None] = []
    update = PeopleTracker.update

    def recording(self: PeopleTracker, *args: object, **kwargs: object) -> object:
        seen.append(self.config.legs.model)
        return update(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(PeopleTracker, "update", recording)
    log = drive(building(), n=5)
    log.odometry = []
    path = tmp_path / "hall.log"
    write_carmen(log, path)
    main(
        [
            "slam",
            str(path),
            "-o",
            str(tmp_path / "map.yaml"),
            "--people-filter",
            "--leg-model",
            str(tmp_path / "mine.json"),
        ]
    )
    assert seen == [mine] * 5
    seen.clear()
    main(["slam", str(path), "-o", str(tmp_path / "map.yaml"), "--people-filter"])
    assert seen == [shipped] * 5


@pytest.mark.parametrize("people_filter", [True, False])
def test_slam_bad_leg_model_is_one_clear_line_before_mapping(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], people_filter: bool
) -> None:
    model = tmp_path / "model.json"
    model.write_text('{"features": ["width"]}')
    out = tmp_path / "map.yaml"
    args = ["slam", str(tmp_path / "nope.log"), "-o", str(out), "--leg-model", str(model)]
    with pytest.raises(SystemExit) as exc:
        main([*args, "--people-filter"] if people_filter else args)
    assert exc.value.code == 2
    err = " ".join(capsys.readouterr().err.split())
    expected = "(field features)" if people_filter else "--leg-model is used only with --people-filter"
    assert expected in err
    assert "nope.log" not in err  # refused before the log is read
    assert not out.exists()


def test_slam_progress_lines_and_partial_map_on_ctrl_c(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import tourbot.io.progress
    from tourbot.mapping.incremental import IncrementalMapper

    monkeypatch.setattr(tourbot.io.progress, "LINE_EVERY", 0.0)
    log = drive(building(), n=20)
    log.odometry = []
    path = tmp_path / "hall.log"
    write_carmen(log, path)
    real = IncrementalMapper.add_scan
    calls = {"n": 0}

    def interrupted(self: IncrementalMapper, *args: object, **kwargs: object) -> object:
        calls["n"] += 1
        if calls["n"] > 12:
            raise KeyboardInterrupt
        return real(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(IncrementalMapper, "add_scan", interrupted)
    out, traj = tmp_path / "map.yaml", tmp_path / "path.tum"
    with pytest.raises(SystemExit) as exc:
        main(["slam", str(path), "-o", str(out), "--trajectory", str(traj), "--keep-partial"])
    assert exc.value.code == 130
    err = capsys.readouterr().err
    assert "mapping hall.log: 12/20 scans" in err
    assert "mapping hall.log: stopped at 12/20 scans" in err
    assert read_map(out).occupied().sum() > 50
    times, _poses = read_tum(traj)
    assert len(times) == 12


def test_slam_refuses_an_odometry_that_does_not_move(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from dataclasses import replace

    log = drive(building(), n=20)
    log.odometry = []
    log.scans = [replace(s, odom=(1.0, 2.0, 0.5)) for s in log.scans]
    path = tmp_path / "still.log"
    write_carmen(log, path)
    with pytest.raises(SystemExit) as exc:
        main(["slam", str(path), "-o", str(tmp_path / "m.yaml")])
    assert exc.value.code == 2
    assert "the odometry does not move" in capsys.readouterr().err
    assert not (tmp_path / "m.yaml").exists()
    main(["slam", str(path), "-o", str(tmp_path / "m.yaml"), "--force"])
    assert (tmp_path / "m.yaml").exists()


def test_slam_refuses_four_odometry_readings_for_hundreds_of_scans(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The FHW log with all but 4 real odometry readings removed: refused before mapping, one line."""
    import gzip

    with gzip.open(shared_data / "carmen" / "fhw-corrected.log.gz", "rt") as f:
        lines = f.read().splitlines()
    real = [
        k for k, line in enumerate(lines) if line.startswith("ODOM") and not lines[k - 1].startswith("FLASER")
    ]
    keep = set(real[:: len(real) // 4][:4])
    variant = tmp_path / "sparse.log"
    variant.write_text("\n".join(ln for k, ln in enumerate(lines) if k not in set(real) - keep) + "\n")
    with pytest.raises(SystemExit) as exc:
        main(["slam", str(variant), "-o", str(tmp_path / "m.yaml")])
    assert exc.value.code == 2
    (error,) = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("error:")]
    assert "only 4 odometry readings for 488 scans" in error
    assert not (tmp_path / "m.yaml").exists()


@pytest.mark.parametrize("flag", ["--loop-closure", "--no-loop-closure"])
def test_slam_with_and_without_loop_closure(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], flag: str
) -> None:
    log = drive(building(), n=60)
    log.odometry = []
    path = tmp_path / "hall.log"
    write_carmen(log, path)
    out = tmp_path / "map.yaml"
    main(["slam", str(path), "-o", str(out), flag])
    assert read_map(out).occupied().sum() > 100
    said = capsys.readouterr().out
    assert ("loop closures:" in said) == (flag == "--loop-closure")


def test_slam_writes_the_run_as_mcap(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Every channel decoded back: the scans and odometry of the log, the SLAM pose after each scan
    as the estimate (the trajectory written), TF composing to it, the map as it grew and finished."""
    from tests.io.test_mcap_out import _decode, _pose, _tf_pose, _wrap
    from tourbot.geometry import compose
    from tourbot.io import load_log
    from tourbot.io.ros2_messages import grid_cells
    from tourbot.mapping.incremental import IncrementalMapper

    log = drive(building(), n=25)
    log.odometry = []
    path = tmp_path / "hall.log"
    write_carmen(log, path)
    out, traj, mcap = tmp_path / "map.yaml", tmp_path / "path.tum", tmp_path / "run.mcap"
    args = ["slam", str(path), "-o", str(out), "--trajectory", str(traj), "--no-loop-closure", "--mcap"]
    main([*args, str(mcap), "--mcap-map-every", "10"])
    assert str(mcap) in capsys.readouterr().out
    read = load_log(path)
    msgs = _decode(mcap)
    assert set(msgs) == {"/scan", "/odom", "/tf", "/estimate", "/map"}  # no tracker: no /people
    stamps = [round(s.timestamp * 1e9) for s in read.scans]
    assert [s for s, _ in msgs["/scan"]] == stamps == [s for s, _ in msgs["/odom"]]
    for scan, (_, m) in zip(read.scans, msgs["/scan"], strict=True):
        np.testing.assert_array_equal(m.ranges, scan.ranges.astype(np.float32))
    odom = np.array([_pose(m.pose.pose) for _, m in msgs["/odom"]])
    np.testing.assert_allclose(odom[:, :2], read.odom_poses[:, :2], atol=1e-9)
    # the estimate is the SLAM pose of each scan: the trajectory written (no loops: not changed after)
    _, poses = read_tum(traj)
    assert [s for s, _ in msgs["/estimate"]] == stamps
    est = np.array([_pose(m.pose.pose) for _, m in msgs["/estimate"]])
    np.testing.assert_allclose(est[:, :2], poses[:, :2], atol=1e-4)
    np.testing.assert_allclose(_wrap(est[:, 2] - poses[:, 2]), 0.0, atol=1e-4)
    assert all((m.pose.covariance == 0).all() for _, m in msgs["/estimate"])  # SLAM gives none
    assert not np.allclose(est[:, :2], odom[:, :2], atol=0.05)  # scan matching corrected the odometry
    tree: dict[tuple[str, str], list[np.ndarray]] = {}
    for _, m in msgs["/tf"]:
        for tf in m.transforms:
            tree.setdefault((tf.header.frame_id, tf.child_frame_id), []).append(_tf_pose(tf))
    assert set(tree) == {("map", "odom"), ("odom", "base_link"), ("base_link", "laser")}
    chain = compose(np.array(tree[("map", "odom")]), np.array(tree[("odom", "base_link")]))
    np.testing.assert_allclose(chain[:, :2], est[:, :2], atol=1e-9)
    # the map after scans 10 and 20 (the scan matcher's so far), then the finished one at the end
    assert [s for s, _ in msgs["/map"]] == [stamps[9], stamps[19], stamps[-1]]
    mapper = IncrementalMapper()
    for k, scan in enumerate(read.scans):
        mapper.add_scan(scan)
        if k + 1 in (10, 25):
            m = dict(msgs["/map"])[stamps[k]]
            grid = mapper.grid()
            assert (m.info.height, m.info.width) == grid.prob.shape
            np.testing.assert_allclose(_pose(m.info.origin), grid.origin, atol=1e-12)
            assert np.array_equal(m.data, grid_cells(grid))
    written = read_map(out)  # the map file is the finished map of the MCAP file
    assert np.array_equal(written.occupied(), grid.occupied())
    assert grid.occupied().sum() > 100


def test_slam_with_the_people_filter_writes_the_people_as_mcap(tmp_path: Path) -> None:
    """A visitor walking past a standing robot: tracked, and on /people near where they walk."""
    from tests.io.test_mcap_out import _decode
    from tests.mapping.test_people_filter import _walker_log

    log, people = _walker_log(building())
    path, mcap = tmp_path / "walker.log", tmp_path / "run.mcap"
    write_carmen(log, path)
    args = ["slam", str(path), "-o", str(tmp_path / "m.yaml"), "--people-filter", "--force"]
    main([*args, "--no-loop-closure", "--mcap", str(mcap), "--mcap-map-every", "0"])
    msgs = _decode(mcap)
    assert len(msgs["/people"]) == len(msgs["/scan"]) == len(log.scans)
    assert len(msgs["/map"]) == 1  # the finished map only
    seen = 0
    for k, (_, m) in enumerate(msgs["/people"]):
        clear, *cylinders = m.markers
        assert clear.action == 3
        for c in cylinders:
            assert c.header.frame_id == "map"
            assert math.hypot(c.pose.position.x - people[k, 0], c.pose.position.y - people[k, 1]) < 0.5
        seen += len(cylinders)
    assert seen > len(log.scans) // 2


def test_slam_refuses_an_existing_mcap_before_mapping(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = drive(building(), n=5)
    log.odometry = []
    path = tmp_path / "hall.log"
    write_carmen(log, path)
    (tmp_path / "run.mcap").write_text("kept")
    for extra in (["--mcap", str(tmp_path / "run.mcap")], ["--mcap-map-every", "-1"]):
        with pytest.raises(SystemExit) as exc:
            main(["slam", str(path), "-o", str(tmp_path / "m.yaml"), *extra])
        assert exc.value.code == 2
        (error,) = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("error:")]
        assert extra[0] in error
    assert (tmp_path / "run.mcap").read_text() == "kept"
    assert not (tmp_path / "m.yaml").exists()
