"""map_server maps: the YAML + PGM pair, origin with yaw, thresholds, negate, modes, bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from tourbot.io import MapFormatError
from tourbot.io.mapserver import read_map, write_map
from tourbot.maps.grid import UNKNOWN, OccupancyGrid


def _grid() -> OccupancyGrid:
    prob = np.full((4, 6), UNKNOWN, dtype=np.float32)
    prob[0, :] = 0.0
    prob[1, 2] = 0.9
    prob[3, 5] = 1.0
    prob[2, 1] = 0.4  # between the thresholds: written as unknown
    return OccupancyGrid(prob, 0.05, origin=(1.5, -2.0, 0.3))


def test_round_trip_trinary(tmp_path: Path) -> None:
    grid = _grid()
    pgm = write_map(grid, tmp_path / "m.yaml")
    assert pgm.read_bytes().startswith(b"P5")
    back = read_map(tmp_path / "m.yaml")
    assert back.resolution == 0.05
    assert back.origin == (1.5, -2.0, 0.3)
    expected = np.full(grid.shape, UNKNOWN, dtype=np.float32)
    expected[grid.free()] = 0.0
    expected[grid.occupied()] = 1.0
    np.testing.assert_array_equal(back.prob, expected)


def test_image_top_row_is_the_far_edge(tmp_path: Path) -> None:
    write_map(_grid(), tmp_path / "m.yaml")
    with Image.open(tmp_path / "m.pgm") as img:
        pixels = np.asarray(img)
    assert pixels.shape == (4, 6)
    assert (pixels[-1] == 254).all()  # grid row 0 (free, smallest y) is the image's bottom row
    assert pixels[0, 5] == 0


def _write_yaml(tmp_path: Path, **doc: object) -> Path:
    base: dict[str, object] = {"image": "m.png", "resolution": 0.1, "origin": [0.0, 0.0, 0.0]}
    base.update(doc)
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(base))
    return path


def test_negate_scale_and_raw(tmp_path: Path) -> None:
    Image.fromarray(np.array([[0, 100, 255]], dtype=np.uint8)).save(tmp_path / "m.png")
    plain = read_map(_write_yaml(tmp_path))
    np.testing.assert_array_equal(plain.prob, [[1.0, UNKNOWN, 0.0]])
    negated = read_map(_write_yaml(tmp_path, negate=1))
    np.testing.assert_array_equal(negated.prob, [[0.0, UNKNOWN, 1.0]])
    scaled = read_map(_write_yaml(tmp_path, mode="scale"))
    occ = 155 / 255
    assert scaled.prob[0, 1] == pytest.approx((occ - 0.196) / (0.65 - 0.196), abs=1e-6)
    raw = read_map(_write_yaml(tmp_path, mode="raw"))
    np.testing.assert_allclose(raw.prob, [[0.0, 1.0, UNKNOWN]])


@pytest.mark.parametrize(
    ("doc", "field", "match"),
    [
        ({"resolution": "fine"}, "resolution", "must be a number"),
        ({"resolution": -1}, "resolution", "positive"),
        ({"origin": [0, 0]}, "origin", r"\[x, y, yaw\]"),
        ({"image": "missing.pgm"}, "image", "does not exist"),
        ({"mode": "fancy"}, "mode", "trinary, scale or raw"),
        ({"free_thresh": 0.9}, "free_thresh", "free_thresh < occupied_thresh"),
    ],
)
def test_bad_yaml(tmp_path: Path, doc: dict[str, object], field: str, match: str) -> None:
    Image.fromarray(np.zeros((2, 2), dtype=np.uint8)).save(tmp_path / "m.png")
    with pytest.raises(MapFormatError, match=match) as info:
        read_map(_write_yaml(tmp_path, **doc))
    assert info.value.field == field


def test_not_yaml_and_not_an_image(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("image: [unclosed\n")
    with pytest.raises(MapFormatError, match="not valid YAML"):
        read_map(bad)
    (tmp_path / "m.png").write_bytes(b"\x00garbage" * 10)
    with pytest.raises(MapFormatError, match="not a readable image"):
        read_map(_write_yaml(tmp_path))
