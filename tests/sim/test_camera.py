"""The one camera renderer and the simulated upward camera: determinism, saturation and blooming,
lights off, spurious blobs, occlusion by tall visitors, and a pinhole through the same renderer."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tourbot.ceiling.camera import Pinhole
from tourbot.ceiling.detection import DetectionConfig, detect_lights
from tourbot.ceiling.rig import CeilingCamera
from tourbot.sim.camera import CameraSimConfig, CameraSimError, CeilingCameraSim, Patch, RenderConfig, render
from tourbot.site.default import site_path
from tourbot.site.model import load_site, site_from_dict


@pytest.fixture(scope="module")
def domus():  # type: ignore[no-untyped-def]
    return load_site(site_path("domus"))


def test_deterministic_per_seed(domus) -> None:  # type: ignore[no-untyped-def]
    cfg = CameraSimConfig(swing_std_deg=1.0)
    a = CeilingCameraSim(domus, CeilingCamera(), cfg, seed=4).frame(0.0, (3.0, -6.0, 0.2)).image
    b = CeilingCameraSim(domus, CeilingCamera(), cfg, seed=4).frame(0.0, (3.0, -6.0, 0.2)).image
    c = CeilingCameraSim(domus, CeilingCamera(), cfg, seed=5).frame(0.0, (3.0, -6.0, 0.2)).image
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_lights_are_where_the_rig_projects_them(domus) -> None:  # type: ignore[no-untyped-def]
    cam = CeilingCamera()
    pose = np.array([5.0, -8.0, 0.7])
    image = CeilingCameraSim(domus, cam, seed=0).frame(0.0, pose).image
    det = detect_lights(image, cam)
    lights = np.array([light.position for light in domus.ceiling_lights])
    uv, seen = cam.project_lights(pose[None], lights)
    assert len(det) >= 6
    d = np.linalg.norm(det.centroids[:, None] - uv[0][seen[0]][None], axis=2).min(axis=1)
    assert np.median(d) < 1.0
    assert d.max() < 3.0


def test_downlight_right_above_saturates_and_blooms(domus) -> None:  # type: ignore[no-untyped-def]
    cam = CeilingCamera()
    below = CeilingCameraSim(domus, cam, seed=0).frame(0.0, (22.13, 2.08, 0.0)).image  # under B42
    assert (below == 255).sum() > 200
    det = detect_lights(below, cam)
    assert det.rethresholded >= 1  # the big saturated blob processed again (Fig. 9)


def test_lights_off_and_spurious_blobs(domus) -> None:  # type: ignore[no-untyped-def]
    cam = CeilingCamera()
    pose = (10.0, -6.0, 0.0)
    full = len(detect_lights(CeilingCameraSim(domus, cam, seed=1).frame(0.0, pose).image, cam))
    dark = CeilingCameraSim(domus, cam, CameraSimConfig(lights_off=0.3), seed=1)
    assert (~dark.on).sum() == 9
    assert len(detect_lights(dark.frame(0.0, pose).image, cam)) < full
    noisy = (
        CeilingCameraSim(domus, cam, CameraSimConfig(spotlights=6, windows=4), seed=1).frame(0.0, pose).image
    )
    clean = CeilingCameraSim(domus, cam, seed=1).frame(0.0, pose).image
    assert (noisy >= 200).sum() > (clean >= 200).sum()


def test_tall_visitor_hides_a_light_near_the_horizon() -> None:
    site = site_from_dict(
        {
            "name": "one",
            "map": {"walls": [[[-20, -20], [20, -20], [20, 20], [-20, 20]]]},
            "ceiling_lights": [{"position": [6.0, 0.0, 3.0], "type": "E"}],
        },
        base_dir=site_path("domus").parent,
    )
    cam = CeilingCamera(rim_theta=math.radians(85.0))
    sim = CeilingCameraSim(site, cam, seed=0)
    seen = sim.frame(0.0, (0.0, 0.0, 0.0)).image
    sim._heights[:] = 1.95  # a tall visitor 0.6 m ahead, between the camera and the light
    hidden = sim.frame(1.0, (0.0, 0.0, 0.0), people=[[0.6, 0.0]]).image
    short = sim.frame(2.0, (0.0, 0.0, 0.0), people=[[0.6, 0.0]])
    low = DetectionConfig(threshold=80)
    assert len(detect_lights(seen, cam, low)) == 1
    assert len(detect_lights(hidden, cam, low)) == 0
    sim._heights[:] = 1.70  # shorter than the camera: hides nothing
    assert len(detect_lights(sim.frame(3.0, (0.0, 0.0, 0.0), people=[[0.6, 0.0]]).image, cam, low)) == 1
    assert short.time == 2.0


def test_site_without_lights_is_refused() -> None:
    site = site_from_dict(
        {"name": "bare", "map": {"walls": [[[0, 0], [5, 0], [5, 5]]]}}, base_dir=site_path("domus").parent
    )
    with pytest.raises(CameraSimError, match="ceiling_lights"):
        CeilingCameraSim(site, CeilingCamera())


def test_the_same_renderer_draws_a_forward_pinhole_view() -> None:
    cam = Pinhole(fx=300.0, fy=300.0, cx=160.0, cy=120.0)
    # a forward camera: optical axis along world +x, image u along -y, v along -z
    rot = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    square = Patch(np.array([[4.0, -0.5, 0.5], [4.0, 0.5, 0.5], [4.0, 0.5, 1.5], [4.0, -0.5, 1.5]]), 200.0)
    img = render(
        cam,
        320,
        240,
        rot,
        np.array([0.0, 0.0, 1.0]),
        [square],
        np.random.default_rng(0),
        RenderConfig(noise_std=0.0, vignetting=0.0),
    )
    ys, xs = np.nonzero(img > 100)
    assert abs(xs.mean() - 160.0) < 1.0
    assert abs(ys.mean() - 120.0) < 1.0
    assert 70 <= xs.max() - xs.min() + 1 <= 80  # 1 m at 4 m: 75 px


# -- the forward camera's 2.5D world -------------------------------------------------------------


def _forward_site(kind: str, height: tuple[float, float]):  # type: ignore[no-untyped-def]
    from pathlib import Path

    room = {
        "name": "room",
        "map": {"walls": [[[0, 0], [10, 0], [10, 6], [0, 6]]], "resolution": 0.05},
        "invisible_obstacles": [
            {
                "name": "o",
                "outline": [[4, 2.5], [5, 2.5], [5, 3.5], [4, 3.5]],
                "height": list(height),
                "kind": kind,
            }
        ],
    }
    return site_from_dict(room, base_dir=Path("."))


def test_forward_camera_is_deterministic_per_seed_and_draws_the_obstacle() -> None:
    from tourbot.sim.camera import ForwardCameraSim

    site = _forward_site("box", (0.0, 0.3))
    empty = site_from_dict(
        {**site.model_dump(exclude={"base_dir"}), "invisible_obstacles": []}, base_dir=site.base_dir
    )
    pose = (2.0, 3.0, 0.0)
    a = ForwardCameraSim(site, seed=3).frame(0.0, pose).image
    b = ForwardCameraSim(site, seed=3).frame(0.0, pose).image
    c = ForwardCameraSim(site, seed=4).frame(0.0, pose).image
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    assert a.shape == (480, 640)
    cam = ForwardCameraSim(site, seed=3).camera
    rot, pos = cam.in_world(pose)
    uv = cam.project(rot, pos, np.array([[4.0, 3.0, 0.3], [4.0, 3.0, 0.0]]))  # the bench's front edge
    col = int(uv[0, 0])
    rows = slice(int(uv[0, 1]) + 3, int(uv[1, 1]) - 3)
    other = ForwardCameraSim(empty, seed=3).frame(0.0, pose).image
    assert not np.array_equal(a[rows, col - 20 : col + 20], other[rows, col - 20 : col + 20])
    # above the bench's top (a far point straight ahead on the back wall) the two images agree
    top = cam.project(rot, pos, np.array([[10.0, 3.0, 1.2]]))[0]
    u, v = int(top[0]), int(top[1])
    assert (
        abs(float(a[v - 5 : v + 5, u - 5 : u + 5].mean()) - float(other[v - 5 : v + 5, u - 5 : u + 5].mean()))
        < 4
    )


def test_scene_depth_test_and_glass() -> None:
    from tourbot.sim.camera import Prism, Scene, Surface, make_texture

    rng = np.random.default_rng(0)
    square = np.array([[2.0, -0.5], [3.0, -0.5], [3.0, 0.5], [2.0, 0.5]])
    rays = np.array([[[1.0, 0.0, 0.0]]], dtype=np.float32)  # straight ahead from 0.5 m up
    pos = np.array([0.0, 0.0, 0.5])
    scene = Scene(make_texture(rng, 64), prisms=[Prism(square, (0.0, 1.0), Surface(200.0, 0.0))])
    assert scene.draw(rays, pos)[0, 0] == pytest.approx(200.0 * (0.8 + 0.2 * -0.6))  # its -x face, shaded
    near = Prism(square - [1.0, 0.0], (0.0, 1.0), Surface(50.0, 0.0))
    scene.prisms.append(near)
    assert scene.draw(rays, pos)[0, 0] == pytest.approx(50.0 * (0.8 + 0.2 * -0.6))  # nearer wins
    scene.prisms = [
        Prism(square, (0.0, 1.0), Surface(100.0, 0.0)),
        Prism(square - [1.0, 0.0], (0.0, 1.0), Surface(200.0, 0.0), 0.35),
    ]
    behind = 100.0 * (0.8 + 0.2 * -0.6)
    glass = 200.0 * (0.8 + 0.2 * -0.6)
    assert scene.draw(rays, pos)[0, 0] == pytest.approx(0.35 * glass + 0.65 * behind, rel=1e-5)
    scene.prisms = [Prism(square, (0.6, 1.0), Surface(100.0, 0.0))]  # above the ray: not hit
    assert scene.draw(rays, pos)[0, 0] != pytest.approx(behind)
