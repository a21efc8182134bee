"""The mounts of a robot's lasers from their scans: found, checked, refused when they cannot be."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from tests.mapping.test_ego_motion import MOUNTS, three_lasers
from tourbot.geometry import relative
from tourbot.mapping.mounts import MountError, bag_lasers, estimate_mounts, mount_lasers


def test_the_mounts_of_three_lasers_are_found_from_their_scans() -> None:
    streams, _ = three_lasers(scans=12)
    est = estimate_mounts(streams, "front")
    assert est.mounts["front"] == (0.0, 0.0, 0.0)
    for name in ("left", "rear"):
        truth = relative(MOUNTS["front"], MOUNTS[name])  # in the front laser's frame
        err = relative(truth, np.asarray(est.mounts[name]))
        assert math.hypot(err[0], err[1]) < 0.03
        assert abs(err[2]) < math.radians(1.0)
    assert est.closure[0] < 0.03
    assert "closure" in est.describe()


def test_scans_that_do_not_see_the_same_room_give_no_mount() -> None:
    streams, _ = three_lasers(scans=12)
    rng = np.random.default_rng(0)
    # the rear laser's scans replaced by noise: nothing in them fits the front laser's walls
    noise = [dataclasses.replace(s, ranges=rng.uniform(1.0, 15.0, len(s.ranges))) for s in streams["rear"]]
    with pytest.raises(MountError):
        estimate_mounts({"front": streams["front"], "rear": noise}, "front")


def test_lasers_that_see_nothing_in_common_do_not_close() -> None:
    from tourbot.records import LaserGeometry

    # 150 degrees each: the front and the rear laser see opposite sides, and a wrong fit of one
    # to the other is caught by the mounts found through the left laser
    narrow = LaserGeometry(
        num_beams=301, angle_min=-5 * math.pi / 12, angle_increment=5 * math.pi / 6 / 300, max_range=20.0
    )
    streams, _ = three_lasers(scans=12, geometry=narrow)
    with pytest.raises(MountError, match="do not close"):
        estimate_mounts(streams, "front")


def test_mounts_from_tf_are_kept() -> None:
    streams, _ = three_lasers(scans=3)
    given = {
        name: [
            dataclasses.replace(s, geometry=dataclasses.replace(s.geometry, offset=MOUNTS[name]))
            for s in scans
        ]
        for name, scans in streams.items()
    }
    mounted, how = mount_lasers(given, "front")
    assert "tf" in how
    assert all(mounted[n][0].geometry.offset == MOUNTS[n] for n in given)


def test_the_lasers_of_a_bag_are_read_with_their_mounts(shared_data: Path) -> None:
    # negative_2.bag: three lasers, no tf; the robot stands still at the start
    lasers, how = bag_lasers(shared_data / "leg_tracker" / "negative_2.bag", "/rear_scan")
    assert list(lasers) == ["/rear_scan", "/left_scan", "/right_scan"]
    assert lasers["/rear_scan"][0].geometry.offset == (0.0, 0.0, 0.0)
    left = np.asarray(lasers["/left_scan"][0].geometry.offset)
    right = np.asarray(lasers["/right_scan"][0].geometry.offset)
    # the side lasers sit about 1 m ahead of the rear one (which looks back), 0.5 m apart
    assert 0.9 < math.hypot(left[0], left[1]) < 1.2
    assert 0.4 < math.hypot(*(left[:2] - right[:2])) < 0.6
    assert "closure" in how  # found directly and through the other side laser, and they close
