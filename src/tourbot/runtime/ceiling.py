"""The ceiling camera's pose tracker as a runtime estimator (``tourbot.interfaces.Estimator``).

It follows the wheel odometry from the runtime's records and corrects the pose with each image of
the upward camera given to :meth:`CeilingEstimator.on_image` (light detection, then
:class:`tourbot.ceiling.tracking.CeilingTracker`). Its estimate goes into the snapshot's ``estimators``
under ``"ceiling"``: the pose, how it was obtained, and the hypotheses of an ambiguous image.
"""

from __future__ import annotations

from typing import Any

from tourbot.ceiling.detection import DetectionConfig, detect_lights
from tourbot.ceiling.tracking import CeilingTracker, TrackState
from tourbot.interfaces import EstimatorOutput, PoseBelief, ScanShare
from tourbot.records import Image, Odometry, Scan

__all__ = ["CeilingEstimator"]


class CeilingEstimator:
    """Odometry and ceiling images in, the camera's pose estimate out."""

    name = "ceiling"
    scan_share = ScanShare.ALL

    def __init__(self, tracker: CeilingTracker, detection: DetectionConfig | None = None) -> None:
        self.tracker = tracker
        self.detection = detection or DetectionConfig()
        self.images = 0

    def on_odometry(self, odom: Odometry) -> None:
        self.tracker.on_odometry(odom.pose)

    def on_scan(self, scan: Scan, belief: PoseBelief) -> None:
        """Scans carry nothing for the ceiling camera."""

    def on_image(self, image: Image, belief: PoseBelief | None = None) -> TrackState | None:  # noqa: ARG002
        """One image of the upward camera (images of other cameras are not for it)."""
        if image.camera != "ceiling":
            return None
        self.images += 1
        det = detect_lights(image.pixels, self.tracker.localizer.camera, self.detection)
        return self.tracker.on_detections(image.timestamp, det.centroids)

    def state(self) -> EstimatorOutput:
        st = self.tracker.state
        out: dict[str, Any] = {"time": st.time, "pose": st.pose, "how": st.how, "images": self.images}
        if st.hypotheses is not None and st.hypotheses.ambiguous:
            out["hypotheses"] = [h.pose for h in st.hypotheses.hypotheses]
        return EstimatorOutput(extra=out)
