"""The ROS bag reader: the leg_tracker bags, a ROS 2 bag built here, and bad bags."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tourbot.io import BagError, load_log
from tourbot.io.rosbag import bag_topics, read_bag, read_pose_arrays


def _bag(shared_data: Path, name: str) -> Path:
    return shared_data / "leg_tracker" / f"{name}.bag"


def test_reads_the_demo_bag(shared_data: Path) -> None:
    log = load_log(_bag(shared_data, "demo_stationary_simple_environment"))
    assert len(log) == 1265
    g = log.scans[0].geometry
    assert g.num_beams == 512
    assert g.fov == pytest.approx(math.pi, abs=0.01)
    # REP 117: "no return" (inf) becomes range_max, so every range is finite
    assert np.isfinite(log.ranges).all()
    assert (log.ranges == np.float64(np.float32(g.max_range))).any()
    assert np.all(np.diff(log.times) > 0)
    assert log.times[-1] - log.times[0] == pytest.approx(126.4, abs=1.0)  # 10 Hz
    assert log.scans[0].sensor == "/scan"
    assert log.scans[0].odom is None  # no odometry in this bag


def test_picks_a_topic_and_says_which_others_exist(shared_data: Path) -> None:
    path = _bag(shared_data, "negative_2")
    log = read_bag(path, scan_topic="/left_scan")
    assert len(log) == 435
    assert {s.sensor for s in log.scans} == {"/left_scan"}
    assert log.scans[0].geometry.num_beams == 768
    assert log.scans[0].geometry.fov == pytest.approx(math.radians(270), abs=0.01)
    default = read_bag(path)
    assert any("also holds LaserScan topics" in w for w in default.warnings)
    with pytest.raises(BagError, match="no LaserScan topic '/front_scan'"):
        read_bag(path, scan_topic="/front_scan")


def test_leg_cluster_annotations_pair_with_scans(shared_data: Path) -> None:
    path = _bag(shared_data, "positive_1_extracted")
    log = read_bag(path)
    arrays = read_pose_arrays(path, "/leg_cluster_positions")
    assert len(log) == len(arrays) == 197
    np.testing.assert_array_equal([t for t, _ in arrays], log.times)
    assert all(xy.ndim == 2 and xy.shape[1] == 2 for _, xy in arrays)
    # legs are a few metres from the laser
    dists = np.concatenate([np.hypot(xy[:, 0], xy[:, 1]) for _, xy in arrays])
    assert 0.2 < np.median(dists) < 5.0


def test_bag_without_laser_topics(tmp_path: Path) -> None:
    path = tmp_path / "odom_only"
    _write_ros2(path, scans=0, odoms=3)
    assert set(bag_topics(path)) == {"/odom"}
    with pytest.raises(BagError, match="no sensor_msgs/LaserScan topic"):
        read_bag(path)


def test_not_a_bag(tmp_path: Path) -> None:
    path = tmp_path / "fake.bag"
    path.write_bytes(b"#ROSBAG V2.0\n" + bytes(range(256)) * 4)
    with pytest.raises(BagError, match="not a readable ROS bag"):
        load_log(path)
    text = tmp_path / "text.bag"
    text.write_text("hello")
    with pytest.raises(BagError, match="not a readable ROS bag"):
        read_bag(text)


def _write_ros2(path: Path, *, scans: int, odoms: int, negative: bool = False) -> None:
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    t: Any = store.types
    Time, Header = t["builtin_interfaces/msg/Time"], t["std_msgs/msg/Header"]
    with Writer(path, version=8) as writer:
        scan_conn = (
            writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store) if scans else None
        )
        odom_conn = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        events = [(0.1 * i, "odom", i) for i in range(odoms)] + [
            (0.1 * i + 0.05, "scan", i) for i in range(scans)
        ]
        for time, kind, i in sorted(events):
            stamp = Time(sec=int(time), nanosec=round((time % 1) * 1e9))
            header = Header(stamp=stamp, frame_id="laser" if kind == "scan" else "odom")
            if kind == "scan":
                ranges = np.array([1.0, np.inf, np.nan, 2.0, -np.inf], dtype=np.float32)
                if negative and i == 1:
                    ranges[0] = -1.0
                msg = t["sensor_msgs/msg/LaserScan"](
                    header=header,
                    angle_min=-1.0,
                    angle_max=1.0,
                    angle_increment=0.5,
                    time_increment=0.0,
                    scan_time=0.1,
                    range_min=0.1,
                    range_max=8.0,
                    ranges=ranges,
                    intensities=np.zeros(0, dtype=np.float32),
                )
                assert scan_conn is not None
                writer.write(
                    scan_conn, int(time * 1e9), store.serialize_cdr(msg, "sensor_msgs/msg/LaserScan")
                )
            else:
                yaw = 0.1 * i
                pose = t["geometry_msgs/msg/Pose"](
                    position=t["geometry_msgs/msg/Point"](x=float(i), y=0.0, z=0.0),
                    orientation=t["geometry_msgs/msg/Quaternion"](
                        x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
                    ),
                )
                cov = np.zeros(36)
                twist = t["geometry_msgs/msg/Twist"](
                    linear=t["geometry_msgs/msg/Vector3"](x=1.0, y=0.0, z=0.0),
                    angular=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.2),
                )
                msg = t["nav_msgs/msg/Odometry"](
                    header=header,
                    child_frame_id="base_link",
                    pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov),
                    twist=t["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=cov),
                )
                writer.write(odom_conn, int(time * 1e9), store.serialize_cdr(msg, "nav_msgs/msg/Odometry"))


def test_ros2_bag_with_odometry(tmp_path: Path) -> None:
    path = tmp_path / "ros2"
    _write_ros2(path, scans=4, odoms=6)
    log = load_log(path)
    assert len(log) == 4
    assert len(log.odometry) == 6
    np.testing.assert_allclose(log.ranges[0], [1.0, 8.0, 8.0, 2.0, 0.0])
    g = log.scans[0].geometry
    assert (g.num_beams, g.angle_min, g.angle_increment) == (5, -1.0, 0.5)
    # the scan at 0.05 s + 0.1 i lies halfway between odometry readings i and i + 1
    for i, scan in enumerate(log.scans):
        assert scan.odom == pytest.approx((i + 0.5, 0.0, 0.1 * i + 0.05))
    assert log.odometry[2].tv == 1.0
    assert log.odometry[2].rv == pytest.approx(0.2)
    # the storage file of a ROS 2 bag opens too
    (db3,) = path.glob("*.db3")
    assert len(load_log(db3)) == 4


def test_negative_range_in_a_bag(tmp_path: Path) -> None:
    path = tmp_path / "neg"
    _write_ros2(path, scans=3, odoms=4, negative=True)
    with pytest.raises(BagError, match=r"message \d+: range\[0\] is negative"):
        read_bag(path)
    log = read_bag(path, lenient=True)
    assert len(log) == 2
    assert any("skipped 1 malformed scan" in w for w in log.warnings)


def test_odometry_from_tf(tmp_path: Path) -> None:
    """Without nav_msgs/Odometry, the odom -> base_link transforms on /tf are the odometry."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    t: Any = store.types
    path = tmp_path / "tf"

    def header(time: float, frame: str) -> Any:
        stamp = t["builtin_interfaces/msg/Time"](sec=int(time), nanosec=round((time % 1) * 1e9))
        return t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    with Writer(path, version=8) as writer:
        scan_conn = writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        tf_conn = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=store)
        for i in range(3):
            time = 1.0 + i
            transforms = []
            for parent, child, x in (("odom", "base_link", float(i)), ("base_link", "laser", 0.2)):
                transforms.append(
                    t["geometry_msgs/msg/TransformStamped"](
                        header=header(time, parent),
                        child_frame_id=child,
                        transform=t["geometry_msgs/msg/Transform"](
                            translation=t["geometry_msgs/msg/Vector3"](x=x, y=0.0, z=0.0),
                            rotation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                        ),
                    )
                )
            msg = t["tf2_msgs/msg/TFMessage"](transforms=transforms)
            writer.write(tf_conn, int(time * 1e9), store.serialize_cdr(msg, "tf2_msgs/msg/TFMessage"))
            if i < 2:
                scan = t["sensor_msgs/msg/LaserScan"](
                    header=header(time + 0.25, "laser"),
                    angle_min=0.0,
                    angle_max=0.0,
                    angle_increment=0.1,
                    time_increment=0.0,
                    scan_time=0.1,
                    range_min=0.1,
                    range_max=8.0,
                    ranges=np.array([1.0], dtype=np.float32),
                    intensities=np.zeros(0, dtype=np.float32),
                )
                stamp_ns = int((time + 0.25) * 1e9)
                writer.write(scan_conn, stamp_ns, store.serialize_cdr(scan, "sensor_msgs/msg/LaserScan"))
    log = read_bag(path)
    assert [o.pose for o in log.odometry] == [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (2.0, 0.0, 0.0)]
    assert [s.odom for s in log.scans] == [pytest.approx((0.25, 0.0, 0.0)), pytest.approx((1.25, 0.0, 0.0))]
    # the base_link -> laser transform is the laser's mount
    assert log.scans[0].geometry.offset == (0.2, 0.0, 0.0)


