from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.people.association import (
    cluster_betas,
    cluster_betas_reference,
    joint_betas,
    joint_betas_reference,
    pair_likelihoods,
    pair_likelihoods_reference,
    sample_weights,
    sample_weights_reference,
)


@st.composite
def clusters(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
    t = draw(st.integers(1, 4))
    f = draw(st.integers(0, 4))
    vals = draw(st.lists(st.floats(0.0, 50.0), min_size=t * f, max_size=t * f))
    gated = draw(st.lists(st.booleans(), min_size=t * f, max_size=t * f))
    ratio = (np.array(vals) * np.array(gated)).reshape(t, f)
    miss = np.array(draw(st.lists(st.floats(0.01, 1.0), min_size=t, max_size=t)))
    return ratio, miss


@settings(max_examples=80, deadline=None)
@given(clusters())
def test_joint_betas_kernel_matches_enumeration(cluster: tuple[np.ndarray, np.ndarray]) -> None:
    ratio, miss = cluster
    beta = joint_betas(ratio, miss)
    np.testing.assert_allclose(beta, joint_betas_reference(ratio, miss), rtol=1e-9, atol=1e-12)
    # Each person is either missed or takes one feature: its row sums to one.
    np.testing.assert_allclose(beta.sum(axis=1), 1.0, rtol=1e-9)
    # A feature goes to at most one person per event: its betas sum to at most one.
    assert np.all(beta[:, 1:].sum(axis=0) <= 1.0 + 1e-9)
    # No probability outside the gates.
    assert np.all(beta[:, 1:][ratio == 0.0] == 0.0)


def test_two_people_one_feature_share_it_by_likelihood() -> None:
    # Eq. 7 by hand: events {miss, miss}, {1->A, miss}, {miss, 1->B}; A twice as likely as B.
    ratio = np.array([[4.0], [2.0]])
    miss = np.array([0.5, 0.5])
    beta = joint_betas(ratio, miss)
    total = 0.25 + 4.0 * 0.5 + 2.0 * 0.5
    assert beta[0, 1] == pytest.approx(2.0 / total)
    assert beta[1, 1] == pytest.approx(1.0 / total)
    assert beta[0, 0] == pytest.approx((0.25 + 1.0) / total)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**16), k=st.integers(1, 3), n=st.integers(1, 20), m=st.integers(1, 4))
def test_pair_likelihoods_and_weights_match_reference(seed: int, k: int, n: int, m: int) -> None:
    rng = np.random.default_rng(seed)
    samples = rng.normal(0.0, 0.5, (k, n, 4))
    detect = rng.uniform(0.0, 0.9, (k, n))
    features = rng.normal(0.0, 0.5, (m, 2))
    pairs = np.array(list(itertools.product(range(k), range(m))))
    pt, pf = pairs[:, 0].copy(), pairs[:, 1].copy()
    sigma = rng.uniform(0.05, 0.3, m)
    lik = pair_likelihoods(samples, detect, features, pt, pf, sigma)
    np.testing.assert_allclose(
        lik, pair_likelihoods_reference(samples, detect, features, pt, pf, sigma), rtol=1e-10
    )
    beta = rng.uniform(0.0, 1.0, size=(len(pt),))
    beta0 = rng.uniform(0.0, 1.0, k)
    w = sample_weights(lik, pt, beta, 1.0 - detect, beta0)
    np.testing.assert_allclose(
        w, sample_weights_reference(lik, pt, beta, 1.0 - detect, beta0), rtol=1e-9, atol=1e-15
    )
    np.testing.assert_allclose(w.sum(axis=1), 1.0)


def test_weights_favour_samples_near_the_feature() -> None:
    samples = np.zeros((1, 3, 4))
    samples[0, :, 0] = [0.0, 0.5, 2.0]
    detect = np.full((1, 3), 0.9)
    pt, pf = np.array([0]), np.array([0])
    lik = pair_likelihoods(samples, detect, np.array([[0.0, 0.0]]), pt, pf, np.array([0.2]))
    w = sample_weights(lik, pt, np.array([1.0]), 1.0 - detect, np.array([0.0]))
    assert w[0, 0] > w[0, 1] > w[0, 2]


