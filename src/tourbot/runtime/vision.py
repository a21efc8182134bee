"""The forward camera's obstacle detector as a runtime estimator (``tourbot.interfaces.ImageEstimator``).

Each scan is kept with the pose estimate it came with; each image of the forward camera is placed
at that estimate moved on by the odometry between the scan and the image (the robot's motion
``u_{t-1}`` of Burgard et al., Sec. 3), paired with the previous image once the robot has moved
``min_baseline`` (not across a turn of more than ``max_turn``), and given to
:class:`tourbot.vision.detector.VisionDetector`.
The detections go into :class:`tourbot.vision.occupancy.VisionMap`; the map's obstacle cells are
published in the snapshot under ``estimators["vision"]["obstacles"]`` (world points), where the
navigator takes them as obstacles beside the laser's.

The pose estimate's uncertainty is used too: an image pair is placed in the world by one estimate,
so an error ``(dx, dy, dtheta)`` of it moves a detection at ``(ax, ay)`` from the robot by
``(dx - ay dtheta, dy + ax dtheta)``. Each obstacle and floor point's evidence in the map is
scaled by the probability that this error, Gaussian with the estimate's covariance (taken
isotropic at its largest spread), moves it less than ``pose_tolerance``
(:func:`evidence_weights`); a pair whose estimate leaves even a point at the robot's own position
below ``min_pose_weight`` is not used at all (``uncertain`` counts them): the robot does not map
what it cannot place.

Visitors leave no phantom obstacles: the people tracker's visitors (``people``, the robot's one
:class:`tourbot.people.estimator.PeopleEstimator`, its confirmed tracks moved on to each image's
time) are masked as upright bodies in both images of a pair (``VisionConfig.person_radius``); a
visitor the tracker has not confirmed yet is masked by the laser alone (the image columns of laser
endpoints that moved between the two scans, ``VisionConfig.moving``, ``body``); what stays is
erased by the floor seen free again (the map's persistence).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tourbot.geometry import compose, relative
from tourbot.interfaces import EstimatorOutput, PoseBelief, ScanShare
from tourbot.maps.grid import OccupancyGrid
from tourbot.people.estimator import PeopleEstimator
from tourbot.records import Image, Odometry, Scan
from tourbot.vision.camera import ForwardCamera
from tourbot.vision.detector import Detection, View, VisionConfig, VisionDetector
from tourbot.vision.model import scan_endpoints
from tourbot.vision.occupancy import VisionMap

__all__ = ["VisionEstimatorConfig", "VisionObstacleEstimator", "evidence_weights"]

FloatArray = NDArray[np.float64]


def evidence_weights(
    pose: ArrayLike, covariance: ArrayLike, points: ArrayLike, tolerance: float
) -> FloatArray:
    """How sure a view placed at ``pose`` (covariance ``(3, 3)`` of x, y, theta) is of each world
    point ``(N, 2)``: ``P(|e| < tolerance)`` for the point's displacement ``e`` by the pose's error.

    The displacement's covariance is ``J C J^T`` with ``J = [[1, 0, -ay], [0, 1, ax]]``, ``(ax, ay)``
    the point relative to the pose's position; taken isotropic with its largest eigenvalue
    ``s^2``, ``|e|`` is Rayleigh distributed: ``1 - exp(-tolerance^2 / (2 s^2))`` (1 for ``s = 0``).
    """
    c = np.asarray(covariance, dtype=np.float64).reshape(3, 3)
    c = 0.5 * (c + c.T)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    origin = np.asarray(pose, dtype=np.float64).reshape(3)
    ax, ay = pts[:, 0] - origin[0], pts[:, 1] - origin[1]
    sxx, syy, stt, sxy, sxt, syt = c[0, 0], c[1, 1], c[2, 2], c[0, 1], c[0, 2], c[1, 2]
    a = sxx - 2.0 * ay * sxt + ay * ay * stt
    d = syy + 2.0 * ax * syt + ax * ax * stt
    b = sxy + ax * sxt - ay * syt - ax * ay * stt
    largest = np.maximum(0.5 * (a + d) + np.sqrt(0.25 * (a - d) ** 2 + b * b), 0.0)
    with np.errstate(divide="ignore"):
        weights = -np.expm1(-(tolerance * tolerance) / (2.0 * largest))
    return np.asarray(weights, dtype=np.float64)


@dataclass(frozen=True)
class VisionEstimatorConfig:
    """``detector``: the detector's parameters; ``min_baseline`` (m): travel needed between paired
    images; ``max_turn`` (rad): images farther apart in heading are not paired (the robot turns on
    the spot; the odometry's turn is its least exact part); ``footprint``: radius (m) about the
    robot's centre where vision cells are forgotten: it stands there, and the camera, blind nearer
    than ``detector.min_distance``, could never clear a phantom that close (with the robot's own
    radius, 0.3 m, one phantom 0.39 m from the centre held a robot still for the rest of its tour,
    FHW seed 6); ``map_margin``:
    detections this close to the static map's obstacles are the map's (m); ``camera``: the images
    it takes; ``pose_tolerance`` (m): the displacement by the pose's error within which a point
    still counts as where it is placed (the 10 cm of the detection target); ``min_pose_weight``:
    a pair whose pose leaves a point at the robot itself less sure than this is skipped (with the
    defaults: a position spread above about 13 cm)."""

    detector: VisionConfig = field(default_factory=VisionConfig)
    min_baseline: float = 0.08
    max_turn: float = math.radians(4.0)
    footprint: float = 0.45
    map_margin: float = 0.2
    camera: str = "forward"
    pose_tolerance: float = 0.1
    min_pose_weight: float = 0.25


class VisionObstacleEstimator:
    """Scans, forward images and pose estimates in; the map of obstacles the laser misses out."""

    name = "vision"
    scan_share = ScanShare.ALL

    def __init__(
        self,
        frame: OccupancyGrid,
        camera: ForwardCamera,
        config: VisionEstimatorConfig | None = None,
        *,
        people: PeopleEstimator | None = None,
    ) -> None:
        self.config = cfg = config or VisionEstimatorConfig()
        self._people = people
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
        self.uncertain = 0  # pairs skipped: the pose that places them too uncertain
        self._scan: tuple[Scan, FloatArray, FloatArray] | None = None
        self._prev: View | None = None
        self._prev_odom: FloatArray | None = None
        self._prev_cov: FloatArray = np.zeros((3, 3))
        self._points: tuple[tuple[float, float], ...] = ()
        self._version = -1

    def on_odometry(self, odom: Odometry) -> None:
        """The odometry reaches it with each image (``Image.odom``)."""

    def on_scan(self, scan: Scan, belief: PoseBelief) -> None:
        est = belief.estimate
        self._scan = (
            scan,
            np.asarray(est.pose, dtype=np.float64),
            np.asarray(est.covariance, dtype=np.float64).reshape(3, 3),
        )

    def on_image(self, image: Image, belief: PoseBelief | None = None) -> Detection | None:  # noqa: ARG002
        """One forward image: placed at the latest estimate moved on by the odometry since."""
        cfg = self.config
        if image.camera != cfg.camera or self._scan is None or image.odom is None:
            return None
        scan, est, cov = self._scan
        if scan.odom is None:
            return None
        self.images += 1
        odom = np.asarray(image.odom, dtype=np.float64)
        pose = compose(est, relative(np.asarray(scan.odom), odom))
        endpoints, returned = scan_endpoints(scan, est)
        visitors = np.zeros((0, 2)) if self._people is None else self._people.positions(image.timestamp)
        view = View(image.pixels, pose, endpoints, returned, visitors)
        self.map.clear(pose[:2], cfg.footprint)  # at every image: the robot may stand still
        prev = self._prev
        if prev is None or self._prev_odom is None:
            self._prev, self._prev_odom, self._prev_cov = view, odom, cov
            return None
        motion = relative(self._prev_odom, odom)
        turned = abs(motion[2]) > cfg.max_turn
        if not turned and math.hypot(motion[0], motion[1]) < cfg.min_baseline:
            return None
        placed = self._prev_cov  # the two images are placed by the earlier one's estimate
        sure = evidence_weights(prev.pose, placed, prev.pose[None, :2], cfg.pose_tolerance)[0]
        uncertain = not turned and sure < cfg.min_pose_weight
        if turned or uncertain:
            # turning: the odometry's turn is least exact and the baseline short; uncertain: the
            # robot does not know well enough where it is to place what it sees; start afresh
            self.uncertain += uncertain
            self._prev, self._prev_odom, self._prev_cov = view, odom, cov
            return None
        # the two images placed by one estimate and the odometry between them (short-term exact)
        view = View(image.pixels, compose(prev.pose, motion), endpoints, returned, visitors)
        det = self.add_pair(prev, view, placed)
        self._prev, self._prev_odom = View(image.pixels, pose, endpoints, returned, visitors), odom
        self._prev_cov = cov
        return det

    def add_pair(self, prev: View, cur: View, covariance: FloatArray) -> Detection:
        """Detect in one pair of views placed by an estimate of covariance ``covariance`` ``(3, 3)``
        and accumulate the detection into the map (what :meth:`on_image` does with each pair; a
        replay of recorded pairs calls it directly)."""
        cfg = self.config
        t0 = time.perf_counter()
        det = self.detector.detect(prev, cur)
        obstacles = self._off_map(det.obstacles)
        self.map.update(
            obstacles,
            det.floor,
            evidence_weights(prev.pose, covariance, obstacles, cfg.pose_tolerance),
            evidence_weights(prev.pose, covariance, det.floor, cfg.pose_tolerance),
        )
        self.map.clear(cur.pose[:2], cfg.footprint)
        self.seconds += time.perf_counter() - t0
        self.pairs += 1
        self.last = (prev, cur, det)
        if self.best is None or len(det.obstacles) > len(self.best[2].obstacles):
            self.best = self.last
        return det

    def _off_map(self, points: FloatArray) -> FloatArray:
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
