"""The camera on the robot: landmark projection (Eq. 3, Alg. 1), tilt, swing, calibration files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tourbot.ceiling.camera import KannalaBrandt
from tourbot.ceiling.rig import CYCLOID_CAMERA, CeilingCamera, load_camera
from tourbot.errors import InputError


def test_light_straight_above_is_at_the_image_centre() -> None:
    cam = CeilingCamera()
    uv, seen = cam.project_lights([[3.0, 4.0, 0.5]], [[3.0, 4.0, 6.0]])
    assert seen[0, 0]
    assert uv[0, 0] == pytest.approx([320.0, 240.0], abs=1e-6)


def test_light_ahead_is_along_plus_u_and_turning_moves_it() -> None:
    cam = CeilingCamera()
    uv, _ = cam.project_lights([[0.0, 0.0, 0.0], [0.0, 0.0, math.pi / 2]], [[2.0, 0.0, 5.0]])
    assert uv[0, 0, 0] > 320.0
    assert uv[0, 0, 1] == pytest.approx(240.0)
    # facing +y, the light at +x is to the robot's right: -v
    assert uv[1, 0, 0] == pytest.approx(320.0)
    assert uv[1, 0, 1] < 240.0


def test_tilt_shifts_the_zenith() -> None:
    tilted = CeilingCamera(pitch=math.radians(5.0))
    uv, _ = tilted.project_lights([[0.0, 0.0, 0.0]], [[0.0, 0.0, 10.0]])
    assert uv[0, 0, 0] < 320.0  # the optical axis leans forward: the zenith is behind it
    # a swing of the base by the opposite pitch turns the axis back up (and moves the camera by
    # 1.8 m x sin 5 deg, which a very high light does not show)
    uv2, _ = tilted.project_lights([[0.0, 0.0, 0.0]], [[0.0, 0.0, 1e5]], swing=(0.0, -math.radians(5.0)))
    assert uv2[0, 0] == pytest.approx([320.0, 240.0], abs=0.01)


def test_rim_rejects_lights_near_the_horizon() -> None:
    cam = CeilingCamera(rim_theta=math.radians(60.0))
    _, seen = cam.project_lights([[0.0, 0.0, 0.0]], [[1.0, 0.0, 5.0], [20.0, 0.0, 3.0]])
    assert seen[0].tolist() == [True, False]


def test_image_of_the_wrong_size_names_the_field() -> None:
    with pytest.raises(InputError, match=r"field image.size.*640x480"):
        CeilingCamera().check_image((240, 320), path="x.png")


def test_camera_file(tmp_path: Path) -> None:
    f = tmp_path / "cam.yaml"
    f.write_text(
        "model: kannala-brandt\nfx: 193.26\nfy: 192.68\ncx: 347.8\ncy: 245.5\nk1: 0.00925\npitch_deg: 22\n"
    )
    cam = load_camera(f)
    assert cam.pitch == pytest.approx(math.radians(22.0))
    f.write_text("model: kannala-brandt\nfx: 193.26\nfy: 192.68\ncx: 900\ncy: 245.5\n")
    with pytest.raises(InputError, match=r"cam.yaml \(field model\): image centre"):
        load_camera(f)
    f.write_text("model: kannala-brandt\nfx: 193.26\ncx: 300\ncy: 245.5\n")
    with pytest.raises(InputError, match=r"field fy"):
        load_camera(f)
    f.write_text("focal: 3\n")
    with pytest.raises(InputError, match=r"field focal"):
        load_camera(f)


def test_published_calibration_sees_the_zenith_ahead_of_the_centre() -> None:
    assert isinstance(CYCLOID_CAMERA.model, KannalaBrandt)
    uv, seen = CYCLOID_CAMERA.project_lights([[0.0, 0.0, 0.0]], [[0.0, 0.0, 8.0]])
    assert seen[0, 0]
    assert uv[0, 0, 0] < CYCLOID_CAMERA.model.cx - 50  # 22 degrees of tilt, about 75 px
    assert np.isfinite(uv).all()
