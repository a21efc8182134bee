from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tourbot.io.errors import LogFormatError
from tourbot.io.g2o import read_g2o


def test_reads_vertices_and_edges(tmp_path: Path) -> None:
    f = tmp_path / "g.g2o"
    f.write_text(
        "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 10 0 0 10 0 100\n"
        "EDGE_SE2 1 0 -1 0.1 0 10 1 0 10 0 100\n"
    )
    g = read_g2o(f)
    assert g.poses.shape == (2, 3)
    assert np.array_equal(g.edges, [[0, 1], [1, 0]])
    assert g.information[1][0, 1] == g.information[1][1, 0] == 1.0


def test_missing_vertices_are_chained_from_edges(tmp_path: Path) -> None:
    f = tmp_path / "g.g2o"
    f.write_text("EDGE_SE2 0 1 1 0 1.5707963 1 0 0 1 0 1\nEDGE_SE2 1 2 1 0 0 1 0 0 1 0 1\n")
    g = read_g2o(f)
    assert np.allclose(g.poses[2], [1.0, 1.0, np.pi / 2], atol=1e-6)


def test_bad_line_names_file_and_line(tmp_path: Path) -> None:
    f = tmp_path / "g.g2o"
    f.write_text("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 x 0 0 1 0 0 1 0 1\n")
    with pytest.raises(LogFormatError, match=r"g\.g2o.*2"):
        read_g2o(f)


def test_real_graphs_parse(shared_data: Path) -> None:
    g = read_g2o(shared_data / "posegraph" / "intel.g2o")
    assert len(g.poses) == 1728
    assert len(g.edges) == 2512
