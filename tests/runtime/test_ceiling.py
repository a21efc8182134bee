"""The ceiling tracker as a runtime estimator: odometry records and images in, its pose out."""

from __future__ import annotations

import math

import numpy as np

from tourbot.ceiling.minimize import CeilingLocalizer
from tourbot.ceiling.rig import CeilingCamera
from tourbot.ceiling.tracking import CeilingTracker
from tourbot.interfaces import Estimator, ImageEstimator
from tourbot.records import Image, Odometry
from tourbot.runtime.ceiling import CeilingEstimator
from tourbot.sim.camera import CeilingCameraSim
from tourbot.site.default import site_path
from tourbot.site.model import load_site


def test_estimator_follows_odometry_between_images() -> None:
    site = load_site(site_path("domus"))
    cam = CeilingCamera()
    lights = np.array([light.position for light in site.ceiling_lights])
    est = CeilingEstimator(CeilingTracker(CeilingLocalizer(cam, lights, site.grid)))
    assert isinstance(est, Estimator)
    assert isinstance(est, ImageEstimator)
    sim = CeilingCameraSim(site, cam, seed=0)
    assert est.state().extra["how"] == "lost"
    pose = np.array([0.0, -7.0, 0.0])
    est.on_odometry(Odometry(0.0, (10.0, 5.0, 1.0)))  # the odometry frame is not the map's
    st = est.on_image(Image(0.0, sim.frame(0.0, pose).image, camera="ceiling"))
    assert st is not None
    assert st.how == "global"
    for k in range(1, 11):
        est.on_odometry(
            Odometry(0.1 * k, (10.0 + 0.05 * k * math.cos(1.0), 5.0 + 0.05 * k * math.sin(1.0), 1.0))
        )
    moved = est.state().extra
    assert moved["images"] == 1
    # the tracker carries the pose by the odometry's motion until the next image
    assert est.tracker.pose is not None
    assert abs(est.tracker.pose[0] - 0.5) < 0.05
    st = est.on_image(Image(1.0, sim.frame(1.0, pose + np.array([0.5, 0.0, 0.0])).image, camera="ceiling"))
    assert st is not None
    assert st.how == "tracked"
    assert st.pose is not None
    assert math.hypot(st.pose[0] - 0.5, st.pose[1] + 7.0) < 0.05
