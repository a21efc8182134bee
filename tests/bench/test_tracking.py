from __future__ import annotations

from pathlib import Path

import numpy as np

from tourbot.bench._stonesoup_jpda import StoneSoupJPDA
from tourbot.bench.tracking import run_sjpdaf, score_frames, simulate_crowd


def test_truth_as_hypotheses_scores_perfectly() -> None:
    run = simulate_crowd(5, 20, seed=1)
    hyps = [
        [(int(i), float(p[i, 0]), float(p[i, 1])) for i in np.flatnonzero(c)]
        for p, c in zip(run.truth, run.counted, strict=True)
    ]
    m = score_frames(run, hyps)
    assert sum(c.sum() for c in run.counted) > 0
    assert m["mota"] == 1.0
    assert m["motp"] == 0.0
    assert m["num_switches"] == 0.0


def test_sjpdaf_tracks_a_small_crowd() -> None:
    run = simulate_crowd(5, 60, seed=2)
    hyps, feats, cost = run_sjpdaf(run)
    assert len(feats) == 60
    assert cost[0] > 0.0
    m = score_frames(run, hyps)
    assert m["mota"] > 0.6
    assert m["motp"] < 0.15


def test_stonesoup_peer_follows_a_walker() -> None:
    peer = StoneSoupJPDA()
    out: list[tuple[int, float, float]] = []
    for k in range(20):
        out = peer.update(0.1 * k, np.array([[1.0 + 0.1 * k, 2.0]]))
    assert len(out) == 1
    assert abs(out[0][1] - 2.9) < 0.1
    assert abs(out[0][2] - 2.0) < 0.1


def test_parse_seeds_reads_ranges_and_lists() -> None:
    from tourbot.bench.tracking import parse_seeds

    assert parse_seeds("0") == [0]
    assert parse_seeds("0-3") == [0, 1, 2, 3]
    assert parse_seeds("0-1, 7") == [0, 1, 7]
    for bad in ["", "x", "1-"]:
        try:
            parse_seeds(bad)
        except ValueError:
            continue
        raise AssertionError(f"{bad!r} was accepted")


def test_track_scores_count_misses_and_switches_of_the_walker(shared_data: Path, tmp_path: Path) -> None:
    from tourbot.bench.tracking import Trace, _draw_traces, track_scores
    from tourbot.people.leg_classifier import default_model

    bag = shared_data / "leg_tracker" / "positive_2_extracted.bag"
    trace: Trace = []
    s = track_scores(bag, default_model(), trace=trace)
    assert s["scans"] == len(trace) == 83
    annotated = sum(len(truth) > 0 for _, truth, _ in trace)
    # the person is missed in the scans where no confirmed track is near them, some but not all
    assert 0 < s["misses"] < annotated
    covered = [tracks for _, truth, tracks in trace if len(truth) and tracks]
    assert s["switches"] <= len(covered)
    assert 0.0 < s["recall"] <= 1.0
    # furniture tracks are a share of the confirmed tracks that are not near an annotated leg
    assert 0.0 <= s["furniture_per_scan"] <= s["tracks_per_scan"] * (1.0 - s["precision"]) + 1e-9
    _draw_traces({bag.name: trace}, tmp_path / "t.png")
    assert (tmp_path / "t.png").stat().st_size > 1000


def test_tour_scene_has_followers_and_standing_visitors() -> None:
    from tourbot.bench.tracking import SimConfig, simulate_tour, standing_tracked, tour_path

    cfg = SimConfig()
    # The robot stands at its first stop, then drives at its speed.
    np.testing.assert_allclose(tour_path(0.0, cfg)[:2], tour_path(19.0, cfg)[:2])
    moved = np.linalg.norm(tour_path(21.0, cfg)[:2] - tour_path(20.0, cfg)[:2])
    assert abs(moved - cfg.robot_speed) < 1e-9
    run = simulate_tour(10, 80, seed=0)
    assert sum(int(a.sum()) for a in run.at_robot) > 0
    assert sum(int((s & c).sum()) for s, c in zip(run.standing, run.counted, strict=True)) > 0
    truth = [
        [(int(i), float(p[i, 0]), float(p[i, 1])) for i in np.flatnonzero(c)]
        for p, c in zip(run.truth, run.counted, strict=True)
    ]
    assert standing_tracked(run, truth) == 1.0
    assert standing_tracked(run, [[] for _ in truth]) == 0.0


def test_the_rules_chosen_are_those_of_least_cost_on_the_recordings_given() -> None:
    from tourbot.bench.tracking import RULES, choose_rules, rule_cost

    assert "shipped" in RULES
    assert RULES["shipped"] == {}  # the defaults are among the candidates
    row = {"furniture_per_scan": 0.2, "misses": 30.0, "scans": 100.0}
    assert abs(rule_cost(row) - 0.5) < 1e-12
    costs = {"a": {"p1": 0.1, "p2": 0.9}, "b": {"p1": 0.5, "p2": 0.2}}
    assert choose_rules(costs, ["p1"]) == "a"
    assert choose_rules(costs, ["p2"]) == "b"
    assert choose_rules(costs, ["p1", "p2"]) == "b"  # mean 0.35 against 0.5


def test_the_ego_motion_rows_of_a_bag_with_three_lasers(shared_data: Path, tmp_path: Path) -> None:
    from tests.cli.test_people import _first_scans_of
    from tourbot.bench.tracking import negative_ego_motion

    bag = _first_scans_of(shared_data / "leg_tracker" / "negative_2.bag", tmp_path / "three.bag", 30)
    rows = negative_ego_motion(bag)
    assert [r["lasers"] for r in rows] == [
        "/left_scan + /rear_scan + /right_scan",
        "/left_scan",
        "/rear_scan",
        "/right_scan",
        "/rear_scan + /right_scan",
        "/left_scan + /right_scan",
        "/left_scan + /rear_scan",
        "/left_scan (before)",
        "/rear_scan (before)",
        "/right_scan (before)",
    ]
    assert "mounts from the scans" in str(rows[0]["mounts"])
    assert all(float(r["path_m"]) > 0.3 for r in rows)  # the robot starts to drive in these 4 s
