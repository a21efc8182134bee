"""Smoke tests of ``tourbot demo`` and ``tourbot simulate`` on the shipped FHW site (short legs)."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import IO, Any

import pytest
from typer.testing import CliRunner

from tourbot.cli.main import build_app


@pytest.mark.slow
def test_demo_runs_a_short_leg_and_writes_its_outputs(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    result = CliRunner().invoke(
        build_app(),
        ["demo", "--record", "--tour", "short", "--crowd", "sparse", "--duration", "20", "--out", str(out)],
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
    result = CliRunner().invoke(build_app(), ["demo", "--record", "--tour", "nope", "--out", str(tmp_path)])
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


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _read_until(stream: IO[str], prefix: str, limit: float) -> tuple[str, list[str]]:
    """The first line starting with ``prefix`` (and every line read), or a failure after ``limit`` s."""
    import selectors
    import time

    lines: list[str] = []
    selector = selectors.DefaultSelector()
    selector.register(stream, selectors.EVENT_READ)
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        if not selector.select(timeout=1.0):
            continue
        line = stream.readline()
        if not line:
            break
        lines.append(line.rstrip())
        if line.startswith(prefix):
            return line, lines
    pytest.fail(f"no line starting with {prefix!r} within {limit} s; output: {lines}")


async def _first_keyframe(base: str, port: int) -> Any:
    import httpx
    from websockets.asyncio.client import connect

    from tourbot.web.stream import KEYFRAME, StreamDecoder

    async with httpx.AsyncClient(base_url=base, trust_env=False) as client:
        token = (await client.get("/api/session")).cookies["tourbot_session"]
    async with connect(
        f"ws://127.0.0.1:{port}/ws/lefkos",
        origin=base,  # type: ignore[arg-type]
        additional_headers={"Cookie": f"tourbot_session={token}"},
        proxy=None,
    ) as ws:
        while True:
            message = await asyncio.wait_for(ws.recv(), 60)
            if isinstance(message, bytes):
                assert message[0] == KEYFRAME  # a client that joins gets a keyframe first
                decoder = StreamDecoder()
                decoder.feed(message)
                return decoder.scene()


@pytest.mark.slow
def test_demo_serves_the_museum_until_ctrl_c(tmp_path: Path) -> None:
    """``tourbot demo`` (what ``make demo`` runs): a taken port is replaced by a free one, the pages
    and the live stream answer, and Ctrl-C (to the whole process group) stops it cleanly."""
    import os
    import re
    import signal
    import socket
    import subprocess
    import sys

    import httpx

    from tourbot.site.default import site_path
    from tourbot.site.model import load_site

    taken = socket.socket()
    taken.bind(("127.0.0.1", _free_port()))
    taken.listen()
    port = int(taken.getsockname()[1])
    src = Path(__file__).resolve().parents[2] / "src"
    env = {**os.environ, "PYTHONPATH": str(src), "PYTHONUNBUFFERED": "1", "COLUMNS": "200"}
    env.pop("TOURBOT_STAFF_PASSWORD", None)
    command = [
        sys.executable,
        "-m",
        "tourbot",
        "demo",
        "--port",
        str(port),
        "--crowd",
        "7",
        "--particles",
        "200",
    ]
    process = subprocess.Popen(
        command, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True,
    )  # fmt: skip
    try:
        assert process.stdout is not None
        line, lines = _read_until(process.stdout, "visitor page:", limit=240)
        taken.close()
        assert f"port {port} is in use: serving on port" in "\n".join(lines)
        assert any(re.search(r"password \S+", x) for x in lines)  # the generated staff password
        match = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
        assert match, line
        served = int(match.group(1))
        assert served != port
        base = f"http://127.0.0.1:{served}"
        more = [_read_until(process.stdout, prefix, limit=10)[0] for prefix in ("on-board", "staff")]
        assert f"{base}/onboard" in more[0]
        assert f"{base}/admin" in more[1]
        page = httpx.get(base + "/", trust_env=False, timeout=30)
        assert page.status_code == 200
        assert "<canvas" in page.text or "three" in page.text
        scene = asyncio.run(_first_keyframe(base, served))
        # the robot of the simulated museum, on a free cell of the FHW map (quantized to 1 cm)
        grid = load_site(site_path("fhw")).grid
        row, col = grid.world_to_cell([scene.robot.x, scene.robot.y])
        assert grid.inside([row, col])
        assert grid.free()[row, col]
        assert (tmp_path / "out" / "demo" / "tourbot-fhw.db").is_file()  # the database is kept there
        os.killpg(process.pid, signal.SIGINT)  # what Ctrl-C in a terminal does
        out, err = process.communicate(timeout=60)
    finally:
        taken.close()
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    assert process.returncode == 0, err
    assert "Traceback" not in err, err
    assert "stopped" in out
