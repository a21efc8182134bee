"""The runtime's MCL adapter: the belief it hands to the estimators that integrate over the pose."""

from __future__ import annotations

import numpy as np

from tourbot.localization.mcl import MCLConfig, MonteCarloLocalization
from tourbot.runtime.localizers import MCLLocalizer, UpdatePolicy
from tourbot.sim.object_scenes import corridor_scene, run_scene


def test_the_belief_leaves_out_recoverys_guesses_but_the_display_shows_them() -> None:
    scene = corridor_scene(states_deg=(0, 90))
    log = run_scene(scene, seed=0).log
    ref = log.reference_poses
    mcl = MonteCarloLocalization(scene.model.grid, MCLConfig(), seed=0)
    mcl.reset_tracking(ref[0])
    loc = MCLLocalizer(mcl, UpdatePolicy(beam_step=1, min_travel=0.0, min_turn=0.0, max_interval=0.0))
    guesses = 0
    for k, scan in enumerate(log.scans[:12]):
        if k == 3:  # recovery is offered guesses 5 m down the corridor, in free space
            mcl.inject(np.tile([ref[k, 0] + 5.0, 0.0, 0.0], (400, 1)))
        belief = loc.on_scan(scan)
        assert belief is not None
        fresh = mcl.recovery.fresh
        guesses = max(guesses, int(fresh.sum()))
        track = np.array([belief.estimate.x, belief.estimate.y])
        # the belief is the track's: every sample near the estimate, weights summing to one
        assert np.hypot(*(belief.samples[:, :2] - track).T).max() < 1.5, k
        assert belief.samples.shape[0] == len(mcl.samples) - int(fresh.sum())
        assert np.isclose(belief.weights.sum(), 1.0)
        # the displayed samples are the filter's, guesses and all
        assert belief.summary is not None
        assert belief.summary.count == len(mcl.samples)
    assert guesses > 0  # the guesses were taken (and not one won)
