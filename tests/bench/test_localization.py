"""tourbot bench localization: the paper's metrics on synthetic error curves, and a smoke run."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tourbot.bench.peers.amcl_adapter import amcl_available
from tourbot.cli.main import main


@pytest.mark.slow
@pytest.mark.usefixtures("shared_data")
def test_quick_run_writes_the_table(tmp_path: Path) -> None:
    methods = "mcl-none,mcl-novelty" + (",amcl" if amcl_available() else "")
    out = tmp_path / "loc.json"
    main(
        [
            "bench", "localization", "--quick", "--methods", methods, "--cache", str(tmp_path / "cache"),
            "--global-scans", "8", "--speed-scans", "3", "-o", str(out),
        ]
    )  # fmt: skip
    payload = json.loads(out.read_text())
    assert [r["method"] for r in payload["rows"]] == methods.split(",")
    assert payload["meta"]["seeds"] == 1
    assert (tmp_path / "localization-fig5.png").exists()


@pytest.mark.slow
@pytest.mark.usefixtures("shared_data")
def test_first_seed_chooses_the_seeds(tmp_path: Path) -> None:
    # Fresh seeds can be run without the earlier ones: --first-seed 3 --seeds 1 is seed 3 alone
    # (its crowds, kidnaps and localizer), recorded in the JSON.
    out = tmp_path / "loc.json"
    main(
        [
            "bench", "localization", "--quick", "--first-seed", "3", "--methods", "mcl-novelty",
            "--cache", str(tmp_path / "cache"), "--global-scans", "8", "--speed-scans", "3",
            "--no-figure", "-o", str(out),
        ]
    )  # fmt: skip
    payload = json.loads(out.read_text())
    assert payload["meta"]["first_seed"] == 3
    assert sorted(p.name for p in (tmp_path / "cache").glob("*.log.gz")) == [
        "fhw25-peak-3-rebuilt.log.gz",
        "fhw25-sparse-3-rebuilt.log.gz",
    ]
    assert set(payload["rows"][0]["raw"]["kidnaps_per_seed"]) <= {"3"}


@pytest.mark.slow
@pytest.mark.usefixtures("shared_data")
def test_parts_runs_only_the_runs_asked_for(tmp_path: Path) -> None:
    # --parts peak: tracking in the peak crowd alone; no sparse crowd is built, the other columns
    # are '-' (not zeros), the peak figures are there.
    out = tmp_path / "loc.json"
    main(
        [
            "bench", "localization", "--quick", "--parts", "peak", "--methods", "mcl-novelty",
            "--cache", str(tmp_path / "cache"), "--speed-scans", "1", "--no-figure", "-o", str(out),
        ]
    )  # fmt: skip
    payload = json.loads(out.read_text())
    assert payload["meta"]["parts"] == ["peak"]
    assert sorted(p.name for p in (tmp_path / "cache").glob("*.log.gz")) == ["fhw25-peak-0-rebuilt.log.gz"]
    (row,) = payload["rows"]
    assert row["fail sparse %"] == row["global ok %"] == row["t rec s"] == "-"
    assert row["raw"]["kidnaps_per_seed"] == {}
    assert row["fail peak %"] != "-"
    assert row["jumps>2m peak"].startswith("0 ")


def test_an_unknown_part_is_a_one_line_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["bench", "localization", "--parts", "peak,kidnap"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "--parts" in err
    assert "'kidnap'" in err
    assert len(err.splitlines()) == 1


@pytest.mark.parametrize(("option", "value"), [("--first-seed", "-1"), ("--workers", "0")])
def test_a_bad_count_is_a_one_line_error_naming_it(
    option: str, value: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["bench", "localization", option, value])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert option in err
    assert len(err.splitlines()) == 1


def test_jumps_count_steps_away_from_the_reference_not_fast_driving() -> None:
    from tourbot.bench.localization import jumps

    ref = np.zeros((6, 3))
    ref[:, 0] = np.arange(6) * 1.5  # the robot itself moves 1.5 m a scan: no jump
    est = ref.copy()
    assert jumps(est, ref) == 0
    est[3, 1] = 30.0  # away for one scan and back: two jumps of 30 m
    assert jumps(est, ref) == 2
    assert jumps(est, ref, threshold=40.0) == 0


def _without_timing(payload: dict[str, Any]) -> dict[str, Any]:
    """The JSON of a run without what differs from run to run: times, the command, the workers."""
    out = copy.deepcopy(payload)
    for key in ("date", "command"):
        out.pop(key)
    for key in ("workers", "dask", "speed_5000_all_beams_s"):
        out["meta"].pop(key)
    out["notes"] = [n for n in out["notes"] if not n.startswith("speed,")]
    for row in out["rows"]:
        for key in ("ms/update", "x real time"):
            row.pop(key)
        for key in ("ms_per_update", "real_time_factor"):
            row["raw"].pop(key)
    return out


@pytest.mark.slow
@pytest.mark.usefixtures("shared_data")
def test_two_workers_and_a_dask_cluster_write_the_serial_json(tmp_path: Path) -> None:
    # Each (log, seed, method) task draws its randomness from its own seed, so a pool of two
    # processes (spawned: nothing inherited) and a two-worker Dask LocalCluster write what one
    # process writes, timings apart. Two seeds and two methods are four tasks, spread over both
    # workers; the kidnap rate is raised so the 20 scans hold kidnaps.
    written = {}
    for backend in ("1", "2", "dask"):
        out = tmp_path / f"loc-{backend}.json"
        how = ["--workers", "2", "--dask", "local"] if backend == "dask" else ["--workers", backend]
        main(
            [
                "bench", "localization", "--scans", "20", "--seeds", "2", "--first-seed", "1",
                "--particles", "500", "--methods", "mcl-none,mcl-novelty", "--kidnap-rate", "0.15",
                "--cache", str(tmp_path / "cache"), "--global-scans", "8", "--speed-scans", "3",
                "--no-figure", *how, "-o", str(out),
            ]
        )  # fmt: skip
        written[backend] = json.loads(out.read_text())
    assert written["2"]["meta"]["workers"] == 2
    assert written["dask"]["meta"]["dask"] == "local"
    rows = written["1"]["rows"]
    assert [r["method"] for r in rows] == ["mcl-none", "mcl-novelty"]
    assert len(rows[0]["raw"]["fail_peak"]) == 2
    assert rows[0]["raw"]["kidnaps_per_seed"], "the test run should hold kidnaps"
    assert _without_timing(written["2"]) == _without_timing(written["1"])
    assert _without_timing(written["dask"]) == _without_timing(written["1"])


@pytest.mark.parametrize("workers", [1, 2])
def test_a_failing_task_is_one_error_naming_it(workers: int) -> None:
    # No data was installed for log "fhw": the task fails, in this process or in a worker.
    from tourbot.bench.localization import run_tasks
    from tourbot.errors import TourbotError

    with pytest.raises(TourbotError) as error:
        run_tasks({}, [("fhw", 3, "mcl-none")], workers, lambda _: False)
    message = str(error.value)
    assert message.startswith("task (log fhw, seed 3, method mcl-none) failed: KeyError")
    assert len(message.splitlines()) == 1


@pytest.mark.slow
def test_dask_task_failures_and_a_missing_scheduler_are_one_line_errors() -> None:
    from tourbot.bench.localization import run_tasks
    from tourbot.errors import TourbotError

    with pytest.raises(TourbotError) as error:
        run_tasks({}, [("fhw", 3, "mcl-none")], 1, lambda _: False, dask="local")
    assert str(error.value).startswith("task (log fhw, seed 3, method mcl-none) failed: KeyError")
    with pytest.raises(TourbotError, match="no Dask scheduler answers"):
        run_tasks({}, [("fhw", 3, "mcl-none")], 1, lambda _: False, dask="tcp://127.0.0.1:9")
