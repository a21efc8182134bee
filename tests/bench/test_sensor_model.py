"""``tourbot bench sensor-model``: the estimators on known data, and the command on a real log."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from tourbot.bench.sensor_model import correlation_length, fit_sigma_hit, measure, robust_sigma
from tourbot.cli.main import main
from tourbot.errors import TourbotError
from tourbot.records import RobotLog

from ..localization.conftest import room_with_boxes


def test_the_ml_sigma_hit_of_a_half_normal_among_strays() -> None:
    rng = np.random.default_rng(0)
    hits = np.abs(rng.normal(0.0, 0.04, 9000))
    strays = rng.uniform(0.0, 2.0, 1000)  # a tenth of the endpoints far from any wall
    sigma, z_hit = fit_sigma_hit(np.concatenate([hits, strays]), max_dist=2.0)
    assert sigma == pytest.approx(0.04, rel=0.05)
    assert z_hit == pytest.approx(0.9, abs=0.02)


def test_the_robust_sigma_ignores_people() -> None:
    rng = np.random.default_rng(1)
    core = rng.normal(0.01, 0.05, 8000)
    people = -rng.uniform(0.5, 5.0, 2000)  # readings a visitor cut short
    assert robust_sigma(np.concatenate([core, people])) == pytest.approx(0.05 * 1.3, rel=0.15)
    assert np.std(np.concatenate([core, people])) > 0.5  # what a plain spread would say
    with pytest.raises(ValueError, match="no residuals"):
        robust_sigma(np.zeros(0))


@pytest.mark.parametrize("rho", [0.0, 0.5, 0.8])
def test_the_correlation_length_of_an_ar1_scan(rho: float) -> None:
    # An AR(1) sequence of beams: rho(k) = rho^k, so 1 + 2 sum_k rho^k = (1 + rho) / (1 - rho)
    # (less the lags below the 0.05 floor, which are left out).
    rng = np.random.default_rng(2)
    scans = np.zeros((400, 180))
    scans[:, 0] = rng.normal(size=400)
    for b in range(1, 180):
        scans[:, b] = rho * scans[:, b - 1] + math.sqrt(1 - rho**2) * rng.normal(size=400)
    scans[rng.random(scans.shape) < 0.05] = np.nan  # beams without a return
    expected = 1.0 + 2.0 * sum(rho**k for k in range(1, 31) if rho**k >= 0.05)
    assert correlation_length(scans) == pytest.approx(expected, rel=0.1, abs=0.1)


def test_a_log_without_reference_poses_is_refused() -> None:
    bare = RobotLog(source="bare.log", scans=[], odometry=[])
    with pytest.raises(TourbotError, match=r"bare\.log: .*reference poses"):
        measure(bare, room_with_boxes())


def test_bench_sensor_model_on_the_intel_log(tmp_path: Path, shared_data: Path) -> None:
    assert shared_data.is_dir()
    out = tmp_path / "sensor.json"
    args = ["--logs", "intel", "--scans", "60", "--cache", str(tmp_path), "-o", str(out)]
    main(["bench", "sensor-model", *args])
    (row,) = json.loads(out.read_text())["rows"]
    assert row["log"] == "intel"
    # a SICK laser on a 5 cm map: a few centimetres of spread, and neighbouring beams err together
    assert 1.0 < row["range sigma cm"] < 10.0
    assert 1.0 < row["field sigma surface cm"] < row["field sigma centre cm"] < 10.0
    assert row["correlated beams"] > 3.0
