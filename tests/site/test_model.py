from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from tourbot.site import SiteError, load_site, rasterize_polygons, site_from_dict

ROOM: dict[str, Any] = {
    "name": "room",
    "map": {"walls": [[[0, 0], [10, 0], [10, 6], [0, 6]]], "resolution": 0.1, "margin": 0.5},
    "exhibits": [
        {"name": "vase", "position": [2, 2], "viewing_pose": [3, 2, math.pi], "text": "A vase."},
        {"name": "globe", "position": [8, 4], "viewing_pose": [7, 4, 0.0]},
    ],
    "tours": [{"name": "short", "exhibits": ["vase", "globe"]}],
    "doors": [{"name": "d", "hinge": [5, 6], "leaf_length": 0.9, "closed_direction": 0.0}],
    "furniture": [{"name": "bench", "outline": [[0, 0], [1, 0], [1, 0.4], [0, 0.4]], "poses": [[4, 1, 0]]}],
    "invisible_obstacles": [{"name": "glass", "outline": [[6, 1], [7, 1], [7, 2], [6, 2]]}],
    "ceiling_lights": [{"position": [5, 3, 3.5]}],
}


def _write(tmp_path: Path, data: Any) -> Path:
    p = tmp_path / "site.yaml"
    p.write_text(yaml.safe_dump(data))
    return p


def test_walls_only_site_loads_and_rasterises(tmp_path: Path) -> None:
    site = load_site(_write(tmp_path, ROOM))
    assert site.tour("short").exhibits == ["vase", "globe"]
    assert site.exhibit("globe").viewing_pose == (7.0, 4.0, 0.0)
    grid = site.grid
    assert grid.resolution == 0.1
    occ = grid.occupied()
    # the wall at y = 0 is occupied, the room's middle is not
    assert occ[grid.world_to_cell([5.0, 0.0])[0], grid.world_to_cell([5.0, 0.0])[1]]
    r, c = grid.world_to_cell([5.0, 3.0])
    assert not occ[r, c]
    inv = site.invisible_mask()
    r, c = grid.world_to_cell([6.5, 1.5])
    assert inv[r, c]
    assert inv.sum() == pytest.approx(100, rel=0.3)  # 1 m^2 at 10 cm cells


def test_door_leaf_and_furniture_polygon() -> None:
    site = site_from_dict(ROOM, base_dir=Path("."))
    a, b = site.doors[0].leaf(1.0)
    assert a == (5.0, 6.0)
    assert b[0] == pytest.approx(5.0)
    assert b[1] == pytest.approx(6.9)
    poly = site.furniture[0].polygon((1.0, 1.0, math.pi / 2))
    assert poly[1][0] == pytest.approx(1.0)
    assert poly[1][1] == pytest.approx(2.0)


@pytest.mark.parametrize(
    ("change", "field", "message"),
    [
        (lambda d: d["exhibits"][1].pop("viewing_pose"), "exhibits.1.viewing_pose", "required"),
        (lambda d: d["tours"][0]["exhibits"].append("nope"), "tours.0.exhibits.2", "unknown exhibit"),
        (lambda d: d["exhibits"][1].update(name="vase"), "exhibits.1.name", "duplicate"),
        (lambda d: d["doors"][0].update(leaf_length=-1), "doors.0.leaf_length", "greater than 0"),
        (lambda d: d.update(colour="red"), "colour", "Extra inputs"),
        (lambda d: d["map"].pop("walls"), "map", "grid file, wall polygons"),
        (lambda d: d["invisible_obstacles"][0].update(height=[1, 0]), "invisible_obstacles.0.height", "low"),
    ],
)
def test_errors_name_the_field(tmp_path: Path, change: Any, field: str, message: str) -> None:
    import copy

    data = copy.deepcopy(ROOM)
    change(data)
    path = _write(tmp_path, data)
    with pytest.raises(SiteError) as info:
        load_site(path)
    assert info.value.field == field
    assert message in str(info.value)
    assert str(path) in str(info.value)


def test_bad_yaml_and_missing_file(tmp_path: Path) -> None:
    p = tmp_path / "site.yaml"
    p.write_text("name: x\nmap: [1, 2\n")
    with pytest.raises(SiteError) as info:
        load_site(p)
    assert info.value.line is not None
    with pytest.raises(SiteError, match="cannot read"):
        load_site(tmp_path / "absent.yaml")


