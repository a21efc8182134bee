"""ROS 1 and ROS 2 bags through ``rosbags`` (pure Python, no ROS install needed).

``read_bag`` turns ``sensor_msgs/LaserScan`` messages into scans and ``nav_msgs/Odometry`` messages
(or, without them, the ``odom -> base_link`` transforms on ``/tf``) into odometry readings, and
gives each scan the odometry interpolated at its header time. Ranges follow REP 117: ``+inf`` and
NaN mean "no return" and become the laser's ``range_max``; ``-inf`` ("too close") becomes 0, below
``range_min``. ``read_pose_arrays`` reads ``geometry_msgs/PoseArray`` topics such as the annotated
``/leg_cluster_positions`` of the leg_tracker bags. ``read_bag_images`` reads a camera's
``sensor_msgs/Image`` (``mono8``, ``mono16``, ``rgb8``, ``bgr8``, ``rgba8``, ``bgra8``) or
``sensor_msgs/CompressedImage`` (PNG, JPEG) topic as 8-bit grey images with their header times.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import interpolate_poses
from tourbot.io.errors import BagError
from tourbot.records import LaserGeometry, Odometry, RobotLog, Scan

__all__ = ["bag_topics", "read_bag", "read_bag_images", "read_pose_arrays"]

LASER_SCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"
POSE_ARRAY = "geometry_msgs/msg/PoseArray"
IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"

_BASE_FRAMES = ("base_link", "base_footprint")


def _bag_paths(path: Path) -> Path:
    """What ``rosbags`` opens: a ROS 1 ``.bag`` file or a ROS 2 bag folder (also from its file)."""
    if path.suffix.lower() in (".db3", ".mcap") and (path.parent / "metadata.yaml").exists():
        return path.parent
    return path


@contextmanager
def _open(path: str | Path) -> Iterator[Any]:
    from rosbags.highlevel import AnyReader

    p = Path(path)
    if not p.exists():
        raise BagError("no such file or folder", path=p)
    if p.is_dir() and not (p / "metadata.yaml").exists():
        raise BagError("a folder, not a log file (nor a ROS 2 bag folder: no metadata.yaml in it)", path=p)
    try:
        reader = AnyReader([_bag_paths(p)])
        reader.open()
    except Exception as exc:  # rosbags raises several unrelated types for unreadable bags
        raise BagError(f"not a readable ROS bag ({type(exc).__name__}: {exc})", path=p) from None
    try:
        yield reader
    finally:
        reader.close()


def bag_topics(path: str | Path) -> dict[str, tuple[str, int]]:
    """Topic name -> (message type, message count) of a bag."""
    with _open(path) as reader:
        out: dict[str, tuple[str, int]] = {}
        for c in reader.connections:
            kind, count = out.get(c.topic, (c.msgtype, 0))
            out[c.topic] = (kind, count + c.msgcount)
        return out


def _stamp(header: Any, bag_time_ns: int) -> float:
    t = float(header.stamp.sec) + 1e-9 * float(header.stamp.nanosec)
    return t if t > 0.0 else 1e-9 * bag_time_ns


def _yaw(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _describe(topics: dict[str, tuple[str, int]]) -> str:
    return ", ".join(f"{t} ({k})" for t, (k, _) in sorted(topics.items())) or "none"


def _pick(
    topics: dict[str, tuple[str, int]], msgtype: str, wanted: str | None, path: Path, what: str
) -> str | None:
    matching = [t for t, (k, _) in topics.items() if k == msgtype]
    if wanted is not None:
        names = {wanted, wanted.lstrip("/"), "/" + wanted.lstrip("/")}
        found = [t for t in matching if t in names]
        if not found:
            raise BagError(f"no {what} topic {wanted!r} (topics: {_describe(topics)})", path=path)
        return found[0]
    if not matching:
        return None
    return max(matching, key=lambda t: (topics[t][1], t))


def read_bag(
    path: str | Path,
    *,
    scan_topic: str | None = None,
    odom_topic: str | None = None,
    lenient: bool = False,
) -> RobotLog:
    """Read the laser scans and odometry of a ROS 1 or ROS 2 bag into a :class:`RobotLog`.

    Without ``scan_topic`` the LaserScan topic with the most messages is read (the others are named
    in a warning). Odometry comes from ``odom_topic`` or the first ``nav_msgs/Odometry`` topic, else
    from ``/tf`` (``odom`` -> ``base_link``/``base_footprint``); without any, scans have no odometry.
    A ``base_link`` -> laser-frame transform on ``/tf`` or ``/tf_static`` sets the laser's offset.
    A malformed scan (negative range, beam count not matching the angles) raises :class:`BagError`,
    or is skipped and counted with ``lenient=True``.
    """
    p = Path(path)
    topics = bag_topics(p)
    scan_t = _pick(topics, LASER_SCAN, scan_topic, p, "LaserScan")
    if scan_t is None:
        raise BagError(f"no sensor_msgs/LaserScan topic in this bag (topics: {_describe(topics)})", path=p)
    warnings: list[str] = []
    others = [t for t, (k, _) in topics.items() if k == LASER_SCAN and t != scan_t]
    if others:
        warnings.append(f"{p}: read {scan_t}; also holds LaserScan topics {', '.join(sorted(others))}")
    odom_t = _pick(topics, ODOMETRY, odom_topic, p, "Odometry")
    tf_topics = {t for t, (k, _) in topics.items() if k == TF}  # /tf and /tf_static

    scans: list[Scan] = []
    odometry: list[Odometry] = []
    order: list[tuple[int, int]] = []  # (kind 0 = odometry / 1 = scan, index) in bag order
    geometries: dict[tuple[object, ...], LaserGeometry] = {}
    skipped = 0
    first_skip = ""
    mounts: dict[str, tuple[float, float, float]] = {}  # child frame -> its pose on the robot base
    frames: list[str] = []  # the laser's frame
    with _open(p) as reader:
        wanted = [c for c in reader.connections if c.topic in {scan_t, odom_t, *tf_topics}]
        for index, (conn, bag_ns, raw) in enumerate(reader.messages(connections=wanted)):
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == scan_t:
                try:
                    scan = _scan(msg, bag_ns, scan_t, geometries)
                except ValueError as exc:
                    if not lenient:
                        raise BagError(f"{scan_t} message {index}: {exc}", path=p) from None
                    skipped += 1
                    first_skip = first_skip or f"message {index}: {exc}"
                    continue
                order.append((1, len(scans)))
                scans.append(scan)
                if not frames:
                    frames.append(msg.header.frame_id.lstrip("/"))
            elif conn.topic == odom_t:
                pose = msg.pose.pose
                twist = msg.twist.twist
                odometry.append(
                    Odometry(
                        timestamp=_stamp(msg.header, bag_ns),
                        pose=(float(pose.position.x), float(pose.position.y), _yaw(pose.orientation)),
                        tv=float(twist.linear.x),
                        rv=float(twist.angular.z),
                    )
                )
                order.append((0, len(odometry) - 1))
            else:
                for tf in msg.transforms:
                    parent = tf.header.frame_id.lstrip("/")
                    child = tf.child_frame_id.lstrip("/")
                    tr = tf.transform.translation
                    pose3 = (float(tr.x), float(tr.y), _yaw(tf.transform.rotation))
                    if parent == "odom" and child in _BASE_FRAMES and odom_t is None:
                        odometry.append(Odometry(timestamp=_stamp(tf.header, bag_ns), pose=pose3))
                        order.append((0, len(odometry) - 1))
                    elif parent in _BASE_FRAMES:
                        mounts.setdefault(child, pose3)
    if skipped:
        warnings.append(f"{p}: skipped {skipped} malformed scan(s) (first: {first_skip})")
    if not scans:
        raise BagError(f"no readable scans on {scan_t}", path=p)
    if frames and frames[0] in mounts:
        # the laser's mount on the robot (a base_link -> laser transform) is its geometry's offset
        offset = mounts[frames[0]]
        fixed = {g: replace(g, offset=offset) for g in {s.geometry for s in scans}}
        scans = [replace(s, geometry=fixed[s.geometry]) for s in scans]
    if odometry:
        scans = _attach_odometry(scans, odometry, order, warnings, p)
    return RobotLog(source=str(p), scans=scans, odometry=odometry, warnings=warnings)


def _scan(msg: Any, bag_ns: int, topic: str, geometries: dict[tuple[object, ...], LaserGeometry]) -> Scan:
    ranges = np.asarray(msg.ranges, dtype=np.float64).copy()
    n = ranges.size
    expected = round((float(msg.angle_max) - float(msg.angle_min)) / float(msg.angle_increment)) + 1
    if n == 0:
        raise ValueError("a scan with no ranges")
    if abs(expected - n) > 1:
        raise ValueError(f"{n} ranges but the angles give {expected} beams")
    max_range = float(msg.range_max)
    if not max_range > 0:
        raise ValueError(f"range_max must be positive, got {max_range}")
    neg = np.isfinite(ranges) & (ranges < 0)
    if neg.any():
        i = int(np.argmax(neg))
        raise ValueError(f"range[{i}] is negative ({ranges[i]})")
    ranges[np.isnan(ranges) | (ranges == np.inf)] = max_range
    ranges[ranges == -np.inf] = 0.0
    key = (n, float(msg.angle_min), float(msg.angle_increment), max_range, float(msg.range_min))
    geometry = geometries.get(key)
    if geometry is None:
        geometry = LaserGeometry(n, key[1], key[2], max_range, key[4])
        geometries[key] = geometry
    return Scan(timestamp=_stamp(msg.header, bag_ns), ranges=ranges, geometry=geometry, sensor=topic)


def _attach_odometry(
    scans: list[Scan],
    odometry: list[Odometry],
    order: list[tuple[int, int]],
    warnings: list[str],
    path: Path,
) -> list[Scan]:
    """Odometry at each scan's time, or in bag order when the odometry times do not increase."""
    times = np.array([o.timestamp for o in odometry])
    poses = np.array([o.pose for o in odometry])
    scan_times = np.array([s.timestamp for s in scans])
    if np.all(np.diff(times) > 0) and np.all(np.diff(scan_times) > 0):
        at = interpolate_poses(times, poses, scan_times)
    else:
        warnings.append(
            f"{path}: timestamps are repeated or go backwards; odometry is matched to scans in bag order"
        )
        at = np.empty((len(scans), 3))
        last = -1
        for kind, i in order:
            if kind == 0:
                last = i
            else:
                at[i] = poses[max(last, 0)]
    return [
        Scan(s.timestamp, s.ranges, s.geometry, (float(a[0]), float(a[1]), float(a[2])), None, s.sensor)
        for s, a in zip(scans, at, strict=True)
    ]


