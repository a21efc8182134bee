"""The ROS 2 messages of a tourbot run (Humble type store of ``rosbags.typesys``, CDR-serialized),
one home for every output that speaks ROS 2: an MCAP file (:class:`tourbot.io.mcap_out.McapRun`)
and the live Foxglove server (:class:`tourbot.io.foxglove_live.FoxgloveLive`).

:class:`Ros2Channels` builds the messages; a subclass says where the serialized bytes go
(``_emit``). The channels:

- ``/map`` ``nav_msgs/msg/OccupancyGrid``, with transient-local durability (latched): the map
  localized in, once at the first time of the run; a map being built (``tourbot slam``), as it
  grows and finished at the end, each replacing the last; cells are ``round(100 * p)`` for a
  known probability ``p`` of occupancy and ``-1`` where the map knows nothing; ``data`` is
  row-major from the cell at ``origin``, as :class:`tourbot.maps.grid.OccupancyGrid` stores it;
- ``/scan`` ``sensor_msgs/msg/LaserScan`` in frame ``laser``;
- ``/odom`` ``nav_msgs/msg/Odometry``: the odometry pose (frame ``odom``, child ``base_link``);
  the log gives no twist or covariance with it, so both are zero;
- ``/tf`` ``tf2_msgs/msg/TFMessage``: ``odom -> base_link`` with each odometry message,
  ``map -> odom`` with each estimate (the estimate composed with the inverse of the odometry pose
  it was computed from) and ``base_link -> laser`` (the laser's mounting offset) with each scan;
- ``/estimate`` ``geometry_msgs/msg/PoseWithCovarianceStamped`` (frame ``map``; the x, y, yaw
  covariance placed at rows/columns 0, 1 and 5 of the 6 x 6 matrix);
- ``/particles`` ``geometry_msgs/msg/PoseArray`` (frame ``map``), at most :data:`MAX_PARTICLES`
  poses, evenly spaced through the sample set;
- ``/beams`` ``visualization_msgs/msg/MarkerArray``: the end points of the beams the localizer
  integrated (namespace ``integrated``, green) and of the in-range beams it rejected (namespace
  ``rejected``, red), as ``POINTS`` markers in frame ``laser``;
- ``/ceiling/image`` ``sensor_msgs/msg/Image`` (``mono8``, frame ``ceiling_camera``): the upward
  camera's images, where the run has them;
- ``/people`` ``visualization_msgs/msg/MarkerArray``: the people the robot tracks, as
  ``CYLINDER`` markers (namespace ``people``, id = track id, frame ``map``) replacing the last set;
- ``/objects`` ``visualization_msgs/msg/MarkerArray``: doors and furniture in their estimated
  states (``tourbot objects``), each outline a closed ``LINE_STRIP`` (namespace ``objects``, id =
  the object's index; orange when observed, grey otherwise) and its name a ``TEXT_VIEW_FACING``
  marker (namespace ``names``, same id), frame ``map``, replacing the last set.

Times are seconds, written as integer nanoseconds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray
from rosbags.typesys import Stores, get_typestore

from tourbot.geometry import compose, invert
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import Image, Scan
from tourbot.snapshot import PersonState

if TYPE_CHECKING:
    from tourbot.maps.objects import ObjectShape

__all__ = ["MAX_PARTICLES", "STORE", "TOPICS", "Ros2Channels", "grid_cells", "message_definition"]

#: At most this many particles per ``PoseArray`` (a subsample, evenly spaced, of larger sets).
MAX_PARTICLES: Final = 500

#: Topic -> ROS 2 message type of every channel.
TOPICS: Final[dict[str, str]] = {
    "/map": "nav_msgs/msg/OccupancyGrid",
    "/scan": "sensor_msgs/msg/LaserScan",
    "/odom": "nav_msgs/msg/Odometry",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/estimate": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "/particles": "geometry_msgs/msg/PoseArray",
    "/beams": "visualization_msgs/msg/MarkerArray",
    "/people": "visualization_msgs/msg/MarkerArray",
    "/objects": "visualization_msgs/msg/MarkerArray",
    "/ceiling/image": "sensor_msgs/msg/Image",
}

#: The ROS 2 Humble type store the messages are built and serialized with.
STORE = get_typestore(Stores.ROS2_HUMBLE)
_MARKER_CYLINDER: Final = 3
_MARKER_LINE_STRIP: Final = 4
_MARKER_POINTS: Final = 8
_MARKER_TEXT: Final = 9
_OBSERVED_RGB: Final = (1.0, 0.55, 0.0)
_UNOBSERVED_RGB: Final = (0.6, 0.6, 0.6)
_MARKER_ADD: Final = 0
_MARKER_DELETEALL: Final = 3


def grid_cells(grid: OccupancyGrid) -> NDArray[np.int8]:
    """The map's cells as ``OccupancyGrid.data``: ``round(100 * p)``, ``-1`` unknown; row-major."""
    known = grid.prob >= 0.0
    cells = np.where(known, np.rint(100.0 * np.clip(grid.prob, 0.0, 1.0)), -1.0)
    return cells.astype(np.int8).ravel()


