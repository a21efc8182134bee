from __future__ import annotations

import numpy as np
import pytest

from tests.mapping.conftest import building, drive
from tourbot.geometry import relative
from tourbot.mapping.features import FeatureMapper, FeatureMappingParams
from tourbot.mapping.features.smoother import rts_smooth
from tourbot.metrics.relative import aligned_trajectory_error, relation_error, sample_pairs
from tourbot.records import RobotLog


@pytest.fixture(scope="module")
def loop() -> RobotLog:
    return drive(building(), n=200, seed=3, odom_noise=0.05)


def test_em_beats_the_odometry_on_a_loop_with_known_truth(loop: RobotLog) -> None:
    ref = loop.reference_poses
    one = FeatureMapper(FeatureMappingParams(iterations=1)).run(loop.scans, start=ref[0])
    em = FeatureMapper().run(loop.scans, start=ref[0])
    odom = aligned_trajectory_error(loop.odom_poses, ref).rmse
    first = aligned_trajectory_error(one.poses, ref).rmse
    final = aligned_trajectory_error(em.poses, ref).rmse
    assert odom > 0.4
    assert final < 0.1 < odom / 4
    assert final <= first + 1e-9  # EM keeps its best iteration: never worse than the first
    assert em.iterations >= 1


def test_the_line_map_lies_on_the_walls(loop: RobotLog) -> None:
    grid = building()
    result = FeatureMapper().run(loop.scans, start=loop.reference_poses[0])
    segments = result.segments()
    assert len(segments) >= 5
    occupied = grid.cell_to_world(np.argwhere(grid.occupied()))
    for a, b in segments:
        for u in np.linspace(0.0, 1.0, 5):
            p = a + u * (b - a)
            assert np.min(np.hypot(*(occupied - p).T)) < 0.25
    total = sum(float(np.hypot(*(b - a))) for a, b in segments)
    assert total > 30.0  # most of the hall's walls, not scraps


def test_smoothed_poses_are_better_than_filtered() -> None:
    """The RTS backward pass uses the future scans: it moves the path closer to the truth."""
    log = drive(building(), n=120, seed=5, odom_noise=0.1)
    ref = log.reference_poses
    mapper = FeatureMapper(FeatureMappingParams(iterations=1))
    feats = [mapper._features(s) for s in log.scans]
    odom = np.array([s.odom for s in log.scans])
    fwd = mapper._forward(feats, relative(odom[:-1], odom[1:]), ref[0], [], None, None)
    smooth, _ = rts_smooth(fwd.filtered, fwd.filtered_cov, fwd.predicted, fwd.predicted_cov, fwd.jacobians)
    before = relation_error(fwd.filtered, ref, sample_pairs(ref)["separation"]).trans_mean
    after = relation_error(smooth, ref, sample_pairs(ref)["separation"]).trans_mean
    assert after < 0.97 * before


def test_a_wrong_corner_does_not_close_a_loop(loop: RobotLog) -> None:
    """Hypotheses that lose vanish: on the synthetic loop every closure agrees with the truth."""
    ref = loop.reference_poses
    result = FeatureMapper().run(loop.scans, start=ref[0])
    for c in result.closures:
        err = relative(relative(ref[c.seen], ref[c.scan]), np.array(c.delta))
        assert np.hypot(err[0], err[1]) < 0.3
