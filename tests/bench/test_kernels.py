"""`tourbot bench kernels` end to end on the real FHW log (small sizes), and the casters on real scans."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tourbot.cli.main import main


@pytest.mark.usefixtures("shared_data")
def test_bench_kernels_runs_and_casters_agree(tmp_path: Path) -> None:
    out = tmp_path / "kernels.json"
    main(
        [
            "bench",
            "kernels",
            "--particles",
            "40",
            "--field-poses",
            "200",
            "--repeat",
            "1",
            "--max-range",
            "20",
            "--output",
            str(out),
        ]
    )
    payload = json.loads(out.read_text())
    kernels = [row["kernel"] for row in payload["rows"]]
    assert "cast DDACaster" in kernels
    assert "cast DistanceCaster" in kernels
    assert "likelihood field, scan sums" in kernels
    assert "likelihood field, scan sums, free space" in kernels
    cast = payload["meta"]["cast_20m"]
    assert cast["distance_within_one_cell"] == 1.0  # the exact accelerated caster: the DDA's ranges
    assert cast["distance_max_m"] == 0.0
    # against the log's real ranges, from its reference poses
    assert cast["distance_real_median_m"] == cast["dda_real_median_m"] < 0.1
    assert 0.5 < cast["mean_range_m"] < 20.0
    assert all(row["M evals/s/core"] > 0 for row in payload["rows"])


def test_cast_ranges_explain_real_scans(shared_data: Path) -> None:
    from tourbot.io.carmen import read_carmen
    from tourbot.maps.raycast import DistanceCaster
    from tourbot.maps.reference import build_reference_map

    log = read_carmen(shared_data / "carmen" / "fhw-corrected.log.gz")
    grid = build_reference_map(log, 0.1)
    geom = log.scans[0].geometry
    idx = np.arange(0, len(log), 10)
    real = log.ranges[idx]
    ok = real < 20.0
    cast = DistanceCaster(grid, geom.max_range).cast(log.reference_poses[idx], geom.angles)
    err = np.abs(cast[ok] - real[ok])
    # most beams of a real scan end where the map says (people and glass make the rest)
    assert np.median(err) < 0.15
    assert np.mean(err < 0.3) > 0.7


def test_bad_options_are_one_line_errors(capsys: pytest.CaptureFixture[str]) -> None:
    for args, field in (
        (["--particles", "0"], "--particles"),
        (["--max-range", "-1"], "--max-range"),
    ):
        with pytest.raises(SystemExit) as exit_info:
            main(["bench", "kernels", *args])
        assert exit_info.value.code == 2
        err = capsys.readouterr().err
        assert field in err
        assert "Traceback" not in err
