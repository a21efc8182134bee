"""``tourbot localize --mcap``: the run as MCAP, decoded back channel by channel with rosbags."""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from tourbot.cli.main import main
from tourbot.geometry import compose
from tourbot.io.carmen import read_carmen, write_carmen
from tourbot.io.mapserver import read_map, write_map
from tourbot.io.mcap_out import McapRun
from tourbot.io.ros2_messages import MAX_PARTICLES, TOPICS, grid_cells
from tourbot.io.tum import read_tum
from tourbot.maps.grid import OccupancyGrid
from tourbot.maps.reference import build_reference_map
from tourbot.records import LaserGeometry, RobotLog, Scan

STORE = get_typestore(Stores.ROS2_HUMBLE)
N_SCANS = 12


def _decode(path: Path) -> dict[str, list[tuple[int, Any]]]:
    out: dict[str, list[tuple[int, Any]]] = defaultdict(list)
    with Reader(path) as reader:
        for conn, stamp, raw in reader.messages():
            assert conn.msgtype == TOPICS[conn.topic]
            out[conn.topic].append((stamp, STORE.deserialize_cdr(raw, conn.msgtype)))
    return out


def _yaw(q: Any) -> float:
    assert q.x == 0.0
    assert q.y == 0.0
    return 2.0 * math.atan2(q.z, q.w)


def _pose(p: Any) -> np.ndarray:
    return np.array([p.position.x, p.position.y, _yaw(p.orientation)])


def _tf_pose(tf: Any) -> np.ndarray:
    t = tf.transform
    return np.array([t.translation.x, t.translation.y, _yaw(t.rotation)])


def _wrap(a: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * a))


@pytest.fixture(scope="module")
def fhw_run(real_log: Any, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path, Path]:
    """The first scans of the FHW corrected log localized (MCL) in its reference map, with --mcap."""
    root = tmp_path_factory.mktemp("mcap")
    full: RobotLog = real_log("fhw")
    write_map(build_reference_map(full), root / "fhw.yaml")
    scans = full.scans[:N_SCANS]
    odometry = [o for o in full.odometry if o.timestamp <= scans[-1].timestamp]
    write_carmen(RobotLog(source="fhw-head", scans=scans, odometry=odometry), root / "head.log")
    mcap = root / "run.mcap"
    tum = root / "run.tum"
    args = ["localize", str(root / "head.log"), "--map", str(root / "fhw.yaml"), "--start-from-reference"]
    main([*args, "--particles", "2000", "--force", "-o", str(tum), "--mcap", str(mcap)])
    return root / "head.log", root / "fhw.yaml", tum, mcap


