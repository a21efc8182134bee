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


def _strict_model(path: Path) -> Path:
    """The shipped leg model with a far lower intercept (a much higher threshold), saved to ``path``."""
    from dataclasses import replace

    from tourbot.people.leg_classifier import default_model

    shipped = default_model()
    assert shipped is not None
    weights = (*shipped.weights[:-1], shipped.weights[-1] - 40.0)
    replace(shipped, weights=weights, trained_on="strict").save(path)
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
