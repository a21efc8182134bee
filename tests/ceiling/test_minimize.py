"""Global localization from one image (Alg. 3): accuracy, the paper's algorithm, symmetric layouts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tourbot.ceiling.minimize import CeilingLocalizer, LocalizerConfig
from tourbot.ceiling.rig import CeilingCamera
from tourbot.site.default import site_path
from tourbot.site.model import load_site


@pytest.fixture(scope="module")
def domus() -> tuple[np.ndarray, object]:
    site = load_site(site_path("domus"))
    return np.array([light.position for light in site.ceiling_lights]), site.grid


def _detections(
    cam: CeilingCamera, lights: np.ndarray, pose: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    uv, seen = cam.project_lights(pose[None], lights)
    return uv[0][seen[0]] + rng.normal(0.0, 0.5, (int(seen.sum()), 2))


def test_domus_poses_found_to_centimetres(domus: tuple[np.ndarray, object]) -> None:
    lights, grid = domus
    cam = CeilingCamera()
    loc = CeilingLocalizer(cam, lights, grid)  # type: ignore[arg-type]
    rng = np.random.default_rng(3)
    for truth in ([2.0, -6.0, 0.4], [20.0, 1.5, -2.0], [-6.0, -11.0, 3.0]):
        t = np.array(truth)
        best = loc.locate(_detections(cam, lights, t, rng), rng).best
        assert best is not None
        assert math.hypot(best.pose[0] - t[0], best.pose[1] - t[1]) < 0.05
        assert abs(math.remainder(best.pose[2] - t[2], 2 * math.pi)) < math.radians(0.5)


def test_the_papers_algorithm_alone_gets_near(domus: tuple[np.ndarray, object]) -> None:
    lights, grid = domus
    cam = CeilingCamera()
    cfg = LocalizerConfig(proposals=False, refine=False)
    loc = CeilingLocalizer(cam, lights, grid, cfg)  # type: ignore[arg-type]
    rng = np.random.default_rng(5)
    errors = []
    for _ in range(8):
        t = np.array([rng.uniform(-4.0, 24.0), rng.uniform(-10.0, -1.0), rng.uniform(-3.0, 3.0)])
        res = loc.locate(_detections(cam, lights, t, rng), rng)
        assert res.evaluations == cfg.initial_particles + cfg.iterations * 200
        assert res.best is not None
        errors.append(math.hypot(res.best.pose[0] - t[0], res.best.pose[1] - t[1]))
    assert np.median(errors) < 1.5  # the paper: 0.53 m mean on its real images


def test_symmetric_ceiling_gives_several_hypotheses() -> None:
    # four identical lights on a square: turning by 90 degrees about its centre looks the same
    lights = np.array([[-2.0, -2.0, 5.0], [2.0, -2.0, 5.0], [2.0, 2.0, 5.0], [-2.0, 2.0, 5.0]])
    xs, ys = np.meshgrid(np.linspace(-4, 4, 81), np.linspace(-4, 4, 81))
    free = np.column_stack([xs.ravel(), ys.ravel()])
    cam = CeilingCamera()
    loc = CeilingLocalizer(cam, lights, free)
    rng = np.random.default_rng(0)
    truth = np.array([1.0, 0.5, 0.3])
    res = loc.locate(_detections(cam, lights, truth, rng), rng)
    assert res.ambiguous
    assert len(res.hypotheses) >= 3
    assert any(math.hypot(h.pose[0] - 1.0, h.pose[1] - 0.5) < 0.1 for h in res.hypotheses)


def test_no_detections_no_hypothesis(domus: tuple[np.ndarray, object]) -> None:
    lights, grid = domus
    res = CeilingLocalizer(CeilingCamera(), lights, grid).locate(np.zeros((0, 2)), np.random.default_rng(0))  # type: ignore[arg-type]
    assert res.best is None
    assert res.evaluations == 0
