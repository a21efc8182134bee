"""``tourbot demo --record --mcap``: the recorded tour as MCAP, through the same recorder as
``simulate --mcap`` (tested in ``tests/io/test_mcap_out.py``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.cli.test_web import _run
from tests.io.test_mcap_out import _decode, _pose
from tourbot.io.mcap_out import TOPICS


def test_a_recorded_demo_tour_is_written_as_mcap(tmp_path: Path) -> None:
    out, mcap = tmp_path / "demo", tmp_path / "tour.mcap"
    args = ["demo", "--record", "--crowd", "empty", "--duration", "6", "--no-animation", "--out", str(out)]
    assert _run([*args, "--mcap", str(mcap)]) == 0
    msgs = _decode(mcap)
    assert set(msgs) == set(TOPICS) - {"/beams"}
    assert len(msgs["/map"]) == 1
    stamps = [s for s, _ in msgs["/scan"]]
    assert len(stamps) > 30  # about 10 scans a simulated second
    assert stamps == sorted(stamps)
    assert [s for s, _ in msgs["/odom"]] == stamps
    assert {s for s, _ in msgs["/estimate"]} <= set(stamps)
    assert len(msgs["/particles"]) == len(msgs["/estimate"]) > 0
    # the estimates are the tour's: within the demo's own measured error of where it drove
    summary = json.loads((out / "summary.json").read_text())
    assert summary["mean_error_m"] < 0.3
    est = np.array([_pose(m.pose.pose) for _, m in msgs["/estimate"]])
    assert np.ptp(est[:, 0]) + np.ptp(est[:, 1]) > 0.2  # it moved
    # an existing file is kept unless --force; --mcap without --record is refused
    assert _run([*args, "--mcap", str(mcap)]) == 2
    assert _run([*args, "--mcap", str(mcap), "--force"]) == 0
    assert _run(["demo", "--mcap", str(tmp_path / "live.mcap")]) == 2
    assert not (tmp_path / "live.mcap").exists()


def test_the_demo_refuses_an_mcap_in_a_missing_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _run(["demo", "--record", "--mcap", str(tmp_path / "nowhere" / "x.mcap")]) == 2
    err = capsys.readouterr().err
    assert "does not exist" in err
    assert "Traceback" not in err
