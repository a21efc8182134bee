"""The ROS 2 messages of a run: schemas for every channel, the people markers, and the Foxglove
layout shipped with the docs naming only channels that exist."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

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
