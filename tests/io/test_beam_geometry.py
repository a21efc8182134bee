"""The beam layout check: consecutive scans from known poses agree only with the right layout."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tourbot.io.beam_geometry import AGREEMENT, candidate_layouts, check_layouts

from ..localization.conftest import room_with_boxes, simulate, waypoints_path


def _drive() -> tuple[list, np.ndarray]:
    drive = simulate(room_with_boxes(), waypoints_path(40), seed=2)
    return drive.scans, drive.truth


def test_the_right_layout_is_kept_and_agrees() -> None:
    scans, poses = _drive()
    check = check_layouts(scans, poses, candidate_layouts(scans[0].geometry, {}))
    assert check is not None
    assert check.chosen == "stated"
    assert check.agrees
    assert check.scores["mirrored (beams left to right)"] > 3 * check.scores["stated"]


def test_reversed_scans_are_found_mirrored() -> None:
    scans, poses = _drive()
    flipped = [replace(s, ranges=s.ranges[::-1].copy()) for s in scans]
    check = check_layouts(flipped, poses, candidate_layouts(scans[0].geometry, {}))
    assert check is not None
    assert check.chosen == "mirrored (beams left to right)"


def test_a_squeezed_alternative_loses_and_noise_fits_nothing() -> None:
    scans, poses = _drive()
    g = scans[0].geometry
    squeezed = replace(g, angle_min=g.angle_min / 2, angle_increment=g.angle_increment / 2)
    check = check_layouts(scans, poses, candidate_layouts(g, {"half": squeezed}))
    assert check is not None
    assert check.chosen == "stated"
    rng = np.random.default_rng(1)
    noise = [replace(s, ranges=rng.permutation(s.ranges)) for s in scans]
    bad = check_layouts(noise, poses, candidate_layouts(g, {"half": squeezed}))
    assert bad is not None
    assert not bad.agrees
    assert min(bad.scores.values()) > AGREEMENT


def test_no_pair_of_scans_apart_means_no_check() -> None:
    scans, poses = _drive()
    still = np.repeat(poses[:1], len(poses), axis=0)
    assert check_layouts(scans, still, candidate_layouts(scans[0].geometry, {})) is None
