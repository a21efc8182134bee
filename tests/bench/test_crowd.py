"""``tourbot bench crowd`` on a short run: the table, the JSON and the figure."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tourbot.cli.main import main
from tourbot.data import data_dir


def test_bench_crowd_writes_json_and_figure(tmp_path: Path) -> None:
    root = data_dir()
    if root is None or not (root / "pedestrians").is_dir():
        pytest.skip("the pedestrian recordings (../shared/data/pedestrians) are absent")
    out, fig = tmp_path / "crowd.json", tmp_path / "crowd.png"
    main(
        [
            "bench", "crowd", "--seeds", "0", "--duration", "20", "--warmup", "5", "--demo-duration", "0",
            "--no-overlay", "--figure", str(fig), "-o", str(out),
        ]
    )  # fmt: skip
    payload = json.loads(out.read_text())
    sources = [r["source"] for r in payload["rows"]]
    assert "crowds_zara01" in sources
    assert "sim peak" in sources
    assert fig.stat().st_size > 10_000
    zara = payload["meta"]["recordings"]["crowds_zara01"]
    assert 0.9 < zara["speed_median"] < 1.5