def _ns(seconds: float) -> int:
    return round(seconds * 1e9)


def message_definition(msgtype: str) -> str:
    """The ``ros2msg`` text of ``msgtype`` with its dependencies (as a schema for Foxglove or MCAP)."""
    text, _ = STORE.generate_msgdef(msgtype, ros_version=2)
    return str(text)


class Ros2Channels:
    """Builds the run's ROS 2 messages; ``_emit(topic, stamp_ns, data)`` says where they go."""

    def __init__(self) -> None:
        self._types = STORE.types

    def _emit(self, topic: str, stamp_ns: int, data: bytes) -> None:
        raise NotImplementedError

    def _write(self, topic: str, stamp_ns: int, msg: object) -> None:
        self._emit(topic, stamp_ns, bytes(STORE.serialize_cdr(msg, TOPICS[topic])))

    # ------------------------------------------------------------------ message parts

    def _header(self, stamp_ns: int, frame: str) -> Any:
        t = self._types
        sec, nanosec = divmod(stamp_ns, 1_000_000_000)
        return t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id=frame
        )

    def _pose(self, pose: ArrayLike) -> Any:
        t = self._types
        x, y, theta = (float(v) for v in np.asarray(pose, dtype=np.float64).reshape(3))
        return t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
            orientation=_quaternion(t, theta),
        )

    def _transform(self, stamp_ns: int, parent: str, child: str, pose: ArrayLike) -> Any:
        t = self._types
        x, y, theta = (float(v) for v in np.asarray(pose, dtype=np.float64).reshape(3))
        return t["geometry_msgs/msg/TransformStamped"](
            header=self._header(stamp_ns, parent),
            child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](x=x, y=y, z=0.0), rotation=_quaternion(t, theta)
            ),
        )

    def _tf(self, stamp_ns: int, parent: str, child: str, pose: ArrayLike) -> None:
        msg = self._types["tf2_msgs/msg/TFMessage"](
            transforms=[self._transform(stamp_ns, parent, child, pose)]
        )
        self._write("/tf", stamp_ns, msg)

    # ------------------------------------------------------------------ the channels

    def write_map(self, grid: OccupancyGrid, timestamp: float) -> None:
        """``/map``: the occupancy grid, once (latched), at ``timestamp`` (s, the run's first time)."""
        t = self._types
        stamp = _ns(timestamp)
        rows, cols = grid.prob.shape
        sec, nanosec = divmod(stamp, 1_000_000_000)
        info = t["nav_msgs/msg/MapMetaData"](
            map_load_time=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
            resolution=float(grid.resolution),
            width=cols,
            height=rows,
            origin=self._pose(grid.origin),
        )
        msg = t["nav_msgs/msg/OccupancyGrid"](
            header=self._header(stamp, "map"), info=info, data=grid_cells(grid)
        )
        self._write("/map", stamp, msg)

    def write_scan(self, scan: Scan) -> None:
        """``/scan`` (frame ``laser``) and the ``base_link -> laser`` transform of its geometry."""
        g = scan.geometry
        stamp = _ns(scan.timestamp)
        msg = self._types["sensor_msgs/msg/LaserScan"](
            header=self._header(stamp, "laser"),
            angle_min=float(g.angle_min),
            angle_max=float(g.angle_min + (g.num_beams - 1) * g.angle_increment),
            angle_increment=float(g.angle_increment),
            time_increment=0.0,
            scan_time=0.0,
            range_min=float(g.min_range),
            range_max=float(g.max_range),
            ranges=np.asarray(scan.ranges, dtype=np.float32),
            intensities=np.zeros(0, dtype=np.float32),
        )
        self._write("/scan", stamp, msg)
        self._tf(stamp, "base_link", "laser", g.offset)

    def write_image(self, image: Image) -> None:
        """``/<camera>/image`` (``mono8``): one 8-bit grey image of the camera named in the record."""
        pixels = np.ascontiguousarray(image.pixels, dtype=np.uint8)
        if pixels.ndim != 2:
            raise ValueError("write_image takes 8-bit grey images (height, width)")
        topic = f"/{image.camera}/image"
        if topic not in TOPICS:
            raise ValueError(f"no MCAP channel for camera {image.camera!r} (channels: {', '.join(TOPICS)})")
        stamp = _ns(image.timestamp)
        h, w = pixels.shape
        msg = self._types["sensor_msgs/msg/Image"](
            header=self._header(stamp, f"{image.camera}_camera"),
            height=h,
            width=w,
            encoding="mono8",
            is_bigendian=0,
            step=w,
            data=pixels.reshape(-1),
        )
        self._write(topic, stamp, msg)

    def write_odometry(
        self, odom_pose: ArrayLike, timestamp: float, tv: float = 0.0, rv: float = 0.0
    ) -> None:
        """``/odom`` (the odometry pose; the twist ``tv`` m/s and ``rv`` rad/s where known) and the
        ``odom -> base_link`` transform."""
        t = self._types
        stamp = _ns(timestamp)
        msg = t["nav_msgs/msg/Odometry"](
            header=self._header(stamp, "odom"),
            child_frame_id="base_link",
            pose=t["geometry_msgs/msg/PoseWithCovariance"](
                pose=self._pose(odom_pose), covariance=np.zeros(36, dtype=np.float64)
            ),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](
                    linear=t["geometry_msgs/msg/Vector3"](x=float(tv), y=0.0, z=0.0),
                    angular=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=float(rv)),
                ),
                covariance=np.zeros(36, dtype=np.float64),
            ),
        )
        self._write("/odom", stamp, msg)
        self._tf(stamp, "odom", "base_link", odom_pose)

    def write_estimate(
        self, pose: ArrayLike, covariance: ArrayLike, odom_pose: ArrayLike, timestamp: float
    ) -> None:
        """``/estimate`` and the ``map -> odom`` transform: ``pose`` composed with ``odom_pose``'s inverse.

        ``covariance`` is the ``(3, 3)`` covariance of x, y and theta.
        """
        t = self._types
        stamp = _ns(timestamp)
        cov3 = np.asarray(covariance, dtype=np.float64).reshape(3, 3)
        cov6 = np.zeros((6, 6))
        idx = np.array([0, 1, 5])
        cov6[np.ix_(idx, idx)] = cov3
        msg = t["geometry_msgs/msg/PoseWithCovarianceStamped"](
            header=self._header(stamp, "map"),
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=self._pose(pose), covariance=cov6.ravel()),
        )
        self._write("/estimate", stamp, msg)
        self._tf(stamp, "map", "odom", compose(pose, invert(odom_pose)))

    def write_particles(self, samples: ArrayLike, timestamp: float) -> None:
        """``/particles``: the sample poses ``(N, 3)`` (map frame), at most :data:`MAX_PARTICLES`."""
        poses = np.asarray(samples, dtype=np.float64).reshape(-1, 3)
        if len(poses) > MAX_PARTICLES:
            poses = poses[np.linspace(0, len(poses) - 1, MAX_PARTICLES).round().astype(int)]
        stamp = _ns(timestamp)
        msg = self._types["geometry_msgs/msg/PoseArray"](
            header=self._header(stamp, "map"), poses=[self._pose(p) for p in poses]
        )
        self._write("/particles", stamp, msg)

    def write_beams(self, scan: Scan, used: ArrayLike) -> None:
        """``/beams``: end points of the integrated beams (``used``) and of the rejected in-range ones.

        A beam at or beyond the sensor's maximum range has no end point and is in neither set.
        """
        t = self._types
        g = scan.geometry
        stamp = _ns(scan.timestamp)
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        used_b = np.asarray(used, dtype=bool).reshape(ranges.shape)
        in_range = np.isfinite(ranges) & (ranges < g.max_range) & (ranges > g.min_range)
        angles = g.angles
        markers = []
        for k, (ns, mask, rgb) in enumerate(
            [
                ("integrated", used_b & in_range, (0.1, 0.8, 0.2)),
                ("rejected", ~used_b & in_range, (0.9, 0.1, 0.1)),
            ]
        ):
            pts = [
                t["geometry_msgs/msg/Point"](x=float(r * math.cos(a)), y=float(r * math.sin(a)), z=0.0)
                for r, a in zip(ranges[mask], angles[mask], strict=True)
            ]
            markers.append(self._marker(stamp, "laser", ns, k, _MARKER_POINTS, rgb, pts))
        self._write("/beams", stamp, t["visualization_msgs/msg/MarkerArray"](markers=markers))

    def _marker(
        self,
        stamp: int,
        frame: str,
        ns: str,
        ident: int,
        kind: int,
        rgb: tuple[float, float, float],
        points: list[Any],
        action: int = _MARKER_ADD,
    ) -> Any:
        """A ``visualization_msgs/Marker`` of type ``kind`` (``action`` DELETEALL clears ``ns``)."""
        t = self._types
        return t["visualization_msgs/msg/Marker"](
            header=self._header(stamp, frame),
            ns=ns,
            id=ident,
            type=kind,
            action=action,
            pose=self._pose((0.0, 0.0, 0.0)),
            scale=t["geometry_msgs/msg/Vector3"](x=0.05, y=0.05, z=0.0),
            color=t["std_msgs/msg/ColorRGBA"](r=rgb[0], g=rgb[1], b=rgb[2], a=1.0),
            lifetime=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
            frame_locked=False,
            points=points,
            colors=[],
            texture_resource="",
            texture=t["sensor_msgs/msg/CompressedImage"](
                header=self._header(stamp, frame), format="", data=np.zeros(0, dtype=np.uint8)
            ),
            uv_coordinates=[],
            text="",
            mesh_resource="",
            mesh_file=t["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, dtype=np.uint8)),
            mesh_use_embedded_materials=False,
        )

    def write_people(self, people: Sequence[PersonState], timestamp: float) -> None:
        """``/people``: one cylinder per tracked person (map frame), replacing the last set."""
        t = self._types
        stamp = _ns(timestamp)
        markers = [
            self._marker(stamp, "map", "people", 0, _MARKER_CYLINDER, (0.0, 0.0, 0.0), [], _MARKER_DELETEALL)
        ]
        for p in people:
            m = self._marker(stamp, "map", "people", int(p.id), _MARKER_CYLINDER, (0.2, 0.4, 1.0), [])
            m.pose = t["geometry_msgs/msg/Pose"](
                position=t["geometry_msgs/msg/Point"](x=float(p.x), y=float(p.y), z=0.85),
                orientation=_quaternion(t, 0.0),
            )
            m.scale = t["geometry_msgs/msg/Vector3"](x=0.4, y=0.4, z=1.7)
            markers.append(m)
        self._write("/people", stamp, t["visualization_msgs/msg/MarkerArray"](markers=markers))

    def write_objects(
        self,
        shapes: Sequence[ObjectShape],
        states: Sequence[Sequence[float]],
        observed: Sequence[bool],
        timestamp: float,
        ids: Sequence[int] | None = None,
    ) -> None:
        """``/objects``: each object's outline in its state (``shapes[i].polygons``, map frame) as
        a closed line strip, orange where ``observed[i]`` else grey, and its name; replacing the last set.

        ``ids`` are the markers' ids (default: the positions in ``shapes``).
        """
        ids = list(range(len(shapes))) if ids is None else list(ids)
        if not len(shapes) == len(states) == len(observed) == len(ids):
            raise ValueError("write_objects takes one state, one observed flag and one id per shape")
        t = self._types
        stamp = _ns(timestamp)
        markers = [
            self._marker(
                stamp, "map", "objects", 0, _MARKER_LINE_STRIP, (0.0, 0.0, 0.0), [], _MARKER_DELETEALL
            )
        ]
        for i, shape, state, seen in zip(ids, shapes, states, observed, strict=True):
            outline = shape.polygons(np.asarray(state, dtype=np.float64)[None, :])[0]
            closed = np.vstack([outline, outline[:1]])
            pts = [t["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0) for x, y in closed]
            rgb = _OBSERVED_RGB if seen else _UNOBSERVED_RGB
            markers.append(self._marker(stamp, "map", "objects", i, _MARKER_LINE_STRIP, rgb, pts))
            label = self._marker(stamp, "map", "names", i, _MARKER_TEXT, rgb, [])
            cx, cy = (float(v) for v in outline.mean(axis=0))
            label.pose = t["geometry_msgs/msg/Pose"](
                position=t["geometry_msgs/msg/Point"](x=cx, y=cy, z=0.5), orientation=_quaternion(t, 0.0)
            )
            label.scale = t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.3)
            label.text = shape.name
            markers.append(label)
        self._write("/objects", stamp, t["visualization_msgs/msg/MarkerArray"](markers=markers))


def _quaternion(types: Any, theta: float) -> Any:
    """The rotation by ``theta`` about z."""
    return types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(theta / 2), w=math.cos(theta / 2))
