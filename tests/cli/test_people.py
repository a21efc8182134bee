from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from tourbot.cli.main import main


def test_track_writes_csv_of_a_real_bag(shared_data: Path, tmp_path: Path) -> None:
    out = tmp_path / "tracks.csv"
    main(
        [
            "track",
            str(shared_data / "leg_tracker" / "positive_1_extracted.bag"),
            "--pose",
            "none",
            "-o",
            str(out),
        ]
    )
    rows = list(csv.DictReader(out.open()))
    rows = [r for r in rows if r["track"]]
    # People walk in front of the laser in this bag: some confirmed tracks, within the laser's reach.
    assert len({r["track"] for r in rows}) >= 1
    assert all(abs(float(r["x"])) < 10.0 and abs(float(r["y"])) < 10.0 for r in rows)


def test_track_missing_log_is_a_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["track", str(tmp_path / "nope.bag"), "-o", str(tmp_path / "t.csv")])
    assert exc.value.code == 2
    assert "nope.bag" in capsys.readouterr().err


def test_track_without_odometry_uses_scan_matching(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "tracks.csv"
    main(["track", str(shared_data / "leg_tracker" / "positive_4_extracted.bag"), "-o", str(out)])
    assert "robot pose from scan-matching" in capsys.readouterr().out
    assert len(list(csv.DictReader(out.open()))) > 0


def test_train_legs_writes_a_model(shared_data: Path, tmp_path: Path) -> None:
    from tourbot.people.leg_classifier import LegModel

    out = tmp_path / "legs.json"
    main(["train-legs", str(shared_data / "leg_tracker" / "positive_1_extracted.bag"), "-o", str(out)])
    model = LegModel.load(out)
    assert "positive_1_extracted.bag" in model.trained_on


def test_track_interrupted_keeps_the_previous_csv(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from tourbot.people.sjpdaf import PeopleTracker

    out = tmp_path / "tracks.csv"
    out.write_text("scan,time,track,x,y,vx,vy\n0,0.0,1,1.0,2.0,0.0,0.0\n")
    before = out.read_text()
    calls = []
    update = PeopleTracker.update

    def interrupted(self: PeopleTracker, *args: object, **kwargs: object) -> object:
        calls.append(1)
        if len(calls) > 50:
            raise KeyboardInterrupt
        return update(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(PeopleTracker, "update", interrupted)
    bag = shared_data / "leg_tracker" / "positive_1_extracted.bag"
    with pytest.raises(SystemExit) as exc:
        main(["track", str(bag), "--pose", "none", "-o", str(out)])
    assert exc.value.code == 130
    assert out.read_text() == before
    assert [p.name for p in tmp_path.iterdir()] == ["tracks.csv"]


def _strict_model(path: Path) -> Path:
    """The shipped leg model from far lower log odds (a much higher threshold), saved to ``path``."""
    from dataclasses import replace

    from tourbot.people.leg_classifier import default_model

    shipped = default_model()
    assert shipped is not None
    replace(shipped, bias=shipped.bias - 40.0, trained_on="strict").save(path)
    return path


def test_train_legs_without_output_writes_in_the_current_folder(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from tourbot.people.leg_classifier import DEFAULT_MODEL, LegModel

    shipped = DEFAULT_MODEL.read_bytes()
    shipped_time = DEFAULT_MODEL.stat().st_mtime_ns
    monkeypatch.chdir(tmp_path)
    main(["train-legs", str(shared_data / "leg_tracker" / "positive_1_extracted.bag")])
    assert DEFAULT_MODEL.read_bytes() == shipped
    assert DEFAULT_MODEL.stat().st_mtime_ns == shipped_time
    assert [p.name for p in tmp_path.iterdir()] == ["leg-model.json"]
    model = LegModel.load(tmp_path / "leg-model.json")
    assert model.trained_on.startswith("positive_1_extracted.bag")
    out = capsys.readouterr().out
    assert "-> leg-model.json" in out
    assert "--leg-model leg-model.json" in out


def test_train_legs_refuses_a_folder_before_training(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["train-legs", str(tmp_path / "missing.bag"), "-o", str(tmp_path)])
    assert exc.value.code == 2
    assert "is a folder" in capsys.readouterr().err


def test_track_uses_the_given_leg_model(shared_data: Path, tmp_path: Path) -> None:
    from tourbot.people.leg_classifier import DEFAULT_MODEL

    bag = shared_data / "leg_tracker" / "positive_4_extracted.bag"

    def rows(*extra: str) -> list[dict[str, str]]:
        out = tmp_path / "tracks.csv"
        main(["track", str(bag), "--pose", "none", "--tentative", "-o", str(out), *extra])
        return list(csv.DictReader(out.open()))

    copy = tmp_path / "copy.json"
    copy.write_bytes(DEFAULT_MODEL.read_bytes())
    shipped = rows()
    assert len(shipped) > 0
    assert rows("--leg-model", str(copy)) == shipped  # the same model from another file: the same tracks
    strict = rows("--leg-model", str(_strict_model(tmp_path / "strict.json")))
    assert len(strict) < len(shipped)


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (None, " (field --leg-model): no such leg model file"),
        ('{"features": ["width"]}', " (field features): leg model built for other features"),
        ("{oops", ":1: not JSON"),
    ],
)
def test_track_bad_leg_model_is_one_clear_line(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str | None, expected: str
) -> None:
    model = tmp_path / "model.json"
    if content is not None:
        model.write_text(content)
    out = tmp_path / "t.csv"
    bag = shared_data / "leg_tracker" / "positive_4_extracted.bag"
    with pytest.raises(SystemExit) as exc:
        main(["track", str(bag), "-o", str(out), "--leg-model", str(model)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert f"{model}{expected}" in " ".join(err.split())
    assert "Traceback" not in err
    assert not out.exists()


def test_track_csv_has_the_robot_pose_and_both_frames(shared_data: Path, tmp_path: Path) -> None:
    import math

    from tourbot.cli.people import CSV_HEADER

    out = tmp_path / "tracks.csv"
    bag = shared_data / "leg_tracker" / "positive_4_extracted.bag"
    main(["track", str(bag), "--tentative", "-o", str(out)])
    rows = list(csv.DictReader(out.open()))
    assert tuple(rows[0].keys()) == CSV_HEADER
    assert {int(r["scan"]) for r in rows} == set(range(295))  # every scan, with its pose
    tracked = [r for r in rows if r["track"]]
    assert tracked
    moved = max(math.hypot(float(r["robot_x"]), float(r["robot_y"])) for r in rows)
    assert moved < 20.0
    for r in tracked:
        rx, ry, rt = (float(r[k]) for k in ("robot_x", "robot_y", "robot_theta"))
        lx, ly = float(r["x_robot"]), float(r["y_robot"])
        # the robot-frame position put back through the robot pose is the world-frame one
        assert rx + math.cos(rt) * lx - math.sin(rt) * ly == pytest.approx(float(r["x"]), abs=1e-3)
        assert ry + math.sin(rt) * lx + math.cos(rt) * ly == pytest.approx(float(r["y"]), abs=1e-3)


@pytest.mark.parametrize(
    ("pose", "missing"), [("odom", "have no odometry"), ("reference", "have no reference pose")]
)
def test_track_requested_pose_source_absent_is_one_clear_line(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], pose: str, missing: str
) -> None:
    bag = shared_data / "leg_tracker" / "positive_1_extracted.bag"
    out = tmp_path / "t.csv"
    with pytest.raises(SystemExit) as exc:
        main(["track", str(bag), "--pose", pose, "-o", str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert str(bag) in " ".join(err.split())
    assert missing in " ".join(err.split())
    assert "Traceback" not in err
    assert not out.exists()


def test_track_auto_uses_the_odometry_of_a_log_that_has_it(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import gzip

    log = tmp_path / "fhw-head.log"
    with gzip.open(shared_data / "carmen" / "fhw-corrected.log.gz", "rt") as fh:
        log.write_text("".join(line for _, line in zip(range(2500), fh, strict=False)))
    out = tmp_path / "t.csv"
    main(["track", str(log), "-o", str(out)])
    assert "robot pose from odom" in capsys.readouterr().out
    rows = list(csv.DictReader(out.open()))
    assert rows
    assert float(rows[-1]["robot_x"]) != 0.0  # the odometry pose, not a robot at the origin


@pytest.mark.parametrize("requested", ["auto", "scan-matching"])
def test_track_scan_matching_that_fails_its_check_is_said(
    shared_data: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    requested: str,
) -> None:
    from tourbot.mapping.ego_motion import ScanMatchedPoses

    calls: list[int] = []

    def jumps(self: ScanMatchedPoses) -> str | None:
        del self
        calls.append(1)
        return "a step of 9.9 m/s" if len(calls) == 20 else None

    monkeypatch.setattr(ScanMatchedPoses, "implausible", jumps)
    bag = shared_data / "leg_tracker" / "positive_4_extracted.bag"
    out = tmp_path / "t.csv"
    if requested == "auto":
        main(["track", str(bag), "-o", str(out)])
        said = capsys.readouterr().out
        assert "failed its check at scan 19: a step of 9.9 m/s" in " ".join(said.split())
        assert "robot pose from none" in said
        rows = list(csv.DictReader(out.open()))
        assert {(r["robot_x"], r["robot_y"], r["robot_theta"]) for r in rows} == {("0.000000",) * 3}
    else:
        with pytest.raises(SystemExit) as exc:
            main(["track", str(bag), "--pose", requested, "-o", str(out)])
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert "failed its check at scan 19" in " ".join(err.split())
        assert not out.exists()


def test_track_writes_the_run_as_mcap_with_the_tracks(shared_data: Path, tmp_path: Path) -> None:
    from tests.io.test_mcap_out import _decode

    out, mcap = tmp_path / "tracks.csv", tmp_path / "tracks.mcap"
    bag = str(shared_data / "leg_tracker" / "positive_1_extracted.bag")
    main(["track", bag, "--pose", "none", "-o", str(out), "--mcap", str(mcap)])
    rows = list(csv.DictReader(out.open()))
    msgs = _decode(mcap)
    scans = sorted({int(r["scan"]) for r in rows})
    assert len(msgs["/scan"]) == len(msgs["/people"]) == len(scans)
    assert len(msgs["/estimate"]) == len(scans)
    # the tracks of each scan are its /people markers (after the one that clears the last set)
    by_scan: dict[int, set[int]] = {}
    for r in rows:
        by_scan.setdefault(int(r["scan"]), set()).update({int(r["track"])} if r["track"] else set())
    for k, (_, m) in zip(scans, msgs["/people"], strict=True):
        assert {mk.id for mk in m.markers[1:]} == by_scan[k]
    assert any(by_scan.values())
    with pytest.raises(SystemExit):  # an existing file is kept unless --force
        main(["track", bag, "--pose", "none", "-o", str(out), "--mcap", str(mcap)])


def _first_scans_of(bag: Path, out: Path, per_topic: int) -> Path:
    """A copy of a ROS 1 bag with only the first ``per_topic`` messages of each topic."""
    from rosbags.rosbag1 import Reader, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    counts: dict[str, int] = {}
    with Reader(bag) as reader, Writer(out) as writer:
        conns = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=store) for c in reader.connections}
        for conn, stamp, raw in reader.messages():
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
            if counts[conn.topic] <= per_topic:
                writer.write(conns[conn.id], stamp, raw)
    return out


def test_track_of_a_bag_with_three_lasers_matches_them_on_one_map_and_says_how_they_agree(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the first 5 s of negative_2.bag: three lasers, no odometry, no tf; the robot starts to drive
    bag = _first_scans_of(shared_data / "leg_tracker" / "negative_2.bag", tmp_path / "three.bag", 40)
    out = tmp_path / "t.csv"
    main(["track", str(bag), "--scan-topic", "/rear_scan", "-o", str(out)])
    said = " ".join(capsys.readouterr().out.split())
    assert "3 lasers matched on one map (/rear_scan, /left_scan, /right_scan)" in said
    assert "laser mounts from the scans, in the frame of /rear_scan" in said
    assert "all lasers on one map:" in said
    for laser in ("/rear_scan", "/left_scan", "/right_scan"):
        assert f"{laser} alone:" in said
    assert "/left_scan + /right_scan:" in said  # all but the rear laser
    rows = list(csv.DictReader(out.open()))
    assert math.hypot(float(rows[-1]["robot_x"]), float(rows[-1]["robot_y"])) > 0.5  # it drove
