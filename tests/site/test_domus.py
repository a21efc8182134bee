"""The Domus hall of Gamallo et al.: Table I's 30 lights, their types, an outline marked approximate."""

from __future__ import annotations

import numpy as np

from tourbot.site.default import site_path
from tourbot.site.model import load_site


def test_domus_has_table_1() -> None:
    site = load_site(site_path("domus"))
    lights = {light.name: light for light in site.ceiling_lights}
    assert len(lights) == 30
    assert sum(light.type == "E" for light in lights.values()) == 6
    assert sum(light.type == "A" for light in lights.values()) == 6
    assert sum(light.type == "B" for light in lights.values()) == 18
    assert lights["E1"].position == (-3.45, -2.26, 11.39)
    assert lights["A4"].position == (10.56, -11.25, 10.5)
    assert lights["B65"].position == (27.5, -1.27, 3.24)  # Table I's "R65"
    assert "map.walls" in site.approximate
    # every light stands over the hall, and the tour's viewing poses are on free floor
    grid = site.grid
    xy = np.array([light.position[:2] for light in lights.values()])
    cells = grid.world_to_cell(xy)
    assert grid.inside(cells).all()
    for name in site.tour("hall").exhibits:
        pose = site.exhibit(name).viewing_pose
        c = grid.world_to_cell(np.array([pose[:2]]))
        assert grid.free()[c[0, 0], c[0, 1]]
