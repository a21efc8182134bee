from __future__ import annotations

import csv
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
    assert list(rows[0].keys()) == ["scan", "time", "track", "x", "y", "vx", "vy"]
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