@st.composite
def scenes(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    k = draw(st.integers(1, 5))
    m = draw(st.integers(1, 5))
    gated = np.array(draw(st.lists(st.booleans(), min_size=k * m, max_size=k * m))).reshape(k, m)
    pt, pf = np.nonzero(gated)
    ratio = np.array(draw(st.lists(st.floats(0.01, 50.0), min_size=pt.size, max_size=pt.size)))
    miss = np.array(draw(st.lists(st.floats(0.01, 1.0), min_size=k, max_size=k)))
    return pt.astype(np.int64), pf.astype(np.int64), ratio, miss, m


@settings(max_examples=80, deadline=None)
@given(scenes())
def test_clusters_factorise_the_joint_events(
    scene: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int],
) -> None:
    # Enumerating each cluster on its own gives the betas of enumerating everything at once.
    pt, pf, ratio, miss, m = scene
    beta, beta0 = cluster_betas(pt, pf, ratio, miss, m, max_events=10**9)
    ref_beta, ref_beta0 = cluster_betas_reference(pt, pf, ratio, miss, m)
    np.testing.assert_allclose(beta, ref_beta, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(beta0, ref_beta0, rtol=1e-9, atol=1e-12)


def test_pruning_bounds_the_events_and_keeps_the_strong_pairs() -> None:
    # 6 people all gating 6 features: 13,327 joint events; pruned to the 2 best options each.
    rng = np.random.default_rng(0)
    pt, pf = (a.ravel() for a in np.meshgrid(np.arange(6), np.arange(6), indexing="ij"))
    ratio = rng.uniform(0.1, 1.0, 36)
    ratio[pt == pf] = 100.0  # person i is plainly feature i
    beta, beta0 = cluster_betas(pt, pf, ratio, np.full(6, 0.1), 6, max_events=1000)
    assert np.all(beta[pt == pf] > 0.95)
    assert np.all(beta0 < 0.05)


def test_a_crowd_pruned_to_one_option_each_falls_into_independent_pieces() -> None:
    # 40 visitors in a row around the robot, each gating its own leg feature strongly and its two
    # neighbours' weakly: one cluster of 40. Pruned to the best option each, it is 40 pieces of
    # one person and one feature (2^40 joint events if enumerated as one): each person takes its
    # feature with probability ratio / (ratio + miss), Eq. 7 for one person and one feature.
    k = 40
    pt = np.concatenate([np.arange(k), np.arange(k - 1), np.arange(1, k)])
    pf = np.concatenate([np.arange(k), np.arange(1, k), np.arange(k - 1)])
    ratio = np.concatenate([np.full(k, 20.0), np.full(2 * (k - 1), 0.5)])
    miss = np.full(k, 0.2)
    beta, beta0 = cluster_betas(pt, pf, ratio, miss, k, max_events=5000)
    best = pt == pf
    np.testing.assert_allclose(beta[best], 20.0 / 20.2, rtol=1e-9)
    np.testing.assert_allclose(beta0, 0.2 / 20.2, rtol=1e-9)
    assert np.all(beta[~best] == 0.0)


def test_pruning_stops_as_soon_as_the_pieces_are_small_enough() -> None:
    # Two groups of 3 visitors, each gating the 3 features of its group, linked into one cluster by
    # one weak pair. 4^3 = 64 events per group: with a budget of 100 the weakest options go until
    # the groups separate, and each group keeps the options that fit its budget.
    group = np.array([(i, j) for i in range(3) for j in range(3)])
    pairs = np.concatenate([group, group + 3, [[2, 3]]])
    pt, pf = pairs[:, 0].copy(), pairs[:, 1].copy()
    rng = np.random.default_rng(1)
    ratio = np.asarray(rng.uniform(1.0, 2.0, pairs.shape[0]), dtype=np.float64)
    ratio[-1] = 0.01
    miss = np.full(6, 0.3)
    beta, beta0 = cluster_betas(pt, pf, ratio, miss, 6, max_events=100)
    ref_beta, ref_beta0 = cluster_betas_reference(pt[:-1], pf[:-1], ratio[:-1], miss, 6)
    np.testing.assert_allclose(beta[:-1], ref_beta, rtol=1e-9)
    np.testing.assert_allclose(beta0, ref_beta0, rtol=1e-9)
    assert beta[-1] == 0.0
