"""Clustering of samples and the estimate: the kernels against their references."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from tourbot.geometry import wrap_angle
from tourbot.localization.mcl.clustering import (
    best_cluster_estimate,
    best_cluster_estimate_reference,
    cluster_bins,
    cluster_bins_reference,
)

poses_strategy = arrays(
    np.float64,
    st.tuples(st.integers(1, 60), st.just(3)),
    elements=st.floats(-2.0, 2.0),
)


@settings(max_examples=80, deadline=None)
@given(poses_strategy)
def test_clustering_matches_reference(p: np.ndarray) -> None:
    p = p.copy()
    p[:, 2] = wrap_angle(p[:, 2] * 1.6)
    assert np.array_equal(
        cluster_bins(p, 0.5, math.radians(30)), cluster_bins_reference(p, 0.5, math.radians(30))
    )


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 6), st.integers(50, 2000))
def test_clustering_of_many_samples_matches_reference(seed: int, groups: int, n: int) -> None:
    # Sample sets like a filter's: a few blobs of various spreads (the hash table fills up).
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-6.0, 6.0, (groups, 3))
    spread = rng.uniform(0.05, 1.5, (groups, 1)) * np.array([1.0, 1.0, 0.5])
    which = rng.integers(0, groups, n)
    p = centres[which] + rng.standard_normal((n, 3)) * spread[which]
    p[:, 2] = wrap_angle(p[:, 2])
    assert np.array_equal(
        cluster_bins(p, 0.5, math.radians(10)), cluster_bins_reference(p, 0.5, math.radians(10))
    )


@settings(max_examples=60, deadline=None)
@given(poses_strategy, st.integers(0, 2**31 - 1))
def test_cluster_estimate_matches_reference(p: np.ndarray, seed: int) -> None:
    p = p.copy()
    p[:, 2] = wrap_angle(p[:, 2] * 1.6)
    w = np.asarray(np.random.default_rng(seed).random(p.shape[0])) + 0.01
    labels = cluster_bins(p, 0.5, math.radians(30))
    pose, cov, weight = best_cluster_estimate(p, w, labels)
    rpose, rcov, rweight = best_cluster_estimate_reference(p, w, labels)
    np.testing.assert_allclose(pose[:2], rpose[:2], atol=1e-9)
    assert abs(float(wrap_angle(pose[2] - rpose[2]))) < 1e-9
    np.testing.assert_allclose(cov, rcov, atol=1e-9)
    assert weight == pytest.approx(rweight)


def test_clustering_separates_distant_groups_and_wraps_heading() -> None:
    p = np.array([[0.0, 0.0, math.pi - 0.01], [0.1, 0.0, -math.pi + 0.01], [5.0, 5.0, 0.0]])
    labels = cluster_bins(p, 0.5, math.radians(10))
    assert labels[0] == labels[1] != labels[2]
