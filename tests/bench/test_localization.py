"""tourbot bench localization: the paper's metrics on synthetic error curves, and a smoke run."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from tourbot.bench.localization import mean_ci, recovery, settle_index, tracking_errors
from tourbot.bench.peers.amcl_adapter import amcl_available
from tourbot.cli.main import main


def test_tracking_errors_wrap_headings() -> None:
    est = np.array([[1.0, 1.0, math.pi - 0.1], [0.0, 0.0, 0.0]])
    ref = np.array([[1.3, 1.4, -math.pi + 0.1], [0.0, 0.0, 0.5]])
    pos, head = tracking_errors(est, ref)
    np.testing.assert_allclose(pos, [0.5, 0.0])
    np.testing.assert_allclose(head, [0.2, 0.5])


def test_settling_needs_more_than_ten_seconds_below_45_cm() -> None:
    times = np.arange(30.0) * 2.0  # a scan every 2 s
    err = np.full(30, 1.0)
    err[5:10] = 0.1  # 8 s below: not enough
    err[12:] = 0.2  # from scan 12 on, for good
    assert settle_index(err, times, 0, 30) == 12
    err[20] = 0.5  # a failure at 40 s: 12..19 spans 14 s, still enough
    assert settle_index(err, times, 0, 30) == 12
    err[17] = 0.5  # now 12..16 spans 8 s; 18..19 too short; 21.. runs to the end
    assert settle_index(err, times, 0, 30) == 21
    assert settle_index(np.full(30, 1.0), times, 0, 30) is None


def test_recovery_per_kidnap_until_the_next() -> None:
    times = np.arange(40.0)
    path = np.arange(40.0) * 0.5
    err = np.full(40, 0.05)
    err[10:13] = 2.0  # kidnap at 10, back at 13 (stays below until 25: > 10 s)
    err[25:] = 2.0  # kidnap at 25, never back (14 s to the end of the log)
    out = recovery(err, times, path, [10, 25])
    assert out[0] == (True, 3.0, 1.5)
    assert out[1] is not None
    assert out[1][0] is False
    assert math.isnan(out[1][1])


def test_a_kidnap_followed_by_another_within_ten_seconds_is_censored() -> None:
    times = np.arange(40.0)
    path = np.arange(40.0)
    err = np.full(40, 0.05)
    err[10:15] = 2.0
    out = recovery(err, times, path, [10, 14, 30])
    assert out[0] is None  # the next kidnap comes 4 s later: it cannot be judged
    assert out[1] == (True, 1.0, 1.0)
    assert out[2] == (True, 0.0, 0.0)
    err[10:25] = 2.0
    judged = recovery(err, times, path, [10, 22])[0]  # 12 s to the next kidnap: judged, failed
    assert judged is not None
    assert judged[0] is False


def test_a_kidnap_within_ten_seconds_of_the_end_is_censored_unless_settled() -> None:
    times = np.arange(40.0)
    path = np.arange(40.0)
    err = np.full(40, 0.05)
    err[35:] = 2.0  # kidnap at 35, 4 s before the end: cannot be judged
    assert recovery(err, times, path, [35]) == [None]
    err[37:] = 0.05  # ... unless it has settled by the end of the log
    assert recovery(err, times, path, [35]) == [(True, 2.0, 2.0)]
    err[28:] = 2.0  # 11 s before the end and never back: judged, failed
    late = recovery(err, times, path, [28])[0]
    assert late is not None
    assert late[0] is False


def test_mean_ci() -> None:
    m, h = mean_ci([1.0, 2.0, 3.0, 4.0, 5.0])
    assert m == 3.0
    # t(0.975, 4) = 2.776; sd = 1.581; h = 2.776 * 1.581 / sqrt(5)
    assert h == pytest.approx(1.963, abs=1e-3)
    assert mean_ci([7.0]) == (7.0, 0.0)
    assert all(math.isnan(v) for v in mean_ci([math.nan]))


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