def read_pose_arrays(path: str | Path, topic: str) -> list[tuple[float, NDArray[np.float64]]]:
    """The ``geometry_msgs/PoseArray`` messages of ``topic``: ``(time, (K, 2) x-y positions)``.

    Positions are in the message's own frame (for ``/leg_cluster_positions``: the laser's). The time
    is the header stamp; where that is zero (as in the extracted leg_tracker bags) it is the header
    stamp of the LaserScan in the same frame nearest in the bag, so annotations pair with the scans
    ``read_bag`` returns by timestamp.
    """
    p = Path(path)
    topics = bag_topics(p)
    found = _pick(topics, POSE_ARRAY, topic, p, "PoseArray")
    if found is None:  # pragma: no cover - _pick raises when a topic is named
        raise BagError(f"no PoseArray topic {topic!r}", path=p)
    arrays: list[tuple[int, float, str, NDArray[np.float64]]] = []
    lasers: dict[str, tuple[list[int], list[float]]] = {}
    with _open(p) as reader:
        conns = [c for c in reader.connections if c.topic == found or c.msgtype == LASER_SCAN]
        for conn, bag_ns, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            stamp = float(msg.header.stamp.sec) + 1e-9 * float(msg.header.stamp.nanosec)
            if conn.topic != found:
                bag_times, stamps = lasers.setdefault(msg.header.frame_id, ([], []))
                bag_times.append(bag_ns)
                stamps.append(stamp)
                continue
            xy = np.array([[q.position.x, q.position.y] for q in msg.poses], dtype=np.float64).reshape(-1, 2)
            arrays.append((bag_ns, stamp, msg.header.frame_id, xy))
    out: list[tuple[float, NDArray[np.float64]]] = []
    for bag_ns, stamp, frame, xy in arrays:
        t = stamp
        if t <= 0.0:
            same = lasers.get(frame)
            if same and same[0]:
                laser_ns = np.array(same[0], dtype=np.int64)
                t = same[1][int(np.argmin(np.abs(laser_ns - bag_ns)))]
            else:
                t = 1e-9 * bag_ns
        out.append((t, xy))
    return out


