"""The forward camera's mount: rays and projection agree, the optical axis looks ahead and down."""

from __future__ import annotations

import math

import numpy as np

from tourbot.vision.camera import ForwardCamera


def test_rays_project_back_to_their_pixels() -> None:
    cam = ForwardCamera()
    rot, pos = cam.in_world((1.0, 2.0, 0.7))
    rays = cam.rays @ rot.T
    pts = pos + 3.0 * rays[::37, ::53]
    uv = cam.project(rot, pos, pts)
    vv, uu = np.mgrid[0 : cam.height : 37, 0 : cam.width : 53]
    assert np.allclose(uv[..., 0], uu, atol=1e-6)
    assert np.allclose(uv[..., 1], vv, atol=1e-6)


def test_optical_axis_is_tilted_down_along_the_heading() -> None:
    cam = ForwardCamera(tilt=math.radians(25.0))
    rot, pos = cam.in_world((0.0, 0.0, math.pi / 2))
    axis = rot[:, 2]
    assert np.allclose(axis, [0.0, math.cos(math.radians(25)), -math.sin(math.radians(25))])
    assert np.allclose(pos, [0.0, cam.offset, cam.mount_height])
    assert abs(np.linalg.det(rot) - 1.0) < 1e-9


def test_scaled_camera_keeps_the_field_of_view() -> None:
    cam = ForwardCamera()
    half = cam.scaled(0.5)
    assert (half.width, half.height) == (320, 240)
    assert math.isclose(half.model.fx / half.width, cam.model.fx / cam.width)
