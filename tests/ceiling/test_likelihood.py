"""The camera as an MCL sensor: its likelihood through MCL's ``weigh`` seam, its hypotheses through
``inject``, and the restart of a kidnapped track from two unambiguous images."""

from __future__ import annotations

import math

import numpy as np

from tourbot.ceiling.likelihood import CeilingLikelihood, CeilingSensor, FusionConfig, recovery_poses
from tourbot.ceiling.minimize import CeilingLocalizer
from tourbot.ceiling.rig import CeilingCamera
from tourbot.geometry import compose
from tourbot.localization.mcl import MonteCarloLocalization
from tourbot.sim.camera import CameraSimConfig, CeilingCameraSim
from tourbot.site.default import site_path
from tourbot.site.model import Site, load_site

TRUTH = np.array([8.0, -7.0, 1.0])


def _domus() -> tuple[Site, CeilingCamera, np.ndarray]:
    site = load_site(site_path("domus"))
    return site, CeilingCamera(), np.array([light.position for light in site.ceiling_lights])


def test_ceiling_likelihood_weighs_the_true_pose_highest_and_injects_hypotheses() -> None:
    site, cam, lights = _domus()
    uv, seen = cam.project_lights(TRUTH[None], lights)
    det = uv[0][seen[0]]
    lik = CeilingLikelihood(cam, lights)
    assert np.all(lik.log_likelihood(np.zeros((4, 3))) == 0.0)  # no measurement yet: no information
    lik.set_detections(det)
    mcl = MonteCarloLocalization(site.grid, seed=0)
    mcl.reset_tracking(TRUTH + np.array([2.0, 1.0, 0.0]), np.diag([4.0, 4.0, 1.0]))
    mcl.samples[17] = TRUTH + np.array([0.05, -0.03, 0.01])
    mcl.weigh((0.0, 0.0, 0.0), lik)
    assert int(np.argmax(mcl.weights)) == 17
    # the camera's hypotheses, offered to a kidnapped filter, contain the truth
    result = CeilingLocalizer(cam, lights, site.grid).locate(det, np.random.default_rng(0))
    poses = recovery_poses(result)
    assert poses.shape[1] == 3
    assert min(math.hypot(p[0] - TRUTH[0], p[1] - TRUTH[1]) for p in poses) < 0.05


def test_sensor_offers_hypotheses_and_restarts_a_kidnapped_track_after_two_agreeing_images() -> None:
    site, cam, lights = _domus()
    render = CeilingCameraSim(site, cam, CameraSimConfig(swing_std_deg=0.0), seed=3)
    sensor = CeilingSensor(cam, lights, site.grid, FusionConfig(offered=4), seed=1)
    m = sensor.measure(render.frame(0.0, TRUTH).image)
    assert len(m.detections) >= 3
    assert m.hypotheses is not None
    assert not m.hypotheses.ambiguous
    assert m.offered.shape == (4 * len(m.hypotheses.hypotheses), 3)
    assert np.all(np.hypot(m.offered[:, 0] - TRUTH[0], m.offered[:, 1] - TRUTH[1]) < 0.6)
    assert m.reset is None  # no estimate given: nothing to restart
    # the estimate agrees with the image: no restart, however often
    for t in (1.0, 2.0):
        assert sensor.measure(render.frame(t, TRUTH).image, TRUTH + 0.1, (0.0, 0.0, 0.0)).reset is None
    # kidnapped: the estimate is 4 m off; one image is not enough, the second (after a 0.5 m drive
    # the odometry saw) restarts the track at the camera's fix
    wrong = TRUTH + np.array([4.0, 0.0, 0.0])
    assert sensor.measure(render.frame(3.0, TRUTH).image, wrong, (0.0, 0.0, 0.0)).reset is None
    moved = compose(TRUTH, np.array([0.5, 0.0, 0.0]))
    reset = sensor.measure(render.frame(4.0, moved).image, wrong, (0.5, 0.0, 0.0)).reset
    assert reset is not None
    assert math.hypot(reset[0] - moved[0], reset[1] - moved[1]) < 0.1
    # two far fixes that the odometry cannot connect (it saw no motion) restart nothing
    sensor.measure(render.frame(5.0, TRUTH).image, wrong, (0.0, 0.0, 0.0))
    assert sensor.measure(render.frame(6.0, moved).image, wrong, (0.0, 0.0, 0.0)).reset is None


def test_a_symmetric_ceiling_never_restarts_the_track() -> None:
    # FHW's lights are a regular 4 m grid: no image is unambiguous, the hypotheses go to recovery
    site = load_site(site_path("fhw"))
    cam = CeilingCamera()
    lights = np.array([light.position for light in site.ceiling_lights])
    render = CeilingCameraSim(site, cam, CameraSimConfig(swing_std_deg=0.0), seed=0)
    sensor = CeilingSensor(cam, lights, site.grid, seed=0)
    truth = np.array([1.2, 7.27, 0.95])
    wrong = truth + np.array([5.0, 0.0, 0.0])
    resets = [
        sensor.measure(render.frame(float(t), truth).image, wrong, (0.0, 0.0, 0.0)).reset for t in range(3)
    ]
    assert resets == [None, None, None]
    m = sensor.measure(render.frame(3.0, truth).image)
    assert m.hypotheses is not None
    assert m.hypotheses.ambiguous
    assert len(m.offered) > 0
