"""Tracking with the odometry motion model between rendered images, and recovery from a kidnap."""

from __future__ import annotations

import math

import numpy as np

from tourbot.ceiling.detection import detect_lights
from tourbot.ceiling.minimize import CeilingLocalizer
from tourbot.ceiling.rig import CeilingCamera
from tourbot.ceiling.tracking import CeilingTracker
from tourbot.geometry import compose
from tourbot.sim.camera import CameraSimConfig, CeilingCameraSim
from tourbot.site.default import site_path
from tourbot.site.model import load_site


def test_tracks_a_drifting_odometry_and_recovers_a_kidnap() -> None:
    site = load_site(site_path("domus"))
    cam = CeilingCamera()
    lights = np.array([light.position for light in site.ceiling_lights])
    sim = CeilingCameraSim(site, cam, CameraSimConfig(swing_std_deg=0.5), seed=2)
    tracker = CeilingTracker(CeilingLocalizer(cam, lights, site.grid), seed=0)
    pose = np.array([-5.0, -6.0, 0.0])
    odom = np.zeros(3)
    errors, hows = [], []
    for k in range(24):
        if k == 12:
            pose = pose + np.array([4.0, -1.5, 0.6])  # carried away; the odometry does not see it
        state = tracker.on_detections(float(k), detect_lights(sim.frame(float(k), pose).image, cam).centroids)
        assert state.pose is not None
        errors.append(math.hypot(state.pose[0] - pose[0], state.pose[1] - pose[1]))
        hows.append(state.how)
        for _ in range(10):  # 0.4 m/s, odometry 3 % long and turning 0.03 rad/m
            pose = compose(pose, [0.04, 0.0, 0.0])
            odom = compose(odom, [0.04 * 1.03, 0.0, 0.0012])
            tracker.on_odometry(odom)
    assert hows[0] == "global"
    assert hows[12] == "global"
    assert "tracked" in hows[1:12]
    assert "tracked" in hows[13:]
    assert max(errors) < 0.15
    assert float(np.mean(errors)) < 0.06
