"""Pieces of ``tourbot bench ceiling``: the path, the error measures, one short run."""

from __future__ import annotations

import math

import numpy as np

from tourbot.bench.ceiling import DOMUS_PATH, _errors, path_poses, run_path
from tourbot.sim.camera import CameraSimConfig
from tourbot.site.default import site_path
from tourbot.site.model import load_site


def test_domus_path_is_24_m_with_headings_along_it() -> None:
    p = path_poses(DOMUS_PATH, 0.4)
    assert len(p) == 61  # 60 images a second apart at 0.4 m/s, and the end
    assert p[0, 2] == 0.0
    assert p[-1, 2] == math.pi / 2
    assert abs(float(np.hypot(*np.diff(p[:, :2], axis=0).T).sum()) - 24.0) < 1e-9


def test_errors_wrap_the_heading_and_count_no_answer_as_infinite() -> None:
    truth = np.array([[0.0, 0.0, math.pi - 0.01], [1.0, 1.0, 0.0]])
    est = np.array([[0.3, 0.4, -math.pi + 0.01], [np.nan, np.nan, np.nan]])
    pos, ang = _errors(est, truth)
    assert abs(pos[0] - 0.5) < 1e-12
    assert abs(ang[0] - math.degrees(0.02)) < 1e-9
    assert math.isinf(pos[1])
    assert math.isinf(ang[1])


def test_a_short_run_localizes_with_all_three_methods() -> None:
    site = load_site(site_path("domus"))
    path = path_poses(DOMUS_PATH, 0.04)[:21]
    run = run_path(site, 0, path, 10, ("paper", "tourbot", "tracking"), CameraSimConfig())
    assert run.truth.shape == (3, 3)
    for m in ("tourbot", "tracking"):
        pos, _ = _errors(run.est[m], run.truth)
        assert pos.max() < 0.1
    assert run.evaluations > 1902
