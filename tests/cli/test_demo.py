"""Smoke tests of ``tourbot demo`` and ``tourbot simulate`` on the shipped FHW site (short legs)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from tourbot.cli.main import build_app


@pytest.mark.slow
def test_demo_runs_a_short_leg_and_writes_its_outputs(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    result = CliRunner().invoke(
        build_app(),
        ["demo", "--tour", "short", "--crowd", "sparse", "--duration", "20", "--out", str(out)],
    )
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["tour"] == "short"
    assert summary["duration_s"] == pytest.approx(20.0, abs=0.5)
    assert summary["distance_m"] > 2.0
    assert summary["within_15cm"] > 0.9
    assert (out / "recording.jsonl.gz").stat().st_size > 0
    assert (out / "tour.gif").stat().st_size > 0


def test_unknown_tour_is_a_clear_error(tmp_path: Path) -> None:
    result = CliRunner().invoke(build_app(), ["demo", "--tour", "nope", "--out", str(tmp_path)])
    assert result.exit_code != 0
    assert "no tour named 'nope'" in str(result.exception)


@pytest.mark.slow
def test_simulate_writes_a_carmen_log_with_ground_truth(tmp_path: Path) -> None:
    from tourbot.io.carmen import read_carmen

    log = tmp_path / "s.log.gz"
    result = CliRunner().invoke(
        build_app(), ["simulate", "--crowd", "10", "--duration", "5", "--write-log", str(log)]
    )
    assert result.exit_code == 0, result.output
    back = read_carmen(log)
    assert len(back.scans) == 50
    assert back.has_reference
    assert (tmp_path / "s.truth.tum").exists()
    people = json.loads((tmp_path / "s.people.json").read_text())
    assert len(people["positions"]) == 50
    assert len(people["positions"][0]) == 10


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["demo", "--duration", "-1"], "field --duration: must be positive"),
        (["demo", "--particles", "-1"], "field --particles: must be at least 1, got -1"),
        (["demo", "--speedup", "-2"], "field --speedup"),
        (["simulate", "--duration", "-5"], "field --duration: must be positive"),
        (["demo", "--crowd", "-3"], "unknown crowd '-3'; choose empty, sparse, peak or a number of visitors"),
        (["simulate", "--crowd", "lots"], "unknown crowd 'lots'"),
    ],
)
def test_bad_numbers_are_refused_before_running(
    args: list[str], expected: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from tests.cli.test_logs import _run

    out = ["--out", str(tmp_path / "demo")] if args[0] == "demo" else ["--write-log", str(tmp_path / "s.log")]
    assert _run([*args, *out]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert expected in err
    assert "Traceback" not in err
    assert not any(tmp_path.iterdir())  # nothing written
