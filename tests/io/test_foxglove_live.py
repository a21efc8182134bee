"""The live Foxglove server: a WebSocket client (the Foxglove protocol, ``foxglove.sdk.v1``)
subscribes and decodes a scan and a pose with the ROS 2 type store."""

from __future__ import annotations

import asyncio
import json
import math
import struct
import threading
import time
from typing import Any

import numpy as np
import pytest
import websockets
from websockets.typing import Subprotocol

from tourbot.errors import InputError
from tourbot.io.foxglove_live import FoxgloveLive
from tourbot.io.ros2_messages import STORE
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import LaserGeometry, Scan

GEOMETRY = LaserGeometry(num_beams=3, angle_min=-1.0, angle_increment=1.0, max_range=8.0)


async def receive(port: int, topics: set[str], timeout: float = 20.0) -> dict[str, Any]:
    """Subscribe to ``topics`` and return the first message decoded on each."""
    got: dict[str, Any] = {}
    deadline = time.monotonic() + timeout
    while True:  # the server may not be up yet
        try:
            ws = await websockets.connect(
                f"ws://127.0.0.1:{port}", subprotocols=[Subprotocol("foxglove.sdk.v1")]
            )
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            await asyncio.sleep(0.2)
    async with ws:
        subscribed: dict[int, tuple[str, str]] = {}
        while set(got) != topics and time.monotonic() < deadline:
            frame = await asyncio.wait_for(ws.recv(), timeout=deadline - time.monotonic())
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg.get("op") == "advertise":
                    subs = []
                    for ch in msg["channels"]:
                        if ch["topic"] in topics:
                            assert ch["encoding"] == "cdr"
                            assert ch["schemaEncoding"] == "ros2msg"
                            sub = len(subscribed) + 1
                            subscribed[sub] = (ch["topic"], ch["schemaName"])
                            subs.append({"id": sub, "channelId": ch["id"]})
                    if subs:
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                continue
            opcode, sub, _stamp = struct.unpack_from("<BIQ", frame)
            if opcode == 1 and sub in subscribed:
                topic, msgtype = subscribed[sub]
                got.setdefault(topic, STORE.deserialize_cdr(bytes(frame[13:]), msgtype))
    return got


def test_a_client_receives_live_scans_and_poses() -> None:
    with FoxgloveLive(port=0) as live:
        assert live.port > 0
        stop = threading.Event()

        def publish() -> None:
            k = 0
            while not stop.is_set():
                k += 1
                live.write_scan(Scan(0.1 * k, np.array([1.0, 2.5, 8.0]), GEOMETRY, odom=(0.0, 0.0, 0.0)))
                live.write_estimate((1.0, 2.0, 0.5), np.eye(3) * 0.01, (0.0, 0.0, 0.0), 0.1 * k)
                if k == 1:  # once, before any client: latched
                    live.write_map(OccupancyGrid(np.zeros((2, 3), np.float32), 0.5), 0.1)
                time.sleep(0.05)

        thread = threading.Thread(target=publish, daemon=True)
        thread.start()
        try:
            time.sleep(0.3)
            got = asyncio.run(receive(live.port, {"/scan", "/estimate", "/map"}))
        finally:
            stop.set()
            thread.join()
    assert got["/scan"].ranges.tolist() == [1.0, 2.5, 8.0]
    assert (got["/map"].info.width, got["/map"].info.height) == (3, 2)
    assert got["/scan"].header.frame_id == "laser"
    pose = got["/estimate"].pose.pose
    assert (pose.position.x, pose.position.y) == (1.0, 2.0)
    assert math.isclose(2 * math.atan2(pose.orientation.z, pose.orientation.w), 0.5)


def test_a_taken_port_and_a_bad_port_are_one_line_errors() -> None:
    with FoxgloveLive(port=0) as first, pytest.raises(InputError, match=f"on 127.0.0.1:{first.port}"):
        FoxgloveLive(port=first.port).__enter__()
    with pytest.raises(InputError, match="must be a TCP port"):
        FoxgloveLive(port=70000)
    with pytest.raises(RuntimeError, match="not open"):
        FoxgloveLive(port=0).write_particles(np.zeros((1, 3)), 0.0)
