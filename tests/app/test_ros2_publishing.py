"""``tourbot demo --record --mcap``: the recorded tour as MCAP, through the same recorder as
``simulate --mcap`` (tested in ``tests/io/test_mcap_out.py``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.cli.test_web import _run
from tests.io.test_mcap_out import _decode, _pose
from tourbot.io.ros2_messages import TOPICS


def test_a_recorded_demo_tour_is_written_as_mcap(tmp_path: Path) -> None:
    out, mcap = tmp_path / "demo", tmp_path / "tour.mcap"
    args = ["demo", "--record", "--crowd", "empty", "--duration", "6", "--no-animation", "--out", str(out)]
    assert _run([*args, "--mcap", str(mcap)]) == 0
    msgs = _decode(mcap)
    assert set(msgs) == set(TOPICS) - {
        "/beams",
        "/ceiling/image",
        "/people",
        "/objects",
    }  # no camera, tracker
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


def test_the_foxglove_client_receives_live_scans_from_the_demo(tmp_path: Path) -> None:
    import asyncio
    import socket
    import threading

    from tests.io.test_foxglove_live import receive
    from tourbot.app.demo import run_tour
    from tourbot.localization.mcl import MCLConfig

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    done = threading.Event()

    def tour() -> None:
        try:
            run_tour(
                site="fhw", tour="highlights", crowd="sparse", seed=0, duration=12.0, speedup=1.0,
                mcl=MCLConfig().with_samples(300), dwell_scale=0.5, out=tmp_path / "demo",
                animation=False, foxglove=port,
            )  # fmt: skip
        finally:
            done.set()

    thread = threading.Thread(target=tour, daemon=True)
    thread.start()
    got = asyncio.run(receive(port, {"/scan", "/estimate", "/particles", "/map"}, timeout=30.0))
    thread.join(timeout=60)
    assert done.is_set()
    assert len(got["/scan"].ranges) > 100  # FHW's laser
    assert got["/map"].info.width > 100
    assert got["/estimate"].header.frame_id == "map"
    assert 0 < len(got["/particles"].poses) <= 500
