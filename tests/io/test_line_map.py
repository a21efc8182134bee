from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from tourbot.io.errors import MapFormatError
from tourbot.io.line_map import line_map_geojson, read_line_map, write_line_map

SEGMENTS = np.array([[[0.0, 0.0], [4.0, 0.0]], [[4.0, 0.0], [4.0, 3.0]], [[-1.5, 2.0], [0.5, 2.5]]])


def test_geojson_is_a_valid_feature_collection_and_round_trips(tmp_path: Path) -> None:
    path = tmp_path / "lines.geojson"
    path_xy = np.array([[0.0, 1.0], [1.0, 1.0], [2.0, 1.5]])
    write_line_map(path, SEGMENTS, corners=[[4.0, 0.0]], trajectory=path_xy, observations=[5, 3, 1])
    doc = json.loads(path.read_text())
    assert doc["type"] == "FeatureCollection"
    kinds = [f["properties"]["kind"] for f in doc["features"]]
    assert kinds == ["wall", "wall", "wall", "corner", "path"]
    for feat in doc["features"]:
        assert feat["type"] == "Feature"
        geom = feat["geometry"]
        assert geom["type"] in ("LineString", "Point")
        coords = np.asarray(geom["coordinates"], dtype=float)
        assert coords.shape[-1] == 2
        if geom["type"] == "LineString":
            assert len(coords) >= 2  # RFC 7946: two or more positions
    assert doc["features"][0]["properties"]["observations"] == 5
    assert np.allclose(read_line_map(path), SEGMENTS)


def test_svg_is_well_formed_xml_with_one_line_per_wall(tmp_path: Path) -> None:
    path = tmp_path / "lines.svg"
    write_line_map(path, SEGMENTS, corners=[[4.0, 0.0]])
    root = ET.fromstring(path.read_text())
    ns = "{http://www.w3.org/2000/svg}"
    assert root.tag == f"{ns}svg"
    assert len(root.findall(f".//{ns}line")) == len(SEGMENTS)
    assert len(root.findall(f".//{ns}circle")) == 1
    # y up: the wall at y = 2.5 is drawn above (smaller SVG y) the one at y = 0
    ys = [float(e.get("y1", "nan")) for e in root.findall(f".//{ns}line")]
    assert ys[2] < ys[0]


def test_unknown_suffix_and_bad_files_are_one_line_errors(tmp_path: Path) -> None:
    with pytest.raises(MapFormatError, match=r"geojson or \.svg"):
        write_line_map(tmp_path / "lines.txt", SEGMENTS)
    assert not (tmp_path / "lines.txt").exists()
    bad = tmp_path / "bad.geojson"
    bad.write_text("{not json")
    with pytest.raises(MapFormatError, match=r"bad\.geojson"):
        read_line_map(bad)
    one_point = {
        "type": "Feature",
        "geometry": {"type": "LineString", "coordinates": [[0, 0]]},
        "properties": {},
    }
    bad.write_text(json.dumps({"type": "FeatureCollection", "features": [one_point]}))
    with pytest.raises(MapFormatError, match=r"features\[0\]"):
        read_line_map(bad)
    with pytest.raises(MapFormatError, match="no such file"):
        read_line_map(tmp_path / "none.geojson")


def test_geojson_refuses_non_finite_segments() -> None:
    with pytest.raises(ValueError, match="finite"):
        line_map_geojson([[[0.0, 0.0], [np.nan, 1.0]]])
