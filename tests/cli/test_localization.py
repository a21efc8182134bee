from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tourbot.cli.main import main
from tourbot.io.carmen import write_carmen
from tourbot.io.mapserver import write_map
from tourbot.io.tum import read_tum
from tourbot.localization.profile import FHW_PROFILE
from tourbot.records import RobotLog

from ..localization.conftest import room_with_boxes, simulate, waypoints_path


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, np.ndarray]:
    root = tmp_path_factory.mktemp("localize")
    grid = room_with_boxes()
    drive = simulate(grid, waypoints_path(20), seed=4)
    log = RobotLog(source="synthetic", scans=drive.scans)
    write_carmen(log, root / "drive.log")
    write_map(grid, root / "room.yaml")
    return root / "drive.log", root / "room.yaml", drive.truth


def test_localize_writes_one_pose_per_scan(files: tuple[Path, Path, np.ndarray], tmp_path: Path) -> None:
    log, room, truth = files
    out = tmp_path / "traj.tum"
    main(
        [
            "localize",
            str(log),
            "--map",
            str(room),
            "--start-from-reference",
            "--particles",
            "500",
            "-o",
            str(out),
        ]
    )
    times, poses = read_tum(out)
    assert len(times) == len(truth)
    assert np.all(np.diff(times) > 0)
    assert np.hypot(*(poses[:, :2] - truth[:, :2]).T).mean() < 0.1


def test_localize_global(files: tuple[Path, Path, np.ndarray], tmp_path: Path) -> None:
    log, room, truth = files
    out = tmp_path / "traj.tum"
    args = ["localize", str(log), "--map", str(room), "--global", "--seed", "3"]
    main([*args, "--particles", "1000", "-o", str(out)])
    times, poses = read_tum(out)
    # Plumbing only (convergence of global localization is tested in tests/localization): one
    # finite pose per scan, inside the room.
    assert len(times) == len(truth)
    assert np.isfinite(poses).all()
    assert (np.abs(poses[:, :2] - [5.0, 2.5]) < 7.0).all()