def test_every_channel_decodes_to_the_run(fhw_run: tuple[Path, Path, Path, Path]) -> None:
    log_path, map_path, tum, mcap = fhw_run
    log = read_carmen(log_path)
    grid = read_map(map_path)
    times, poses = read_tum(tum)
    msgs = _decode(mcap)
    assert set(msgs) == set(TOPICS) - {"/ceiling/image", "/people", "/objects"}  # no camera, tracker, objects
    stamps = [round(s.timestamp * 1e9) for s in log.scans]

    # the map, once, latched at the first time; cells -1 unknown, else 100 * p
    ((stamp, m),) = msgs["/map"]
    assert stamp == stamps[0]
    assert (m.info.height, m.info.width) == grid.prob.shape
    assert m.info.resolution == pytest.approx(grid.resolution)
    np.testing.assert_allclose(_pose(m.info.origin), grid.origin, atol=1e-12)
    cells = m.data.reshape(grid.prob.shape)
    assert np.array_equal(cells == -1, grid.prob < 0)
    assert np.array_equal(cells[grid.prob >= 0], np.rint(100 * grid.prob[grid.prob >= 0]).astype(np.int8))
    assert {-1, 0, 100} <= set(np.unique(cells).tolist())

    # every scan, with the log's times and ranges
    assert [s for s, _ in msgs["/scan"]] == stamps
    for scan, (_, m) in zip(log.scans, msgs["/scan"], strict=True):
        assert m.header.frame_id == "laser"
        assert m.header.stamp.sec * 10**9 + m.header.stamp.nanosec == round(scan.timestamp * 1e9)
        np.testing.assert_array_equal(m.ranges, scan.ranges.astype(np.float32))
        assert m.angle_min == pytest.approx(scan.geometry.angle_min)
        assert m.angle_increment == pytest.approx(scan.geometry.angle_increment)
        assert m.range_max == pytest.approx(scan.geometry.max_range)

    # the odometry the localizer used: the scans' odometry poses
    assert [s for s, _ in msgs["/odom"]] == stamps
    odom = np.array([_pose(m.pose.pose) for _, m in msgs["/odom"]])
    np.testing.assert_allclose(odom[:, :2], log.odom_poses[:, :2], atol=1e-9)
    np.testing.assert_allclose(_wrap(odom[:, 2] - log.odom_poses[:, 2]), 0.0, atol=1e-9)

    # the estimate, as the TUM trajectory has it
    assert [s for s, _ in msgs["/estimate"]] == stamps
    est = np.array([_pose(m.pose.pose) for _, m in msgs["/estimate"]])
    assert all(m.header.frame_id == "map" for _, m in msgs["/estimate"])
    np.testing.assert_allclose(times, [s / 1e9 for s in stamps], atol=1e-6)
    np.testing.assert_allclose(est[:, :2], poses[:, :2], atol=1e-4)
    np.testing.assert_allclose(_wrap(est[:, 2] - poses[:, 2]), 0.0, atol=1e-4)
    cov = np.array([m.pose.covariance.reshape(6, 6) for _, m in msgs["/estimate"]])
    assert (cov[:, 0, 0] > 0).all()
    assert (cov[:, 5, 5] > 0).all()
    assert (cov[:, 2:5, :] == 0).all()
    # tracking from the reference: the estimate stays near it (the run is a real one)
    assert np.hypot(*(est[:, :2] - log.reference_poses[:, :2]).T).max() < 0.5

    # TF: map -> odom -> base_link composes to the estimate; base_link -> laser is the offset
    tree: dict[tuple[str, str], list[np.ndarray]] = defaultdict(list)
    for _, m in msgs["/tf"]:
        for tf in m.transforms:
            tree[(tf.header.frame_id, tf.child_frame_id)].append(_tf_pose(tf))
    assert set(tree) == {("map", "odom"), ("odom", "base_link"), ("base_link", "laser")}
    chain = compose(np.array(tree[("map", "odom")]), np.array(tree[("odom", "base_link")]))
    np.testing.assert_allclose(chain[:, :2], est[:, :2], atol=1e-9)
    np.testing.assert_allclose(_wrap(chain[:, 2] - est[:, 2]), 0.0, atol=1e-9)
    offsets = np.array(tree[("base_link", "laser")])
    np.testing.assert_allclose(offsets, [log.scans[0].geometry.offset] * N_SCANS)

    # particles: a subsample of at most MAX_PARTICLES around the estimate
    assert [s for s, _ in msgs["/particles"]] == stamps
    for k, (_, m) in enumerate(msgs["/particles"]):
        pts = np.array([_pose(p) for p in m.poses])
        assert 0 < len(pts) <= MAX_PARTICLES
        assert np.hypot(*(pts[:, :2].mean(axis=0) - est[k, :2])) < 0.3

    # beams: integrated and rejected end points, in the laser frame, within the scan's ranges
    assert msgs["/beams"], "no update integrated a scan"
    for stamp, m in msgs["/beams"]:
        scan = log.scans[stamps.index(stamp)]
        assert [mk.ns for mk in m.markers] == ["integrated", "rejected"]
        finite = scan.ranges[scan.ranges < scan.geometry.max_range]
        n = sum(len(mk.points) for mk in m.markers)
        assert len(m.markers[0].points) > 0
        assert n <= len(finite)
        for mk in m.markers:
            assert mk.header.frame_id == "laser"
            r = np.array([math.hypot(p.x, p.y) for p in mk.points])
            assert np.isin(r.astype(np.float32), finite.astype(np.float32)).all()


def test_beams_split_by_the_used_mask(tmp_path: Path) -> None:
    geometry = LaserGeometry(num_beams=4, angle_min=-math.pi / 2, angle_increment=math.pi / 3, max_range=8.0)
    scan = Scan(timestamp=3.25, ranges=np.array([1.0, 2.0, 8.0, 4.0]), geometry=geometry, odom=(0, 0, 0))
    grid = OccupancyGrid(prob=np.array([[0.0, 0.5, -1.0], [1.0, 0.2, 0.0]], dtype=np.float32), resolution=0.5)
    path = tmp_path / "b.mcap"
    with McapRun(path) as run:
        run.write_map(grid, 3.0)
        run.write_beams(scan, [True, False, True, False])
        run.write_particles(np.zeros((1234, 3)), 3.25)
    msgs = _decode(path)
    ((_, m),) = msgs["/beams"]
    integrated, rejected = m.markers
    # beam 2 is at the maximum range: no end point, in neither set
    assert [(round(p.x, 9), round(p.y, 9)) for p in integrated.points] == [(0.0, -1.0)]
    assert [(round(p.x, 9), round(p.y, 9)) for p in rejected.points] == [
        (round(2 * math.cos(-math.pi / 6), 9), round(2 * math.sin(-math.pi / 6), 9)),
        (round(4 * math.cos(math.pi / 2), 9), round(4 * math.sin(math.pi / 2), 9)),
    ]
    ((_, pm),) = msgs["/particles"]
    assert len(pm.poses) == MAX_PARTICLES
    ((_, gm),) = msgs["/map"]
    assert gm.data.tolist() == [0, 50, -1, 100, 20, 0] == grid_cells(grid).tolist()


