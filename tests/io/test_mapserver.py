"""map_server maps: the YAML + PGM pair, origin with yaw, thresholds, negate, modes, bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from tourbot.errors import InputError
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


def _graded_grid() -> OccupancyGrid:
    """Every occupancy from 0 to 1 in steps of 0.01, and unknown cells, on a 7 x 15 grid."""
    prob = np.full(105, UNKNOWN, dtype=np.float32)
    prob[:101] = np.linspace(0.0, 1.0, 101)
    prob[101:103] = np.nextafter(np.array([0.65, 0.196], np.float32), np.array([1.0, 0.0], np.float32))
    return OccupancyGrid(prob.reshape(7, 15), 0.05, origin=(-1.0, 2.5, 0.0))


@pytest.mark.parametrize("mode", ["raw", "scale"])
def test_raw_and_scale_keep_the_occupancy_between_the_thresholds(tmp_path: Path, mode: str) -> None:
    grid = _graded_grid()
    image = write_map(grid, tmp_path / "m.yaml", mode=mode)  # type: ignore[arg-type]
    assert image.suffix == (".pgm" if mode == "raw" else ".png")
    doc = yaml.safe_load((tmp_path / "m.yaml").read_text())
    assert doc["mode"] == mode
    assert doc["image"] == image.name
    back = read_map(tmp_path / "m.yaml")
    np.testing.assert_array_equal(back.unknown(), grid.unknown())
    known = ~grid.unknown()
    np.testing.assert_allclose(back.prob[known], grid.prob[known], atol=0.0101)  # 1 % steps
    # rounding never moves a cell across a threshold: the same occupied and free cells
    np.testing.assert_array_equal(back.occupied(), grid.occupied())
    np.testing.assert_array_equal(back.free(), grid.free())


def test_trinary_stays_the_default_and_loses_the_middle(tmp_path: Path) -> None:
    grid = _graded_grid()
    write_map(grid, tmp_path / "m.yaml")
    assert yaml.safe_load((tmp_path / "m.yaml").read_text())["mode"] == "trinary"
    back = read_map(tmp_path / "m.yaml")
    between = (grid.prob >= grid.free_thresh) & (grid.prob <= grid.occupied_thresh)
    assert between.any()
    assert back.unknown()[between].all()


def test_raw_pixels_are_percent_and_scale_pixels_what_map_server_reads_back(tmp_path: Path) -> None:
    prob = np.array([[0.0, 0.5, 1.0, UNKNOWN]], dtype=np.float32)
    grid = OccupancyGrid(prob, 0.1)
    write_map(grid, tmp_path / "r.yaml", mode="raw")
    with Image.open(tmp_path / "r.pgm") as img:
        np.testing.assert_array_equal(np.asarray(img), [[0, 50, 100, 255]])
    write_map(grid, tmp_path / "s.yaml", mode="scale")
    with Image.open(tmp_path / "s.png") as img:
        assert img.mode == "LA"
        grey, alpha = np.asarray(img)[..., 0].astype(float), np.asarray(img)[..., 1]
    np.testing.assert_array_equal(alpha, [[255, 255, 255, 0]])
    # map_server's scale mode: occ = 1 - shade, and p = (occ - free) / (occupied - free) between
    occ = 1.0 - grey[0, :3] / 255.0
    p = np.clip((occ - grid.free_thresh) / (grid.occupied_thresh - grid.free_thresh), 0.0, 1.0)
    np.testing.assert_allclose(p, [0.0, 0.5, 1.0], atol=0.006)


def test_scale_mode_reads_transparent_pixels_as_unknown(tmp_path: Path) -> None:
    la = np.array([[[0, 255], [0, 0], [255, 255]]], dtype=np.uint8)  # black, transparent, white
    Image.fromarray(la).save(tmp_path / "m.png")
    scaled = read_map(_write_yaml(tmp_path, mode="scale"))
    np.testing.assert_array_equal(scaled.prob, [[1.0, UNKNOWN, 0.0]])


def test_a_map_written_again_keeps_the_old_one_when_writing_fails(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    write_map(_grid(), tmp_path / "m.yaml")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}

    def broken(_self: Path, _data: bytes) -> int:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Path, "write_bytes", broken)
    with pytest.raises(OSError, match="No space"):
        write_map(_graded_grid(), tmp_path / "m.yaml", mode="raw")
    monkeypatch.undo()
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_map_output_names_are_checked_before_any_work(tmp_path: Path) -> None:
    from tourbot.io.mapserver import check_map_output

    with pytest.raises(MapFormatError, match=r"must end in \.yaml"):
        check_map_output(tmp_path / "m.pgm")
    (tmp_path / "d.yaml").mkdir()
    with pytest.raises(InputError, match="is a folder"):
        check_map_output(tmp_path / "d.yaml")
    assert check_map_output(tmp_path / "m.yaml") == tmp_path / "m.yaml"


def test_a_map_image_given_instead_of_its_yaml_is_named(tmp_path: Path) -> None:
    write_map(_grid(), tmp_path / "m.yaml")
    with pytest.raises(MapFormatError, match=r"give the \.yaml file"):
        read_map(tmp_path / "m.pgm")