def test_localize_needs_exactly_one_start(
    files: tuple[Path, Path, np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log, room, _ = files
    with pytest.raises(SystemExit) as exc:
        main(["localize", str(log), "--map", str(room), "-o", str(tmp_path / "t.tum")])
    assert exc.value.code == 2
    assert "--start-from-reference" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["localize", str(log), "--map", str(room), "--start", "1,2", "-o", str(tmp_path / "t.tum")])
    assert exc.value.code == 2
    assert "X,Y,THETA" in capsys.readouterr().err


def test_localize_grid_says_it_builds_the_table_and_caches_it(
    files: tuple[Path, Path, np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log, room, truth = files
    out = tmp_path / "traj.tum"
    cache = tmp_path / "tables"
    # the FHW profile: the paper's plain product of the beams' likelihoods (the default) is far
    # too confident for the grid (GridMarkovConfig.likelihood_power)
    profile = ["--config", str(FHW_PROFILE)]
    args = ["localize", str(log), "--map", str(room), "--method", "grid", "--start-from-reference", *profile]
    main([*args, "--table-cache", str(cache), "-o", str(out)])
    first = " ".join(capsys.readouterr().err.split())  # the console may wrap lines
    assert "expected-range table" in first
    assert "built and saved to" in first
    assert len(list(cache.glob("*.npz"))) == 1
    _, poses = read_tum(out)
    assert np.hypot(*(poses[:, :2] - truth[:, :2]).T).mean() < 0.15

    main([*args, "--table-cache", str(cache), "-o", str(out)])
    assert "read from" in " ".join(capsys.readouterr().err.split())
    main([*args, "--no-cache-table", "-o", str(out)])
    second = " ".join(capsys.readouterr().err.split())
    assert "expected-range table" in second
    assert "built in" in second


def test_localize_takes_a_profile_and_refuses_a_bad_one(
    files: tuple[Path, Path, np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log, room, truth = files
    out = tmp_path / "traj.tum"
    profile = tmp_path / "p.yaml"
    profile.write_text(
        "mcl:\n  sampling: {max_samples: 400, min_samples: 100}\n  sensor: {beam_filter: none}\n"
    )
    main(
        [
            "localize",
            str(log),
            "--map",
            str(room),
            "--start-from-reference",
            "--config",
            str(profile),
            "-o",
            str(out),
        ]
    )
    _, poses = read_tum(out)
    assert np.hypot(*(poses[:, :2] - truth[:, :2]).T).max() < 0.3
    capsys.readouterr()
    profile.write_text("mcl:\n  sampling: {max_samples: many}\n")
    with pytest.raises(SystemExit) as exc:
        main(
            [
                "localize",
                str(log),
                "--map",
                str(room),
                "--start-from-reference",
                "--config",
                str(profile),
                "-o",
                str(out),
            ]
        )
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "p.yaml" in err
    assert "mcl.sampling.max_samples: must be an integer" in err


def _localize(log: Path, room: Path, out: Path, *extra: str) -> None:
    main(
        [
            "localize",
            str(log),
            "--map",
            str(room),
            "--start-from-reference",
            "--particles",
            "300",
            "-o",
            str(out),
            *extra,
        ]
    )


def test_localize_prints_progress_lines_when_stderr_is_not_a_terminal(
    files: tuple[Path, Path, np.ndarray],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import tourbot.io.progress

    monkeypatch.setattr(tourbot.io.progress, "LINE_EVERY", 0.0)
    log, room, truth = files
    _localize(log, room, tmp_path / "t.tum")
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("localize (mcl + novelty): ")]
    assert f"localize (mcl + novelty): 1/{len(truth)} scans" in lines[0]
    assert "scans/s" in lines[0]
    assert " s left" in lines[0]
    assert lines[-1].startswith(f"localize (mcl + novelty): done at {len(truth)}/{len(truth)} scans")


def test_localize_keeps_the_partial_trajectory_on_ctrl_c(
    files: tuple[Path, Path, np.ndarray], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from tourbot.localization.mcl import MonteCarloLocalization

    real = MonteCarloLocalization.update
    calls = {"n": 0}

    def interrupted(self: MonteCarloLocalization, *args: object, **kwargs: object) -> object:
        calls["n"] += 1
        if calls["n"] > 7:
            raise KeyboardInterrupt
        return real(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(MonteCarloLocalization, "update", interrupted)
    log, room, _truth = files
    kept, dropped = tmp_path / "kept.tum", tmp_path / "dropped.tum"
    with pytest.raises(SystemExit) as exc:
        _localize(log, room, kept, "--keep-partial")
    assert exc.value.code == 130
    times, _poses = read_tum(kept)
    assert len(times) == 7
    calls["n"] = 0
    with pytest.raises(SystemExit):
        _localize(log, room, dropped)
    assert not dropped.exists()


def test_localize_refuses_a_map_that_does_not_fit_unless_forced(
    files: tuple[Path, Path, np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from tourbot.maps.grid import OccupancyGrid

    log, _room, _truth = files
    prob = np.zeros((600, 600), np.float32)
    prob[:3, :] = prob[-3:, :] = prob[:, :3] = prob[:, -3:] = 1.0
    hall = tmp_path / "hall.yaml"
    write_map(OccupancyGrid(prob, 0.05, origin=(-10.0, -10.0, 0.0)), hall)
    with pytest.raises(SystemExit) as exc:
        _localize(log, hall, tmp_path / "t.tum")
    assert exc.value.code == 2
    (error,) = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert "the map does not fit the log" in error
    assert error.endswith("--force goes on anyway")
    _localize(log, hall, tmp_path / "t.tum", "--force")
    assert "going on: --force" in capsys.readouterr().err


def test_localize_refuses_sparse_odometry_and_no_motion(
    files: tuple[Path, Path, np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from dataclasses import replace

    from tourbot.io import read_carmen
    from tourbot.records import Odometry

    log, room, _truth = files
    drive = read_carmen(log)
    sparse = replace(
        drive, odometry=[Odometry(s.timestamp, s.odom or (0.0, 0.0, 0.0)) for s in drive.scans[:1]]
    )
    write_carmen(sparse, tmp_path / "sparse.log")
    with pytest.raises(SystemExit) as exc:
        _localize(tmp_path / "sparse.log", room, tmp_path / "t.tum")
    assert exc.value.code == 2
    assert f"only 1 odometry reading for {len(drive.scans)} scans" in capsys.readouterr().err
    still = replace(drive, scans=[replace(s, odom=(0.0, 0.0, 0.0)) for s in drive.scans])
    write_carmen(still, tmp_path / "still.log")
    with pytest.raises(SystemExit):
        _localize(tmp_path / "still.log", room, tmp_path / "t.tum")
    assert "the odometry does not move" in capsys.readouterr().err
    _localize(tmp_path / "sparse.log", room, tmp_path / "t.tum", "--force")  # forced: warned, then run
    err = " ".join(capsys.readouterr().err.split())
    assert f"only 1 odometry reading for {len(drive.scans)} scans" in err
    assert "(going on: --force)" in err
    assert len(read_tum(tmp_path / "t.tum")[0]) == len(drive.scans)


def test_localize_refuses_four_odometry_readings_for_237_scans_of_the_fhw_log(
    shared_data: Path,
    files: tuple[Path, Path, np.ndarray],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    # issue 22: a log with 4 odometry readings for 237 scans was localized to the end (92 % failures)
    import gzip

    with gzip.open(shared_data / "carmen" / "fhw-corrected.log.gz", "rt") as f:
        lines = f.read().splitlines()
    lasers = [k for k, line in enumerate(lines) if line.startswith("FLASER")]
    lines = lines[: lasers[236] + 2]  # 237 scans, each with its copy of the corrected pose
    odom = [k for k, line in enumerate(lines) if line.startswith("ODOM")]
    real = [k for k in odom if not lines[k - 1].startswith("FLASER")]  # the copies follow a scan
    keep = set(real[:: len(real) // 4][:4])
    variant = tmp_path / "sparse.log"
    variant.write_text("\n".join(x for k, x in enumerate(lines) if k not in set(real) - keep) + "\n")
    _room_log, room, _truth = files
    with pytest.raises(SystemExit) as exc:
        _localize(variant, room, tmp_path / "t.tum")
    assert exc.value.code == 2
    (error,) = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert "only 4 odometry readings for 237 scans" in error
    assert not (tmp_path / "t.tum").exists()


def test_localize_never_prints_a_real_time_factor_it_cannot_know(
    files: tuple[Path, Path, np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # issue 22: "0x real time" and "323872908x real time" from zero and wrapped timestamps
    from dataclasses import replace

    from tourbot.io import read_carmen

    log, room, _truth = files
    drive = read_carmen(log)
    unstamped = replace(
        drive,
        scans=[replace(s, timestamp=0.0) for s in drive.scans],
        odometry=[replace(o, timestamp=0.0) for o in drive.odometry],
    )
    write_carmen(unstamped, tmp_path / "zero.log")
    _localize(tmp_path / "zero.log", room, tmp_path / "t.tum")
    err = " ".join(capsys.readouterr().err.split())
    assert "real time unknown (the scan timestamps are all zero)" in err
    assert "x real time" not in err


@pytest.fixture(scope="module")
def domus_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path, np.ndarray]:
    """An 8 s drive through the Domus hall with the upward camera."""
    from tourbot.ceiling.rig import CeilingCamera
    from tourbot.io.images import write_image_stream
    from tourbot.sim.camera import CeilingCameraSim
    from tourbot.sim.simulator import SimConfig, Simulator
    from tourbot.site.default import site_path
    from tourbot.site.model import load_site

    root = tmp_path_factory.mktemp("ceiling")
    site = load_site(site_path("domus"))
    sim = Simulator(
        site,
        SimConfig(record=True),
        seed=5,
        start=(-4.0, -7.0, 0.0),
        cameras=[CeilingCameraSim(site, CeilingCamera(), seed=5)],
    )
    sim.command(0.3, 0.0)
    for _ in range(80):
        sim.poll()
    write_carmen(sim.to_robot_log(), root / "domus.log")
    write_map(site.grid, root / "domus.yaml")
    images = sim.image_history["ceiling"]
    write_image_stream(root / "domus.ceiling.npz", [i.timestamp for i in images], [i.pixels for i in images])
    return root / "domus.log", root / "domus.yaml", root / "domus.ceiling.npz", np.array(sim.truth_poses)


def test_localize_fuses_the_ceiling_camera(
    domus_run: tuple[Path, Path, Path, np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # (a kidnapped robot found again from the ceiling: tests/app/test_simulated.py)
    log, room, images, truth = domus_run
    out = tmp_path / "fused.tum"
    camera = [
        "--camera",
        str(images),
        "--site",
        "domus",
        "--particles",
        "300",
        "--mcap",
        str(tmp_path / "r.mcap"),
    ]
    main(["localize", str(log), "--map", str(room), "--start-from-reference", *camera, "-o", str(out)])
    _, poses = read_tum(out)
    said = " ".join(capsys.readouterr().err.split())
    # 8 images at 0.1, 1.1, ... 7.1 s; the first comes with the first scan, before any estimate
    assert "ceiling camera: 7 images fused (0 restarts of the track from the ceiling)" in said, said
    assert np.hypot(*(poses[:, :2] - truth[:, :2]).T).max() < 0.2
    from tourbot.io.images import read_camera_images

    # the MCAP holds every image (also the first, given before any estimate) on /ceiling/image
    times, _ = read_camera_images(tmp_path / "r.mcap")
    assert len(times) == 8


def test_localize_camera_input_errors(
    domus_run: tuple[Path, Path, Path, np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from tourbot.io.images import write_image_stream

    log, room, images, _ = domus_run
    base = ["localize", str(log), "--map", str(room), "--start-from-reference", "-o", str(tmp_path / "t.tum")]
    small = tmp_path / "small.npz"
    write_image_stream(small, [0.5], [np.zeros((10, 20), dtype=np.uint8)])
    cases = [
        (["--camera", str(images)], "--camera needs --site"),
        (["--site", "domus"], "give --camera too"),
        (["--camera", str(images), "--site", "domus", "--method", "grid"], "use --method mcl"),
        (["--camera", str(small), "--site", "domus"], "calibration is for 480 rows x 640 columns"),
        (["--camera", str(tmp_path / "none.npz"), "--site", "domus"], "none.npz"),
    ]
    for extra, message in cases:
        with pytest.raises(SystemExit) as exc:
            main([*base, *extra])
        assert exc.value.code == 2
        said = capsys.readouterr().err
        assert message in said, said
        assert len(said.strip().splitlines()) == 1  # one line, no traceback
