"""The numba kernels of grid Markov localization against their plain-numpy references."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.localization import grid_kernels as gk


@dataclass
class Case:
    n_theta: int
    free_rc: np.ndarray
    free_index: np.ndarray
    laser_shift: np.ndarray
    table: np.ndarray
    beam_cols: np.ndarray
    ll: np.ndarray
    ps: np.ndarray
    idx: np.ndarray
    w: np.ndarray
    used: np.ndarray

    @property
    def n_free(self) -> int:
        return int(self.free_rc.shape[0])

    @property
    def args(self) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return (self.n_free, self.free_rc, self.free_index, self.laser_shift, self.table, self.beam_cols)


@st.composite
def cases(draw: st.DrawFn) -> Case:
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    rows, cols = draw(st.integers(1, 7)), draw(st.integers(1, 7))
    free = rng.random((rows, cols)) < draw(st.floats(0.3, 1.0))
    free.flat[rng.integers(rows * cols)] = True
    free_rc = np.argwhere(free).astype(np.int64)
    free_index = np.full((rows, cols), -1, dtype=np.int64)
    free_index[free_rc[:, 0], free_rc[:, 1]] = np.arange(free_rc.shape[0])
    n_theta = draw(st.integers(1, 6))
    n_angles = draw(st.integers(1, 9))
    n_beams = draw(st.integers(1, 6))
    n_bins = draw(st.integers(1, 12))
    n_poses = n_theta * free_rc.shape[0]
    n = draw(st.integers(1, n_poses))
    idx = rng.choice(n_poses, size=n, replace=False).astype(np.int64)
    used = rng.random(n_beams) < 0.7
    return Case(
        n_theta=n_theta,
        free_rc=free_rc,
        free_index=free_index,
        laser_shift=rng.integers(-1, 2, size=(n_theta, 2)).astype(np.int64),
        table=rng.integers(0, n_bins, size=(free_rc.shape[0], n_angles)).astype(np.uint16),
        beam_cols=rng.integers(0, n_angles, size=(n_theta, n_beams)).astype(np.int64),
        ll=rng.normal(-2.0, 1.5, size=(n_beams, n_bins)),
        ps=rng.random((n_beams, n_bins)),
        idx=idx,
        w=rng.random(n) + 1e-3,
        used=used,
    )


@settings(max_examples=40, deadline=None)
@given(cases())
def test_scan_log_likelihood_matches_reference(c: Case) -> None:
    fast = gk.scan_log_likelihood(c.idx, *c.args, c.used, c.ll)
    ref = gk.scan_log_likelihood_reference(c.idx, *c.args, c.used, c.ll)
    np.testing.assert_allclose(fast, ref, rtol=1e-6, atol=1e-5)  # float32 table


@settings(max_examples=40, deadline=None)
@given(cases())
def test_filter_statistics_match_the_project_beam_filters(c: Case) -> None:
    beams = np.flatnonzero(c.used)
    mult = np.random.default_rng(len(c.idx)).integers(1, 4, len(c.idx))
    dh, pn = gk.filter_statistics(c.idx, c.w, mult.astype(np.float64), *c.args, beams, c.ll, c.ps)
    dh_ref, pn_ref = gk.filter_statistics_reference(c.idx, c.w, mult, *c.args, beams, c.ll, c.ps)
    np.testing.assert_allclose(dh[beams], dh_ref[beams], atol=1e-5)  # float32 tables
    np.testing.assert_allclose(pn[beams], pn_ref[beams], atol=1e-6)
    assert np.all(np.isnan(dh[~c.used]))
    assert np.all(np.isnan(pn[~c.used]))
    assert np.all((pn[beams] >= -1e-12) & (pn[beams] <= 1 + 1e-12))


@st.composite
def motion_cases(draw: st.DrawFn) -> tuple[Case, np.ndarray, np.ndarray]:
    c = draw(cases())
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    kt, kr, kc = draw(st.integers(1, 3)), draw(st.integers(1, 4)), draw(st.integers(1, 4))
    weights = rng.random((c.n_theta, kt, kr, kc))
    weights[weights < 0.2] = 0.0
    offsets = np.stack(
        [rng.integers(-2, 2, c.n_theta), rng.integers(-3, 2, c.n_theta), rng.integers(-3, 2, c.n_theta)],
        axis=-1,
    ).astype(np.int64)
    return c, weights, offsets


@settings(max_examples=40, deadline=None)
@given(motion_cases())
def test_motion_scatter_matches_reference(case: tuple[Case, np.ndarray, np.ndarray]) -> None:
    c, weights, offsets = case
    dense = np.zeros(c.n_theta * c.n_free)
    touched = gk.motion_scatter(
        c.idx, c.w, c.n_theta, c.n_free, c.free_rc, c.free_index, weights, offsets, dense
    )
    ref = gk.motion_scatter_reference(
        c.idx, c.w, c.n_theta, c.n_free, c.free_rc, c.free_index, weights, offsets
    )
    np.testing.assert_allclose(dense, ref, rtol=1e-12, atol=1e-15)
    assert len(np.unique(touched)) == len(touched)
    assert set(touched.tolist()) == set(np.flatnonzero(ref).tolist())
    idx, w = gk.collect(touched, dense, 0.0)
    assert not dense.any(), "collect must leave the scratch array clean"
    order = np.argsort(idx)
    ref_idx, ref_w = gk.collect_reference(ref, 0.0)
    np.testing.assert_array_equal(idx[order], ref_idx)
    np.testing.assert_allclose(w[order], ref_w, rtol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 0.9))
def test_collect_matches_reference(seed: int, ratio: float) -> None:
    rng = np.random.default_rng(seed)
    dense = np.where(rng.random(50) < 0.5, rng.random(50), 0.0)
    ref_idx, ref_w = gk.collect_reference(dense, ratio)
    touched = np.flatnonzero(dense).astype(np.int64)
    rng.shuffle(touched)
    idx, w = gk.collect(touched, dense.copy(), ratio)
    order = np.argsort(idx)
    np.testing.assert_array_equal(idx[order], ref_idx)
    np.testing.assert_allclose(w[order], ref_w)


def test_motion_scatter_conserves_mass_in_open_space_and_drops_it_in_walls() -> None:
    free = np.ones((5, 5), dtype=bool)
    free[:, 4] = False  # a wall on the right
    free_rc = np.argwhere(free).astype(np.int64)
    free_index = np.full((5, 5), -1, dtype=np.int64)
    free_index[free_rc[:, 0], free_rc[:, 1]] = np.arange(free_rc.shape[0])
    n_free = free_rc.shape[0]
    weights = np.zeros((1, 1, 1, 2))
    weights[0, 0, 0] = [0.5, 0.5]  # half stays, half moves one column right
    offsets = np.zeros((1, 3), dtype=np.int64)
    src = np.array([free_index[2, 1], free_index[2, 3]], dtype=np.int64)
    dense = np.zeros(n_free)
    touched = gk.motion_scatter(
        src, np.array([1.0, 1.0]), 1, n_free, free_rc, free_index, weights, offsets, dense
    )
    idx, w = gk.collect(touched, dense, 0.0)
    got = dict(zip(idx.tolist(), w.tolist(), strict=True))
    assert got == {free_index[2, 1]: 0.5, free_index[2, 2]: 0.5, free_index[2, 3]: 0.5}
