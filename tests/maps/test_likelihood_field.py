"""The likelihood field's table look-ups against a from-scratch numpy evaluation of Table 6.3."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.maps.grid import MapError, OccupancyGrid
from tourbot.maps.likelihood_field import (
    LikelihoodField,
    LikelihoodFieldParams,
    beam_log_likelihoods_reference,
    padded_table,
    surface_distance,
)
from tourbot.records import LaserGeometry


def small_grid(seed: int) -> OccupancyGrid:
    rng = np.random.default_rng(seed)
    prob = np.zeros((30, 40), dtype=np.float32)
    for _ in range(6):
        r, c = rng.integers(0, 30), rng.integers(0, 40)
        prob[r : r + rng.integers(1, 4), c : c + rng.integers(1, 4)] = 1.0
    prob[rng.integers(0, 30), :5] = -1.0
    return OccupancyGrid(
        prob, resolution=0.1, origin=(rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-3, 3))
    )


GEOM = LaserGeometry(
    num_beams=19,
    angle_min=-math.pi / 2,
    angle_increment=math.pi / 18,
    max_range=5.0,
    offset=(0.1, 0.02, 0.05),
)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), sigma=st.floats(0.05, 0.5), max_dist=st.floats(0.1, 3.0))
def test_matches_reference(seed: int, sigma: float, max_dist: float) -> None:
    grid = small_grid(seed)
    rng = np.random.default_rng(seed)
    params = LikelihoodFieldParams(sigma_hit=sigma, max_dist=max_dist, max_range=GEOM.max_range)
    field = LikelihoodField.from_grid(grid, params)
    local = np.column_stack([rng.uniform(-0.5, 4.5, 6), rng.uniform(-0.5, 3.5, 6), rng.uniform(-4, 4, 6)])
    poses = grid.grid_to_world(local)
    ranges = rng.uniform(0.0, 6.0, GEOM.num_beams)
    ranges[rng.integers(0, GEOM.num_beams)] = np.nan
    got = field.beam_log_likelihoods(poses, ranges, GEOM)
    ref = beam_log_likelihoods_reference(grid, params, poses, ranges, GEOM).astype(np.float32)
    # The table is float32, the endpoint maths float64: the same cells, so the same values.
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_allclose(
        field.log_likelihood(poses, ranges, GEOM), ref.astype(np.float64).sum(axis=1), rtol=1e-12, atol=1e-12
    )


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), longest=st.floats(0.2, 2.5), edge=st.floats(0.0, 1.0))
def test_scan_sums_match_reference_inside_and_near_the_edges(seed: int, longest: float, edge: float) -> None:
    # Poses in the middle of the grid, whose beams all end on it (the kernel's unchecked path), and
    # poses near or beyond its edges (the checked path), against the numpy Table 6.3.
    grid = small_grid(seed)
    rng = np.random.default_rng(seed)
    params = LikelihoodFieldParams(sigma_hit=0.2, max_dist=1.0, max_range=GEOM.max_range)
    field = LikelihoodField.from_grid(grid, params)
    middle = np.column_stack([rng.uniform(1.6, 2.4, 4), rng.uniform(1.1, 1.9, 4), rng.uniform(-4, 4, 4)])
    near = np.column_stack(
        [rng.uniform(-0.5, 4.5, 4) * edge, rng.uniform(-0.5, 3.5, 4) * edge, rng.uniform(-4, 4, 4)]
    )
    poses = grid.grid_to_world(np.vstack([middle, near]))
    ranges = rng.uniform(0.0, longest, GEOM.num_beams)
    ref = beam_log_likelihoods_reference(grid, params, poses, ranges, GEOM).astype(np.float32)
    np.testing.assert_array_equal(field.beam_log_likelihoods(poses, ranges, GEOM), ref)
    np.testing.assert_allclose(
        field.log_likelihood(poses, ranges, GEOM), ref.astype(np.float64).sum(axis=1), rtol=1e-12, atol=1e-12
    )


def test_endpoints_off_the_grid_score_as_far_from_any_wall() -> None:
    # Poses beyond every edge and corner (and an odd count, the kernel's single-pose tail): all
    # endpoints read the padded frame, which holds log p at max_dist.
    grid = small_grid(3)
    field = LikelihoodField.from_grid(grid, max_range=GEOM.max_range)
    assert field.padded.shape == (grid.shape[0] + 2, grid.shape[1] + 2)
    assert field.outside == pytest.approx(float(field.params.log_p(field.params.max_dist)), rel=1e-6)
    local = np.array(
        [[-9.0, 1.5, 0.0], [13.0, 1.5, 1.0], [2.0, -9.0, 2.0], [2.0, 12.0, 3.0], [-9.0, -9.0, 0.5]]
    )
    ranges = np.full(GEOM.num_beams, 1.0)
    total = field.log_likelihood(grid.grid_to_world(local), ranges, GEOM)
    np.testing.assert_allclose(total, GEOM.num_beams * field.outside, rtol=1e-12)


def test_skips_no_return_and_masked_beams() -> None:
    grid = small_grid(1)
    field = LikelihoodField.from_grid(grid, max_range=GEOM.max_range)
    poses = grid.grid_to_world(np.array([[2.0, 1.5, 0.3]]))
    ranges = np.full(GEOM.num_beams, 1.0)
    ranges[:3] = GEOM.max_range  # no return
    mask = np.ones(GEOM.num_beams, dtype=bool)
    mask[5] = False
    per_beam = field.beam_log_likelihoods(poses, ranges, GEOM, beam_mask=mask)
    assert np.all(per_beam[0, :3] == 0.0)
    assert per_beam[0, 5] == 0.0
    assert np.all(per_beam[0, 6:] < 0.0)
    total = field.log_likelihood(poses, ranges, GEOM, beam_mask=mask)
    assert total[0] == pytest.approx(float(per_beam.sum()), rel=1e-5)


def test_true_pose_scores_best_in_a_room() -> None:
    prob = np.zeros((60, 60), dtype=np.float32)
    prob[5, 5:55] = prob[54, 5:55] = prob[5:55, 5] = prob[5:40, 54] = 1.0
    grid = OccupancyGrid(prob, resolution=0.1)
    geom = LaserGeometry(num_beams=181, angle_min=-math.pi, angle_increment=2 * math.pi / 181, max_range=20.0)
    from tourbot.maps.raycast import DDACaster

    truth = np.array([[2.2, 3.1, 0.4]])
    ranges = DDACaster(grid, geom.max_range).cast(truth, geom.angles)[0]
    field = LikelihoodField.from_grid(grid, max_range=geom.max_range)
    others = truth + np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.0, -0.3, 0.0], [0.0, 0.0, 0.1]])
    ll = field.log_likelihood(others, ranges, geom)
    assert int(np.argmax(ll)) == 0


def test_bad_input_is_reported() -> None:
    grid = small_grid(0)
    field = LikelihoodField.from_grid(grid)
    with pytest.raises(MapError):
        field.log_likelihood(np.zeros((2, 3)), np.zeros(5), GEOM)
    with pytest.raises(MapError):
        LikelihoodFieldParams(sigma_hit=0.0)
    with pytest.raises(MapError, match="finite"):
        field.log_likelihood(np.array([[0.0, np.nan, 0.0]]), np.ones(GEOM.num_beams), GEOM)


def test_surface_distance_counts_depth_behind_the_surface() -> None:
    # One row: free cells 0-9, a wall of three occupied cells 10-12, unknown cells 13-15 behind it.
    prob = np.full((1, 16), -1.0, dtype=np.float32)
    prob[0, :10] = 0.0
    prob[0, 10:13] = 1.0
    grid = OccupancyGrid(prob, resolution=0.05)
    got = surface_distance(grid)[0]
    cells = {5: 4.5, 9: 0.5, 10: 0.5, 11: 1.5, 12: 2.5, 13: 3.5, 15: 5.5}
    np.testing.assert_allclose([got[c] for c in cells], [0.05 * v for v in cells.values()], atol=1e-9)
    # The book's field is zero anywhere inside the wall, the surface field grows with the depth.
    centre = LikelihoodField.from_grid(grid, LikelihoodFieldParams(sigma_hit=0.1)).table[0]
    surface = LikelihoodField.from_grid(grid, LikelihoodFieldParams(sigma_hit=0.1, distance="surface")).table[
        0
    ]
    assert centre[10] == centre[11] == centre[12]
    assert surface[10] > surface[11] > surface[12]
    assert surface[9] == pytest.approx(surface[10])


def _thick_walled_room() -> tuple[OccupancyGrid, float, float, float, float]:
    """Free space x in [0.5, 3.0), y in [0.5, 3.5) m, walls 4 cells (20 cm) thick, unknown beyond."""
    res = 0.05
    prob = np.full((80, 80), -1.0, dtype=np.float32)
    prob[6:74, 6:64] = 1.0
    prob[10:70, 10:60] = 0.0
    return OccupancyGrid(prob, resolution=res), 0.5, 3.0, 0.5, 3.5


def test_surface_field_is_not_pulled_into_thick_walls() -> None:
    grid, _, x1, y0, y1 = _thick_walled_room()
    geom = LaserGeometry(num_beams=181, angle_min=-math.pi / 2, angle_increment=math.pi / 180, max_range=20.0)
    px, py = 1.7512, 2.0133  # robot facing +x, the wall at x1 ahead
    a = geom.angles
    c, s = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 1e-9, (x1 - px) / c, np.inf)
        ty = np.where(s > 1e-9, (y1 - py) / s, np.where(s < -1e-9, (y0 - py) / s, np.inf))
    ranges = np.minimum(tx, ty)  # exact ranges to the free-space surface
    ranges[np.abs(a) > math.radians(40.0)] = geom.max_range  # only the wall ahead: no corners
    shifts = np.arange(-0.10, 0.1001, 0.005)
    poses = np.column_stack([px + shifts, np.full(shifts.size, py), np.zeros(shifts.size)])
    ll = {
        d: LikelihoodField.from_grid(
            grid, LikelihoodFieldParams(sigma_hit=0.1, max_range=20.0, distance=d)
        ).log_likelihood(poses, ranges, geom)
        for d in ("centre", "surface")
    }
    at = {round(v, 3): i for i, v in enumerate(shifts)}

    def plateau_middle(v: np.ndarray) -> float:
        top = shifts[v >= v.max() - 1e-6]  # 5 cm cells: the best poses form a plateau
        return float(0.5 * (top.min() + top.max()))

    # The book's field: 10 cm into the wall ahead scores as well as the true pose; its best poses
    # lie ahead of the true one.
    assert ll["centre"][at[0.1]] >= ll["centre"][at[0.0]] - 1e-6
    assert plateau_middle(ll["centre"]) >= 0.05
    # The surface field's best poses are centred on the true pose, and it falls off on both sides.
    assert abs(plateau_middle(ll["surface"])) <= 0.01
    assert ll["surface"][at[0.1]] < ll["surface"][at[0.0]] - 5.0
    assert ll["surface"][at[-0.1]] < ll["surface"][at[0.0]] - 5.0


def test_distance_kind_is_checked() -> None:
    with pytest.raises(MapError, match="distance"):
        LikelihoodFieldParams(distance="edge")  # type: ignore[arg-type]


def test_grids_beyond_32_bit_cell_indices_are_refused() -> None:
    huge = np.broadcast_to(np.float32(0.0), (50_000, 50_000))  # a view: nothing is allocated
    with pytest.raises(MapError, match="32-bit"):
        padded_table(huge, -5.0)