def read_bag_images(
    path: str | Path, topic: str | None = None
) -> tuple[NDArray[np.float64], NDArray[np.uint8]]:
    """The images ``(N, H, W)`` 8-bit grey of a camera topic and their times ``(N,)`` (header stamps),
    in time order. Without ``topic``: the one ``Image`` or ``CompressedImage`` topic with the most
    messages. Every image must have the same size."""
    p = Path(path)
    topics = bag_topics(p)
    cameras = {t: n for t, (k, n) in topics.items() if k in (IMAGE, COMPRESSED_IMAGE)}
    if topic is not None:
        names = {topic, "/" + topic.lstrip("/")}
        cameras = {t: n for t, n in cameras.items() if t in names}
    if not cameras:
        named = f" named {topic!r}" if topic else ""
        raise BagError(
            f"no camera topic{named} (sensor_msgs/Image or CompressedImage; topics: {_describe(topics)})",
            path=p,
        )
    found = max(cameras, key=lambda t: (cameras[t], t))
    times: list[float] = []
    images: list[NDArray[np.uint8]] = []
    with _open(p) as reader:
        conns = [c for c in reader.connections if c.topic == found]
        for k, (conn, bag_ns, raw) in enumerate(reader.messages(connections=conns)):
            msg = reader.deserialize(raw, conn.msgtype)
            image = _grey(msg, conn.msgtype, p, f"{found} message {k}")
            if images and image.shape != images[0].shape:
                raise BagError(
                    f"{found} message {k} is {image.shape[1]}x{image.shape[0]}, the first was "
                    f"{images[0].shape[1]}x{images[0].shape[0]}",
                    path=p,
                )
            times.append(_stamp(msg.header, bag_ns))
            images.append(image)
    order = np.argsort(np.array(times), kind="stable")
    stack = np.stack(images)[order] if images else np.zeros((0, 0, 0), dtype=np.uint8)
    return np.asarray(times, dtype=np.float64)[order], stack