def test_a_failed_run_leaves_no_file(tmp_path: Path) -> None:
    path = tmp_path / "x.mcap"

    def interrupted() -> None:
        with McapRun(path) as run:
            run.write_particles(np.zeros((3, 3)), 1.0)
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        interrupted()
    assert not path.exists()
    assert list(tmp_path.iterdir()) == []


def test_localize_refuses_a_bad_mcap_path(
    fhw_run: tuple[Path, Path, Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log_path, map_path, _, mcap = fhw_run
    args = ["localize", str(log_path), "--map", str(map_path), "--start-from-reference", "-o"]
    before = mcap.stat().st_mtime_ns
    for target, words in [
        (mcap, "exists; --force overwrites it"),
        (tmp_path / "no" / "such" / "r.mcap", "does not exist"),
        (tmp_path, "is a folder"),
    ]:
        with pytest.raises(SystemExit) as exc:
            main([*args, str(tmp_path / "t.tum"), "--mcap", str(target)])
        assert exc.value.code == 2
        (error,) = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("error:")]
        assert words in error
        assert "--mcap" in error
    assert mcap.stat().st_mtime_ns == before
    assert not (tmp_path / "t.tum").exists()


def test_simulate_writes_the_run_as_mcap(tmp_path: Path) -> None:
    log_path, mcap = tmp_path / "sim.log.gz", tmp_path / "sim.mcap"
    args = ["simulate", "--crowd", "empty", "--duration", "6", "--write-log", str(log_path)]
    main([*args, "--mcap", str(mcap)])
    log = read_carmen(log_path)
    msgs = _decode(mcap)
    assert set(msgs) == set(TOPICS) - {"/beams", "/ceiling/image", "/people", "/objects"}
    scans = [m for _, m in msgs["/scan"]]
    assert len(scans) == len(log.scans) > 0
    for scan, m in zip(log.scans, scans, strict=True):
        np.testing.assert_allclose(m.ranges, scan.ranges, atol=5e-3)
    stamps = [s for s, _ in msgs["/scan"]]
    assert [s for s, _ in msgs["/odom"]] == stamps
    assert msgs["/estimate"]
    assert {s for s, _ in msgs["/estimate"]} <= set(stamps)
    # the TF chain at each estimate's time composes to the estimate
    by_stamp: dict[tuple[int, str], np.ndarray] = {}
    for stamp, m in msgs["/tf"]:
        for tf in m.transforms:
            by_stamp[(stamp, tf.child_frame_id)] = _tf_pose(tf)
    for stamp, m in msgs["/estimate"]:
        chain = compose(by_stamp[(stamp, "odom")], by_stamp[(stamp, "base_link")])
        est = _pose(m.pose.pose)
        np.testing.assert_allclose(chain[:2], est[:2], atol=1e-9)
        assert abs(_wrap(chain[2] - est[2])) < 1e-9
    # the robot is where the simulator says (a real run, started at the tour's start pose)
    truth = log.reference_poses[[stamps.index(s) for s, _ in msgs["/estimate"]]]
    est = np.array([_pose(m.pose.pose) for _, m in msgs["/estimate"]])
    assert np.hypot(*(est[:, :2] - truth[:, :2]).T).max() < 0.5
    # the map MCL localized in: the site's
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site

    ((_, grid_msg),) = msgs["/map"]
    site_grid = load_site(site_path("fhw")).grid
    assert (grid_msg.info.height, grid_msg.info.width) == site_grid.prob.shape
    assert np.array_equal(grid_msg.data, grid_cells(site_grid))
    with pytest.raises(SystemExit) as exc:
        main([*args, "--mcap", str(mcap)])
    assert exc.value.code == 2


def test_an_unwritable_folder_is_refused_naming_file_and_option(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the tests may run as root, for whom every folder is writable: the permission check is faked
    from tourbot.errors import InputError
    from tourbot.io import mcap_out

    target = tmp_path / "r.mcap"
    assert mcap_out.check_mcap_output(target, force=False) == target
    monkeypatch.setattr(mcap_out.os, "access", lambda *_a, **_k: False)
    with pytest.raises(InputError, match="is not writable") as exc:
        mcap_out.check_mcap_output(target, force=False)
    assert "--mcap" in str(exc.value)
    assert str(target) in str(exc.value)
