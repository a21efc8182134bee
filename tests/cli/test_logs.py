"""``tourbot log`` and bad input on the command line: one clear line, exit code 2, no traceback."""

from __future__ import annotations

import gzip
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from tourbot.cli.main import main
from tourbot.io import read_carmen
from tourbot.io.tum import read_tum
from tourbot.records import RobotLog


def _run(args: list[str]) -> int:
    try:
        main(args)
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


def test_log_info(fhw_log_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _run(["log", "info", str(fhw_log_path)]) == 0
    out = capsys.readouterr().out
    for expected in ("488", "180", "2007.2 s", "405.5 m", "FLASER"):
        assert expected in out


def test_log_info_names_the_whole_file_on_one_line(
    fhw_log_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _run(["log", "info", str(fhw_log_path)]) == 0
    assert capsys.readouterr().out.splitlines()[0].strip() == str(fhw_log_path)


def test_log_info_of_a_bag(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = shared_data / "leg_tracker" / "positive_1.bag"
    assert _run(["log", "info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "400" in out
    assert "768" in out


def test_convert_and_tum(fhw_log_path: Path, tmp_path: Path, real_log: Callable[[str], RobotLog]) -> None:
    copy = tmp_path / "fhw.log.gz"
    assert _run(["log", "convert", str(fhw_log_path), "-o", str(copy)]) == 0
    assert len(read_carmen(copy)) == 488
    traj = tmp_path / "ref.txt"
    assert _run(["log", "tum", str(fhw_log_path), "-o", str(traj)]) == 0
    times, poses = read_tum(traj)
    log = real_log("fhw")
    np.testing.assert_array_equal(times, log.times)
    np.testing.assert_allclose(poses[:, :2], log.reference_poses[:, :2], atol=1e-12)
    from tourbot.geometry import wrap_angle

    np.testing.assert_allclose(wrap_angle(poses[:, 2] - log.reference_poses[:, 2]), 0.0, atol=1e-12)


def _bad_inputs(tmp_path: Path, fhw: Path) -> dict[str, tuple[Path, str]]:
    nan = tmp_path / "nan.log"
    nan.write_text("FLASER 3 1.0 nan 2.0 0 0 0 0 0 0 1.0 h 1.0\n")
    neg = tmp_path / "neg.log"
    neg.write_text("FLASER 2 1.0 2.0 0 0 0 0 0 0 1.0 h 1.0\nFLASER 2 -1.0 2.0 0 0 0 0 0 0 2.0 h 2.0\n")
    cut = tmp_path / "cut.log.gz"
    cut.write_bytes(fhw.read_bytes()[:50_000])
    empty = tmp_path / "empty.log"
    empty.write_text("")
    garbage = tmp_path / "garbage.log"
    garbage.write_bytes(bytes(range(256)) * 16)
    notgz = tmp_path / "bad.log.gz"
    notgz.write_bytes(gzip.compress(b"ODOM 0 0 0 0 0 0 1 h 1\n")[:-12] + b"\xff" * 12)
    return {
        "nan": (nan, "nan.log:1 (field range[1]): FLASER range is nan (not a number)"),
        "negative": (neg, "neg.log:2 (field range[0]): FLASER range is negative (-1.0)"),
        "truncated gzip": (cut, "the gzip stream is truncated"),
        "empty": (empty, "empty.log: empty file"),
        "garbage": (garbage, "garbage.log:1: binary data"),
        "corrupt gzip": (notgz, "gzip stream"),
        "missing": (tmp_path / "missing.log", "missing.log: no such file"),
    }


@pytest.mark.parametrize(
    "case", ["nan", "negative", "truncated gzip", "empty", "garbage", "corrupt gzip", "missing"]
)
def test_bad_logs_give_one_clear_line(
    case: str, tmp_path: Path, fhw_log_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, expected = _bad_inputs(tmp_path, fhw_log_path)[case]
    assert _run(["log", "info", str(path)]) == 2
    err = capsys.readouterr().err
    assert expected in " ".join(err.split())
    assert "Traceback" not in err


def test_lenient_skips_and_counts(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "some_bad.log"
    path.write_text(
        "FLASER 2 1.0 2.0 0 0 0 0 0 0 1.0 h 1.0\nFLASER 2 -1.0 2.0 0 0 0 0 0 0 2.0 h 2.0\n"
        "FLASER 2 1.0 2.0 0 0 0 0 0 0 3.0 h 3.0\n"
    )
    assert _run(["log", "info", "--lenient", str(path)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "skipped 1 malformed record(s) (first: line 2, field range[0]" in out


def test_bag_without_laser_topics_on_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from tests.io.test_rosbag import _write_ros2

    path = tmp_path / "odom_only"
    _write_ros2(path, scans=0, odoms=2)
    assert _run(["log", "info", str(path)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "no sensor_msgs/LaserScan topic in this bag (topics: /odom (nav_msgs/msg/Odometry))" in err


def test_real_process_prints_no_traceback(tmp_path: Path) -> None:
    path = tmp_path / "nan.log"
    path.write_text("FLASER 3 1.0 nan 2.0 0 0 0 0 0 0 1.0 h 1.0\n")
    proc = subprocess.run(
        [sys.executable, "-m", "tourbot", "log", "info", str(path)],
        capture_output=True,
        text=True,
        env={"PYTHONPATH": str(Path(__file__).parents[2] / "src"), "COLUMNS": "200"},
        check=False,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert "range[1]" in proc.stderr


def test_a_plain_folder_is_not_taken_for_a_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "logs"
    folder.mkdir()
    assert _run(["log", "info", str(folder)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"{folder}: a folder, not a log file" in err
    assert "Traceback" not in err


def test_convert_creates_the_output_folder(fhw_log_path: Path, tmp_path: Path) -> None:
    out = tmp_path / "new" / "deeper" / "fhw.log"
    assert _run(["log", "convert", str(fhw_log_path), "-o", str(out)]) == 0
    assert len(read_carmen(out)) == 488


def test_log_info_says_what_it_inferred_and_how_the_odometry_was_read(
    fhw_log_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    main(["log", "info", str(fhw_log_path)])
    out = capsys.readouterr().out
    assert "rebuilt" in out
    assert "inferred: beams: -90 to +89 deg" in " ".join(out.split())
    assert "inferred: max range: 51.05 m" in " ".join(out.split())
    assert "odometry vs reference │ 26." in " ".join(out.split())  # README: about 26 m, aligned
    main(["log", "info", str(fhw_log_path), "--odometry-stream", "as-recorded"])
    out = " ".join(capsys.readouterr().out.split())
    assert "re-anchored" in out
    assert "odometry vs reference │ 0.07 m RMS" in out


def test_log_info_never_prints_a_duration_it_cannot_know(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "zero.log"
    lines = [
        f"ODOM {0.1 * k} 0 0 0 0 0 0 host 0\nFLASER 3 1 2 3 {0.1 * k} 0 0 {0.1 * k} 0 0 0 host 0"
        for k in range(5)
    ]
    path.write_text("\n".join(lines) + "\n")
    main(["log", "info", str(path)])
    out = " ".join(capsys.readouterr().out.split())
    assert "duration │ unknown (the scan timestamps are all zero)" in out


@pytest.mark.parametrize("name", ["fhw.mcap", "fhw_bag"])
def test_convert_to_a_ros2_bag_reads_back_the_same_scans_and_odometry(
    fhw_log_path: Path, tmp_path: Path, name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from tourbot.io import load_log

    out = tmp_path / name
    assert _run(["log", "convert", str(fhw_log_path), "-o", str(out)]) == 0
    if out.suffix == "":
        assert (out / "metadata.yaml").is_file()
        assert [f.suffix for f in out.iterdir() if f.name != "metadata.yaml"] == [".db3"]
    assert not list(tmp_path.glob("*.partial*"))
    original, back = load_log(fhw_log_path), load_log(out)
    assert len(back.scans) == len(original.scans) == 488
    assert len(back.odometry) == len(original.odometry)
    for a, b in zip(original.scans, back.scans, strict=True):
        assert abs(a.timestamp - b.timestamp) < 1e-6
        ret = a.ranges < a.geometry.max_range  # returns the same; "no return" stays no return
        np.testing.assert_allclose(b.ranges[ret], a.ranges[ret], atol=1e-5)
        assert np.all(b.ranges[~ret] >= b.geometry.max_range - 1e-5)
        assert a.odom is not None
        assert b.odom is not None
        np.testing.assert_allclose(b.odom, a.odom, atol=1e-5)
    assert back.scans[0].geometry.offset == pytest.approx(original.scans[0].geometry.offset, abs=1e-6)
    # an existing output is kept unless --force (and --force never replaces a plain folder)
    capsys.readouterr()
    assert _run(["log", "convert", str(fhw_log_path), "-o", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
    assert _run(["log", "convert", str(fhw_log_path), "-o", str(out), "--force"]) == 0
    plain = tmp_path / "plain"
    plain.mkdir()
    assert _run(["log", "convert", str(fhw_log_path), "-o", str(plain), "--force"]) == 2


def _fhw_variant(fhw_log_path: Path, tmp_path: Path, first: str) -> Path:
    with gzip.open(fhw_log_path, "rt") as f:
        lines = [first, *f.read().splitlines()]
    out = tmp_path / "variant.log.gz"
    with gzip.open(out, "wt", compresslevel=1) as f:
        f.write("\n".join(lines) + "\n")
    return out


def test_log_info_says_a_radians_field_of_view_was_read_as_radians(
    fhw_log_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # issue 22: "log info" printed "field of view 180.0 deg" for scans rotated by 88 deg
    variant = _fhw_variant(fhw_log_path, tmp_path, "PARAM laser_front_laser_fov 3.14159 x 0")
    main(["log", "info", str(variant)])
    out = " ".join(capsys.readouterr().out.split())
    assert "field of view │ 179.0 deg" in out  # 180 beams 1 deg apart, the first at -90 deg
    assert "inferred: beams: -90 to +89 deg (PARAM laser_front_laser_fov 3.14159 read as radians" in out
    assert "PARAM field of view read as degrees: 57.3 cm" in out  # the reading it turned down, and why


def test_log_info_says_a_10_m_range_param_is_a_software_cap(
    fhw_log_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    main(["log", "info", str(_fhw_variant(fhw_log_path, tmp_path, "PARAM robot_front_laser_max 10 x 0"))])
    out = " ".join(capsys.readouterr().out.split())
    assert "max range │ 51.05 m" in out
    assert "read as a software cap" in out
