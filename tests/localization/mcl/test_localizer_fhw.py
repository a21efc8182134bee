"""MCL on a stretch of the real FHW museum log (the map is built from the log's reference poses)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tourbot.io.carmen import read_carmen
from tourbot.localization.beam_filters import BeamFilter
from tourbot.localization.mcl import MonteCarloLocalization
from tourbot.localization.profile import FHW_PROFILE, LocalizationProfile
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.reference import build_reference_map
from tourbot.records import RobotLog
from tourbot.sim.kidnap import Kidnap, apply_kidnaps

_FHW = LocalizationProfile.load(FHW_PROFILE).mcl
STRETCH = 60  # scans: about 4 minutes of the tour, with visitors around the robot


@pytest.fixture(scope="module")
def fhw(fhw_log_path: Path) -> tuple[RobotLog, OccupancyGrid]:
    log = read_carmen(fhw_log_path)
    grid = build_reference_map(log, 0.05)
    log.scans = log.scans[:STRETCH]
    return log, grid


def _track(log: RobotLog, grid: OccupancyGrid, kind: BeamFilter, seed: int = 0) -> np.ndarray:
    mcl = MonteCarloLocalization(grid, _FHW.with_samples(1000).with_filter(kind), seed=seed)
    mcl.reset_tracking(log.scans[0].reference)  # type: ignore[arg-type]
    est = np.array([mcl.update(s.odom, s).pose for s in log.scans])  # type: ignore[arg-type]
    ref = log.reference_poses
    return np.asarray(np.hypot(est[:, 0] - ref[:, 0], est[:, 1] - ref[:, 1]))


def test_novelty_mcl_tracks_the_museum_log(fhw: tuple[RobotLog, OccupancyGrid]) -> None:
    log, grid = fhw
    err = _track(log, grid, BeamFilter.NOVELTY)
    assert err.max() < 0.45  # no failure in the paper's sense
    assert err.mean() < 0.12


def test_mcl_recovers_from_a_kidnap_on_the_museum_log(fhw: tuple[RobotLog, OccupancyGrid]) -> None:
    log, grid = fhw
    # At scan 20 the odometry reports a phantom half-turn and 80 cm shift (Fox et al. 1998's
    # kidnap: heading 180 +/- 90 deg, position 0 +/- 100 cm).
    kidnapped = apply_kidnaps(log, [Kidnap(scan=20, time=log.scans[20].timestamp, delta=(0.5, -0.6, 3.0))])
    err = _track(kidnapped, grid, BeamFilter.NOVELTY, seed=1)
    assert err[:20].max() < 0.45
    assert err[20] > 0.45  # the kidnap does throw it off
    times = log.times
    back = 20 + int(np.argmax(err[20:] < 0.45))
    assert times[back] - times[20] < 30.0  # re-localized within 30 s...
    assert err[back:].max() < 0.45  # ...for good