def _write_camera_bag(path: Path, messages: list[tuple[str, float, Any]]) -> None:
    """A ROS 1 bag with camera topics: (topic, time, message fields) in writing order."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    t: Any = store.types
    conns: dict[str, Any] = {}
    with Writer(path) as writer:
        for topic, time, fields in messages:
            kind = "sensor_msgs/msg/CompressedImage" if "format" in fields else "sensor_msgs/msg/Image"
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, kind, typestore=store)
            stamp = t["builtin_interfaces/msg/Time"](sec=int(time), nanosec=round((time % 1) * 1e9))
            header = t["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id="camera")
            msg = t[kind](header=header, **fields)
            writer.write(conns[topic], int(time * 1e9), store.serialize_ros1(msg, kind))


def test_camera_images_from_a_ros1_bag_raw_and_compressed(tmp_path: Path) -> None:
    import cv2

    from tourbot.io.rosbag import read_bag_images

    grey = np.arange(12, dtype=np.uint8).reshape(3, 4) * 20
    rgb = np.stack([grey, grey, grey], axis=-1)
    padded = np.zeros((3, 16), dtype=np.uint8)  # rows padded to a step of 16 bytes
    padded[:, :12] = rgb.reshape(3, 12)
    wide = (grey.astype(np.uint16) << 8) | 7  # mono16, little-endian
    ok, png = cv2.imencode(".png", grey)
    assert ok
    raw = [
        (
            "/ceiling/image",
            2.0,
            {
                "height": 3,
                "width": 4,
                "encoding": "rgb8",
                "is_bigendian": 0,
                "step": 16,
                "data": padded.reshape(-1),
            },
        ),
        (
            "/ceiling/image",
            1.0,
            {
                "height": 3,
                "width": 4,
                "encoding": "mono8",
                "is_bigendian": 0,
                "step": 4,
                "data": grey.reshape(-1),
            },
        ),
        (
            "/ceiling/image",
            3.0,
            {
                "height": 3,
                "width": 4,
                "encoding": "mono16",
                "is_bigendian": 0,
                "step": 8,
                "data": wide.astype("<u2").view(np.uint8).reshape(-1),
            },
        ),
        ("/front/compressed", 1.5, {"format": "png", "data": np.frombuffer(png.tobytes(), dtype=np.uint8)}),
    ]
    path = tmp_path / "camera.bag"
    _write_camera_bag(path, raw)
    times, images = read_bag_images(path, "/ceiling/image")
    assert times.tolist() == [1.0, 2.0, 3.0]  # in time order
    assert images.shape == (3, 3, 4)
    for img in images:
        assert np.abs(img.astype(int) - grey).max() <= 1  # the same picture in every encoding
    t2, png_images = read_bag_images(path, "front/compressed")
    assert t2.tolist() == [1.5]
    assert np.array_equal(png_images[0], grey)
    with pytest.raises(BagError, match="no camera topic named '/scan'"):
        read_bag_images(path, "/scan")


def test_camera_images_bad_encoding_and_sizes_are_named(tmp_path: Path) -> None:
    from tourbot.io.rosbag import read_bag_images

    one = {
        "height": 2,
        "width": 2,
        "encoding": "mono8",
        "is_bigendian": 0,
        "step": 2,
        "data": np.zeros(4, np.uint8),
    }
    bayer = {**one, "encoding": "bayer_rggb8"}
    bigger = {
        "height": 2,
        "width": 3,
        "encoding": "mono8",
        "is_bigendian": 0,
        "step": 3,
        "data": np.zeros(6, np.uint8),
    }
    short = {**one, "data": np.zeros(3, np.uint8)}
    for name, second, message in [
        ("bayer", bayer, "message 1: encoding 'bayer_rggb8'"),
        ("bigger", bigger, "message 1 is 3x2, the first was 2x2"),
        ("short", short, "message 1: 3 bytes for 2x2 mono8"),
    ]:
        path = tmp_path / f"{name}.bag"
        _write_camera_bag(path, [("/cam", 1.0, one), ("/cam", 2.0, second)])
        with pytest.raises(BagError, match=re.escape(message)):
            read_bag_images(path)
    _write_ros2(tmp_path / "nocam", scans=1, odoms=1)
    with pytest.raises(BagError, match="no camera topic"):
        read_bag_images(tmp_path / "nocam")


def test_mcap_run_images_read_back(tmp_path: Path) -> None:
    from tourbot.io.images import read_camera_images
    from tourbot.io.mcap_out import McapRun
    from tourbot.records import Image

    pixels = np.arange(12, dtype=np.uint8).reshape(3, 4)
    with McapRun(tmp_path / "run.mcap") as run:
        run.write_image(Image(1.5, pixels, camera="ceiling"))
        run.write_image(Image(2.5, pixels + 1, camera="ceiling"))
        with pytest.raises(ValueError, match="no MCAP channel for camera 'forward'"):
            run.write_image(Image(2.5, pixels, camera="forward"))
    times, images = read_camera_images(tmp_path / "run.mcap")
    assert times.tolist() == [1.5, 2.5]
    assert np.array_equal(images[1], pixels + 1)
