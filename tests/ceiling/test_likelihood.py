"""The camera as an MCL sensor (the ``PoseLikelihood`` seam) and its hypotheses for recovery."""

from __future__ import annotations

import math

import numpy as np

from tourbot.ceiling.likelihood import CeilingLikelihood, recovery_poses
from tourbot.ceiling.minimize import CeilingLocalizer
from tourbot.ceiling.rig import CeilingCamera
from tourbot.site.default import site_path
from tourbot.site.model import load_site


class _TinyMCL:
    """A stand-in for the seam of ``tourbot.localization.mcl`` until it lands: weights samples with
    the extra likelihoods and takes injected poses."""

    def __init__(self, samples: np.ndarray, extra: list[CeilingLikelihood]) -> None:
        self.samples = samples
        self.extra = extra
        self.log_w = np.zeros(len(samples))

    def weigh(self) -> np.ndarray:
        for lik in self.extra:
            self.log_w = self.log_w + lik.log_likelihood(self.samples)
        w = np.exp(self.log_w - self.log_w.max())
        return w / w.sum()

    def inject(self, poses: np.ndarray) -> None:
        self.samples[: len(poses)] = poses
        self.log_w[: len(poses)] = 0.0


def test_ceiling_likelihood_weighs_the_true_pose_highest_and_injects_hypotheses() -> None:
    site = load_site(site_path("domus"))
    cam = CeilingCamera()
    lights = np.array([light.position for light in site.ceiling_lights])
    truth = np.array([8.0, -7.0, 1.0])
    uv, seen = cam.project_lights(truth[None], lights)
    det = uv[0][seen[0]]
    lik = CeilingLikelihood(cam, lights)
    assert np.all(lik.log_likelihood(np.zeros((4, 3))) == 0.0)  # no measurement yet: no information
    lik.set_detections(det)
    rng = np.random.default_rng(0)
    samples = np.column_stack([rng.uniform(-8, 28, 500), rng.uniform(-12, 4, 500), rng.uniform(-3, 3, 500)])
    samples[17] = truth + np.array([0.05, -0.03, 0.01])
    mcl = _TinyMCL(samples.copy(), [lik])
    w = mcl.weigh()
    assert int(np.argmax(w)) == 17
    # a kidnapped filter (no sample near the truth) gets the camera's hypotheses injected
    result = CeilingLocalizer(cam, lights, site.grid).locate(det, rng)
    poses = recovery_poses(result)
    assert poses.shape[1] == 3
    assert len(poses) >= 1
    far = _TinyMCL(samples[np.hypot(samples[:, 0] - 8.0, samples[:, 1] + 7.0) > 3.0].copy(), [lik])
    far.inject(poses)
    best = far.samples[int(np.argmax(far.weigh()))]
    assert math.hypot(best[0] - truth[0], best[1] - truth[1]) < 0.05
