"""ETH/UCY pedestrian files: read on the real recordings, one-line errors on bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tourbot.data import data_dir
from tourbot.io.pedestrians import PedestrianFormatError, read_pedestrians


def test_reads_frames_ids_and_positions(tmp_path: Path) -> None:
    path = tmp_path / "scene.txt"
    path.write_text("10\t2.0\t1.5\t2.5\n0\t1.0\t0.0\t0.0\n10\t1.0\t0.4\t0.0\n")
    tr = read_pedestrians(path)
    assert tr.people == 2
    np.testing.assert_array_equal(tr.ids, [1, 1, 2])
    np.testing.assert_array_equal(tr.frames, [0, 1, 1])
    np.testing.assert_allclose(tr.xy[1], [0.4, 0.0])
    assert tr.duration == pytest.approx(0.8)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("0\t1\t2\n", r"scene\.txt:1.*4 columns"),
        ("0\t1\t2\t3\n5\t1\t2\t3\n", r"scene\.txt:2.*multiple of 10"),
        ("0\t1\tx\t3\n", r"scene\.txt:1.*not a number"),
        ("0\t1\t2\tnan\n", r"scene\.txt:1.*not finite"),
        ("0\t1\t2\t3\n0\t1\t2\t4\n", r"twice in one frame"),
        ("", r"no trajectories"),
    ],
)
def test_bad_files_are_one_line_errors(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "scene.txt"
    path.write_text(text)
    with pytest.raises(PedestrianFormatError, match=message):
        read_pedestrians(path)


def test_reads_the_recordings() -> None:
    root = data_dir()
    if root is None or not (root / "pedestrians").is_dir():
        pytest.skip("the pedestrian recordings (../shared/data/pedestrians) are absent")
    tr = read_pedestrians(root / "pedestrians" / "crowds_zara01.txt")
    assert tr.people > 100
    assert 300.0 < tr.duration < 400.0
