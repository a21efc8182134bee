"""The ROS 2 messages of a run: schemas for every channel, the people markers, and the Foxglove
layout shipped with the docs naming only channels that exist."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from tests.io.test_mcap_out import _decode
from tourbot.io.mcap_out import McapRun
from tourbot.io.ros2_messages import TOPICS, message_definition
from tourbot.snapshot import PersonState

LAYOUT = Path(__file__).parents[2] / "docs" / "foxglove" / "tourbot.layout.json"


def test_every_channel_has_a_ros2msg_schema() -> None:
    for msgtype in TOPICS.values():
        text = message_definition(msgtype)
        assert text.strip()
        assert "MSG: " in text or "/" not in text.split("\n", 1)[0]  # dependencies follow the type


def test_people_markers_replace_the_last_set(tmp_path: Path) -> None:
    path = tmp_path / "p.mcap"
    with McapRun(path) as run:
        run.write_people([PersonState(7, 1.0, 2.0), PersonState(9, -1.0, 0.5)], 1.0)
        run.write_people([], 2.0)
    (t1, first), (t2, second) = _decode(path)["/people"]
    assert (t1, t2) == (1_000_000_000, 2_000_000_000)
    clear, *people = first.markers
    assert clear.action == 3  # DELETEALL: the last set goes
    assert [(m.id, m.pose.position.x, m.pose.position.y) for m in people] == [(7, 1.0, 2.0), (9, -1.0, 0.5)]
    assert all(m.type == 3 and m.header.frame_id == "map" for m in people)  # cylinders in the map
    assert [m.action for m in second.markers] == [3]


def test_the_shipped_layout_names_only_existing_channels() -> None:
    layout = json.loads(LAYOUT.read_text())
    named = set(re.findall(r'"(/[a-z_/]+)[".]', json.dumps(layout)))
    assert named
    assert named <= set(TOPICS), named - set(TOPICS)
    panels = set(layout["configById"])
    assert panels == set(re.findall(r'"([0-9A-Za-z]+![a-z]+)"', json.dumps(layout["layout"])))
    assert np.all([p.split("!")[0] in {"3D", "Image", "Plot"} for p in panels])
    # the 3D panel shows every channel that draws in the map: grids, scans, poses and markers
    drawn = {
        t
        for t, m in TOPICS.items()
        if m.split("/")[0] != "tf2_msgs" and not m.endswith(("Image", "Odometry"))
    }
    assert set(layout["configById"]["3D!tourbot"]["topics"]) == drawn


def test_object_outlines_in_their_states_replace_the_last_set(tmp_path: Path) -> None:
    from tourbot.maps.objects import ObjectShape

    door = ObjectShape(
        "D", "door", np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.1], [0.0, 0.1]]), hinge=(2.0, 3.0)
    )
    table = ObjectShape("T", "furniture", np.array([[-0.5, -0.25], [0.5, -0.25], [0.5, 0.25], [-0.5, 0.25]]))
    path = tmp_path / "o.mcap"
    with McapRun(path) as run:
        run.write_objects([door, table], [(np.pi / 2,), (1.0, -1.0, 0.0)], [True, False], 1.5)
        run.write_objects([table], [(0.0, 0.0, np.pi / 2)], [True], 2.0, ids=[7])
        with pytest.raises(ValueError, match="one state"):
            run.write_objects([door], [], [True], 3.0)
    (t1, first), (t2, second) = _decode(path)["/objects"]
    assert (t1, t2) == (1_500_000_000, 2_000_000_000)
    assert [(m.ns, m.id, m.type, m.action) for m in first.markers] == [
        ("objects", 0, 4, 3),  # DELETEALL: the last set goes
        ("objects", 0, 4, 0),
        ("names", 0, 9, 0),
        ("objects", 1, 4, 0),
        ("names", 1, 9, 0),
    ]
    door_pts = np.array([(p.x, p.y) for p in first.markers[1].points])
    # the door opened 90 degrees about its hinge, the outline closed
    expected = np.array([[2.0, 3.0], [2.0, 4.0], [1.9, 4.0], [1.9, 3.0], [2.0, 3.0]])
    np.testing.assert_allclose(door_pts, expected, atol=1e-9)
    table_pts = np.array([(p.x, p.y) for p in first.markers[3].points])
    np.testing.assert_allclose(table_pts[:4], table.outline + np.array([1.0, -1.0]), atol=1e-12)
    assert [m.text for m in first.markers[2::2]] == ["D", "T"]
    assert first.markers[1].color.g == pytest.approx(0.55)  # observed: orange
    assert first.markers[3].color.g == pytest.approx(0.6)  # not observed: grey
    assert all(m.header.frame_id == "map" for m in first.markers)
    assert [(m.ns, m.id) for m in second.markers[1:]] == [("objects", 7), ("names", 7)]
    turned = np.array([(p.x, p.y) for p in second.markers[1].points])
    np.testing.assert_allclose(turned[0], [0.25, -0.5], atol=1e-12)