def test_unknown_tour_lists_the_tours() -> None:
    site = site_from_dict(ROOM, base_dir=Path("."))
    with pytest.raises(SiteError, match="short"):
        site.tour("long")


def test_rasterize_fills_polygons() -> None:
    site = site_from_dict(ROOM, base_dir=Path("."))
    mask = rasterize_polygons(site.grid, [[(1.0, 1.0), (3.0, 1.0), (3.0, 3.0), (1.0, 3.0)]])
    assert mask.sum() == pytest.approx(400, rel=0.15)
    assert mask.dtype == np.bool_


def test_segment_walls_draw_as_the_segments() -> None:
    from tourbot.site.model import MapSpec, segment_walls, walls_grid

    segments = np.array([[[0.0, 0.0], [5.0, 0.0]], [[5.0, 0.0], [5.0, 3.0]]])
    walls = segment_walls(segments)
    MapSpec(walls=walls)  # valid wall polygons of a site
    grid = walls_grid(walls, resolution=0.05, margin=0.5)
    occ = grid.occupied()
    for x, y in [(1.0, 0.0), (2.5, 0.0), (5.0, 1.5), (5.0, 2.9)]:
        r, c = grid.world_to_cell([x, y])
        assert occ[max(r - 1, 0) : r + 2, max(c - 1, 0) : c + 2].any()
    r, c = grid.world_to_cell([2.5, 1.5])
    assert not occ[r, c]
    assert occ.sum() < 2 * (5.0 + 3.0) / 0.05  # one or two cells thick, not filled
    with pytest.raises(ValueError, match="no walls"):
        walls_grid([])


def test_what_the_laser_sees_of_an_obstacle_comes_from_its_heights() -> None:
    base = {"name": "o", "outline": [[0, 0], [1, 0], [1, 0.6], [0, 0.6]]}
    site = site_from_dict(
        {
            **ROOM,
            "invisible_obstacles": [
                {**base, "name": "old"},  # an old file: a box from the floor to 0.3 m
                {**base, "name": "plinth", "height": [0.0, 0.9]},
                {**base, "name": "cabinet", "height": [0.7, 1.3]},
                {**base, "name": "case", "height": [0.0, 1.0], "kind": "glass"},
                {**base, "name": "table", "height": [0.0, 0.75], "kind": "table"},
                {**base, "name": "railed", "height": [0.0, 1.0], "kind": "glass", "base": 0.12, "lid": 0.05},
                {**base, "name": "on-plinth", "height": [0.0, 1.6], "kind": "glass", "base": 0.8},
            ],
        },
        base_dir=Path("."),
    )
    seen = {o.name: (o.laser_outline(0.4), len(o.laser_legs(0.4))) for o in site.invisible_obstacles}
    assert seen == {
        "old": (False, 0),
        "plinth": (True, 0),
        "cabinet": (False, 0),
        "case": (False, 0),
        "table": (False, 4),
        "railed": (False, 0),
        "on-plinth": (True, 0),
    }
    assert [o.name for o in site.laser_missed(0.4)] == ["old", "cabinet", "case", "table", "railed"]
    parts = site.invisible_obstacles[5].solid_parts()
    assert np.allclose(parts, [(0.0, 0.12), (0.95, 1.0)])
    legs = np.asarray(site.invisible_obstacles[4].leg_centres())
    assert np.allclose(legs, [[0.05, 0.05], [0.95, 0.05], [0.95, 0.55], [0.05, 0.55]], atol=1e-9)


@pytest.mark.parametrize(
    ("extra", "message"),
    [({"kind": "box", "base": 0.1}, "glass case"), ({"kind": "glass", "base": 0.8, "lid": 0.3}, "fit")],
)
def test_glass_case_parts_must_fit(extra: dict[str, object], message: str) -> None:
    data = {
        **ROOM,
        "invisible_obstacles": [
            {"name": "x", "outline": [[0, 0], [1, 0], [1, 1]], "height": [0, 1], **extra}
        ],
    }
    with pytest.raises(SiteError) as err:
        site_from_dict(data, base_dir=Path("."))
    assert message in str(err.value)


def test_unknown_obstacle_kind_names_the_field(tmp_path: Path) -> None:
    data = {
        **ROOM,
        "invisible_obstacles": [{"name": "x", "outline": [[0, 0], [1, 0], [1, 1]], "kind": "jelly"}],
    }
    with pytest.raises(SiteError) as err:
        load_site(_write(tmp_path, data))
    assert "invisible_obstacles.0.kind" in str(err.value)