_CHANNELS = {"mono8": 1, "mono16": 1, "rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4}


def _grey(msg: Any, msgtype: str, path: Path, where: str) -> NDArray[np.uint8]:
    import cv2

    if msgtype == COMPRESSED_IMAGE:
        img = cv2.imdecode(np.asarray(msg.data, dtype=np.uint8), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise BagError(f"{where}: not a PNG or JPEG image (format {msg.format!r})", path=path)
        return np.asarray(img, dtype=np.uint8)
    enc = str(msg.encoding).lower()
    if enc not in _CHANNELS:
        raise BagError(f"{where}: encoding {msg.encoding!r} is not one of {', '.join(_CHANNELS)}", path=path)
    depth = 2 if enc == "mono16" else 1
    h, w, step, ch = int(msg.height), int(msg.width), int(msg.step), _CHANNELS[enc]
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < w * ch * depth or data.size < h * step:
        raise BagError(f"{where}: {data.size} bytes for {w}x{h} {enc} with step {step}", path=path)
    rows = data[: h * step].reshape(h, step)[:, : w * ch * depth]
    if depth == 2:
        big = bool(msg.is_bigendian)
        return (rows.view(">u2" if big else "<u2").reshape(h, w) >> 8).astype(np.uint8)
    pixels = rows.reshape(h, w, ch)
    if ch == 1:
        return np.ascontiguousarray(pixels[:, :, 0])
    code = {
        "rgb8": cv2.COLOR_RGB2GRAY,
        "bgr8": cv2.COLOR_BGR2GRAY,
        "rgba8": cv2.COLOR_RGBA2GRAY,
        "bgra8": cv2.COLOR_BGRA2GRAY,
    }[enc]
    return np.asarray(cv2.cvtColor(np.ascontiguousarray(pixels), code), dtype=np.uint8)
