"""The forward camera's obstacle detector as a runtime estimator (``tourbot.interfaces.ImageEstimator``).

Each scan is kept with the pose estimate it came with; each image of the forward camera is placed
at that estimate moved on by the odometry between the scan and the image (the robot's motion
``u_{t-1}`` of Burgard et al., Sec. 3), paired with the previous image once the robot has moved
``min_baseline`` (not across a turn of more than ``max_turn``), and given to
:class:`tourbot.vision.detector.VisionDetector`.
The detections go into :class:`tourbot.vision.occupancy.VisionMap`; the map's obstacle cells are
published in the snapshot under ``estimators["vision"]["obstacles"]`` (world points), where the
navigator takes them as obstacles beside the laser's.

Visitors leave no phantom obstacles: the laser sees them, and the image columns of laser endpoints
that moved between the two scans are masked (``VisionConfig.moving``, ``body``); what stays
(a visitor who stood, then left) is erased by the floor seen free again (the map's persistence).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tourbot.geometry import compose, relative
from tourbot.interfaces import EstimatorOutput, PoseBelief, ScanShare
from tourbot.maps.grid import OccupancyGrid
from tourbot.records import Image, Odometry, Scan
from tourbot.vision.camera import ForwardCamera
from tourbot.vision.detector import Detection, View, VisionConfig, VisionDetector
from tourbot.vision.model import scan_endpoints
from tourbot.vision.occupancy import VisionMap

__all__ = ["VisionEstimatorConfig", "VisionObstacleEstimator"]


@dataclass(frozen=True)
class VisionEstimatorConfig:
    """``detector``: the detector's parameters; ``min_baseline`` (m): travel needed between paired
    images; ``max_turn`` (rad): images farther apart in heading are not paired (the robot turns on
    the spot; the odometry's turn is its least exact part); ``footprint``: radius (m) about the
    robot's centre where vision cells are forgotten: it stands there, and the camera, blind nearer
    than ``detector.min_distance``, could never clear a phantom that close; ``map_margin``:
    detections this close to the static map's obstacles are the map's (m); ``camera``: the images
    it takes."""

    detector: VisionConfig = field(default_factory=VisionConfig)
    min_baseline: float = 0.08
    max_turn: float = math.radians(4.0)
    footprint: float = 0.45
    map_margin: float = 0.2
    camera: str = "forward"


class VisionObstacleEstimator:
    """Scans, forward images and pose estimates in; the map of obstacles the laser misses out."""

    name = "vision"
    scan_share = ScanShare.ALL

    def __init__(
        self, frame: OccupancyGrid, camera: ForwardCamera, config: VisionEstimatorConfig | None = None
    ) -> None:
        self.config = cfg = config or VisionEstimatorConfig()
        self.detector = VisionDetector(camera, cfg.detector)
        self.map = VisionMap(frame)
        self._static = frame
        from scipy import ndimage

        self._static_clearance = ndimage.distance_transform_edt(~frame.occupied()) * frame.resolution
        self.images = 0
        self.pairs = 0
        self.seconds = 0.0
        self.last: tuple[View, View, Detection] | None = None
        self.best: tuple[View, View, Detection] | None = None  # the pair with the most detections
        self._scan: tuple[Scan, NDArray[np.float64]] | None = None
        self._prev: View | None = None
        self._prev_odom: NDArray[np.float64] | None = None
        self._points: tuple[tuple[float, float], ...] = ()
        self._version = -1

    def on_odometry(self, odom: Odometry) -> None:
        """The odometry reaches it with each image (``Image.odom``)."""

    def on_scan(self, scan: Scan, belief: PoseBelief) -> None:
        self._scan = (scan, np.asarray(belief.estimate.pose, dtype=np.float64))

    def on_image(self, image: Image, belief: PoseBelief | None = None) -> Detection | None:  # noqa: ARG002
        """One forward image: placed at the latest estimate moved on by the odometry since."""
        cfg = self.config
        if image.camera != cfg.camera or self._scan is None or image.odom is None:
            return None
        scan, est = self._scan
        if scan.odom is None:
            return None
        self.images += 1
        odom = np.asarray(image.odom, dtype=np.float64)
        pose = compose(est, relative(np.asarray(scan.odom), odom))
        endpoints, returned = scan_endpoints(scan, est)
        view = View(image.pixels, pose, endpoints, returned)
        self.map.clear(pose[:2], cfg.footprint)  # at every image: the robot may stand still
        prev = self._prev
        if prev is None or self._prev_odom is None:
            self._prev, self._prev_odom = view, odom
            return None
        motion = relative(self._prev_odom, odom)
        if abs(motion[2]) > cfg.max_turn:
            # turning: the odometry's turn is least exact and the baseline short; start afresh
            self._prev, self._prev_odom = view, odom
            return None
        if math.hypot(motion[0], motion[1]) < cfg.min_baseline:
            return None
        # the two images placed by one estimate and the odometry between them (short-term exact)
        view = View(image.pixels, compose(prev.pose, motion), endpoints, returned)
        t0 = time.perf_counter()
        det = self.detector.detect(prev, view)
        self.map.update(self._off_map(det.obstacles), det.floor)
        self.map.clear(view.pose[:2], cfg.footprint)
        self.seconds += time.perf_counter() - t0
        self.pairs += 1
        self.last = (prev, view, det)
        if self.best is None or len(det.obstacles) > len(self.best[2].obstacles):
            self.best = self.last
        self._prev, self._prev_odom = View(image.pixels, pose, endpoints, returned), odom
        return det

    def _off_map(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """The points farther than ``map_margin`` from the static map's obstacles: what is on the map
        (walls, seen through the gaps of a map drawn from laser returns) is already in the costmap."""
        if not len(points):
            return points
        cells = self._static.world_to_cell(points)
        ok = self._static.inside(cells)
        keep = np.ones(len(points), dtype=bool)
        keep[ok] = self._static_clearance[cells[ok, 0], cells[ok, 1]] > self.config.map_margin
        return points[keep]

    def obstacle_points(self) -> tuple[tuple[float, float], ...]:
        """World centres of the vision obstacle cells (cached until the map changes)."""
        if self._version != self.map.version:
            self._version = self.map.version
            self._points = tuple((float(x), float(y)) for x, y in self.map.obstacle_points())
        return self._points

    def state(self) -> EstimatorOutput:
        return EstimatorOutput(extra={"obstacles": self.obstacle_points(), "images": self.images})
