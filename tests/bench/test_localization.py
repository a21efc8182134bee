"""tourbot bench localization: the paper's metrics on synthetic error curves, and a smoke run."""

from __future__ import annotations

import json
from pathlib import Path

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


def test_a_negative_first_seed_is_a_one_line_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["bench", "localization", "--first-seed", "-1"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "--first-seed" in err
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
