from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tourbot.mapping.consistency import ConsistencyParams, clear_specks, speck_evidence
from tourbot.maps.grid import OccupancyGrid

RES = 0.05
FREE, OCC, UNKNOWN = 0.3, 0.9, -1.0


def _floor(rows: int = 60, cols: int = 60) -> np.ndarray:
    """A map seen free everywhere."""
    return np.full((rows, cols), FREE, np.float32)


def _centre(row: int, col: int) -> np.ndarray:
    return np.array([(col + 0.5) * RES, (row + 0.5) * RES])


def _beam_to(row: int, col: int, back: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """One beam along +x ending at the centre of a cell, from ``back`` metres before it."""
    end = _centre(row, col)
    return (end - [back, 0.0])[None, :], end[None, :]


def test_a_speck_on_seen_free_floor_is_cleared() -> None:
    prob = _floor()
    prob[30, 30] = OCC
    grid = OccupancyGrid(prob, RES)
    origins, ends = _beam_to(30, 30)
    out, n = clear_specks(grid, origins, ends)
    assert n == 1
    assert not out.occupied().any()
    assert out.prob[30, 30] == pytest.approx(FREE)  # the floor's probability
    assert grid.occupied()[30, 30]  # the input is left alone


def test_a_face_with_unknown_space_behind_stays() -> None:
    """A speck with nothing seen past it (an exhibit's face seen once) is no contradiction."""
    prob = _floor()
    prob[:, 31:] = UNKNOWN  # behind the speck along the beam, and half its ring
    prob[30, 30] = OCC
    origins, ends = _beam_to(30, 30)
    ev = speck_evidence(OccupancyGrid(prob, RES), origins, ends)
    assert ev.behind_free[0] == 0.0
    assert ev.ring_free[0] == pytest.approx(14 / 24)
    assert clear_specks(OccupancyGrid(prob, RES), origins, ends)[1] == 0


def test_walls_poles_and_unseen_specks_stay() -> None:
    prob = _floor()
    prob[10, 5:50] = OCC  # a wall
    prob[40:43, 40:43] = OCC  # a pole, 3 x 3 cells
    prob[50, 20] = OCC  # a speck no kept beam ended in, alone
    prob[30, 10] = OCC  # a speck next to another one (ring not empty)
    prob[31, 12] = OCC
    origins = np.array([[0.0, _centre(40, 40)[1]], [0.0, _centre(30, 10)[1]]])
    ends = np.array([_centre(40, 40), _centre(30, 10)])
    grid = OccupancyGrid(prob, RES)
    alone = ConsistencyParams(group_radius=0)  # each speck judged on its own only
    ev = speck_evidence(grid, origins, ends, alone)
    out, n = clear_specks(grid, origins, ends, alone)
    assert n == 0
    assert np.array_equal(out.occupied(), grid.occupied())
    assert ev.cells.max() == 45
    assert len(ev.group_cells) == 0
    # with another speck allowed in the ring, the one a beam ended in goes; a speck no beam
    # ended in, the wall and the pole stay
    loose = ConsistencyParams(ring_occupied=0.1, group_radius=0)
    out, n = clear_specks(grid, origins, ends, loose)
    assert n == 1
    assert not out.occupied()[30, 10]
    assert out.occupied()[31, 12]
    assert out.occupied()[50, 20]
    assert out.occupied()[10, 5:50].all()
    assert out.occupied()[40:43, 40:43].all()
    # judged as a group (the default), the two neighbouring specks go together; the lone speck
    # no beam ended in, the wall and the pole stay
    out, n = clear_specks(grid, origins, ends)
    assert n == 2
    assert not out.occupied()[30, 10]
    assert not out.occupied()[31, 12]
    assert out.occupied()[50, 20]
    assert out.occupied()[10, 5:50].all()
    assert out.occupied()[40:43, 40:43].all()


def _group(prob: np.ndarray, cells: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray]:
    """Mark ``cells`` occupied and return one beam along +x ending in each."""
    for r, c in cells:
        prob[r, c] = OCC
    beams = [_beam_to(r, c) for r, c in cells]
    return np.concatenate([b[0] for b in beams]), np.concatenate([b[1] for b in beams])


def test_a_group_of_specks_on_seen_free_floor_is_cleared_as_a_whole() -> None:
    """Visitors standing together: specks 10-50 cm apart, each in another's ring."""
    prob = _floor()
    cells = [(30, 30), (30, 31), (32, 33), (36, 30), (28, 38)]
    origins, ends = _group(prob, cells)
    grid = OccupancyGrid(prob, RES)
    ev = speck_evidence(grid, origins, ends)
    assert len(ev.group_cells) == 1
    assert ev.group_cells[0] == 5
    assert set(ev.group[ev.group > 0].tolist()) == {1}
    assert ev.group_ring_occupied[0] == 0.0
    assert ev.group_ring_free[0] == pytest.approx(1.0)
    # alone, the specks with a neighbour within 2 cells fail; only the two far ones pass
    assert clear_specks(grid, origins, ends, ConsistencyParams(group_radius=0))[1] == 2
    out, n = clear_specks(grid, origins, ends)
    assert n == 5
    assert not out.occupied().any()
    # a group of more than ``group_cells`` cells stays (but its lone far members still go alone)
    assert clear_specks(grid, origins, ends, ConsistencyParams(group_cells=4))[1] == 2
    # a run of 5 cells is no member: within 2 cells of a member it is structure in the group's
    # ring, and the group stays (its lone far member still goes alone)
    prob5 = prob.copy()
    prob5[34, 30:35] = OCC
    out, n = clear_specks(OccupancyGrid(prob5, RES), origins, ends)
    assert n == 1
    assert not out.occupied()[28, 38]
    assert out.occupied()[34, 30:35].all()
    assert out.occupied()[30, 30]
    assert out.occupied()[32, 33]
    assert out.occupied()[36, 30]


def test_a_group_next_to_a_wall_or_with_nothing_seen_behind_stays() -> None:
    prob = _floor()
    prob[20, 5:55] = OCC  # a wall
    near = [(22, 30), (22, 31), (24, 33)]  # 2 cells from the wall: the wall is in the ring
    origins, ends = _group(prob, near)
    assert clear_specks(OccupancyGrid(prob, RES), origins, ends)[1] == 0
    # a dotted far wall seen once: specks 3 cells apart in a row, nothing seen behind them
    prob = _floor()
    prob[:, 41:] = UNKNOWN
    dots = [(r, 40) for r in range(20, 40, 3)]
    origins, ends = _group(prob, dots)
    ev = speck_evidence(OccupancyGrid(prob, RES), origins, ends)
    assert ev.group_behind_free.max() == 0.0
    assert clear_specks(OccupancyGrid(prob, RES), origins, ends)[1] == 0


def test_a_two_cell_speck_is_judged_as_one() -> None:
    prob = _floor()
    prob[30, 30:32] = OCC
    origins, ends = _beam_to(30, 31)
    out, n = clear_specks(OccupancyGrid(prob, RES), origins, ends)
    assert n == 2
    assert not out.occupied().any()
    out, n = clear_specks(
        OccupancyGrid(prob, RES), origins, ends, ConsistencyParams(max_cells=1, group_radius=0)
    )
    assert n == 0


def test_a_speck_at_the_map_edge_counts_the_outside_as_unknown() -> None:
    prob = _floor(20, 20)
    prob[0, 10] = OCC
    ev = speck_evidence(OccupancyGrid(prob, RES), *_beam_to(0, 10))
    # a 5 x 5 ring less the speck: 24 cells, of which the 10 below the edge are outside
    assert ev.ring_free[0] == pytest.approx(14 / 24)
    # behind: 10 to 50 cm past the end are columns 12 to 20, and column 20 is outside
    assert ev.behind_cells[0] == 9
    assert ev.behind_free[0] == pytest.approx(8 / 9)


def _far_speck() -> np.ndarray:
    """A speck on seen-free floor with little of the floor just behind it seen (a visitor far
    away: the floor behind was seldom reached by a beam)."""
    prob = _floor()
    prob[30, 30] = OCC
    prob[28:33, 32:38] = UNKNOWN
    return prob


FAR = ConsistencyParams(ring_free=0.4, group_member_cells=6, far_range=6.0)


def test_a_speck_seen_once_from_afar_only_is_judged_with_the_looser_test() -> None:
    prob = _far_speck()
    origins, ends = _beam_to(30, 30, back=8.0)
    ev = speck_evidence(OccupancyGrid(prob, RES), origins, ends, FAR, np.array([0]))
    assert 0.2 <= ev.behind_free[0] < 0.5  # too little behind for the test of every speck
    assert ev.ring_free[0] >= 0.75
    assert ev.nearest[0] == pytest.approx(8.0)
    assert ev.scans[0] == 1
    without = ConsistencyParams(ring_free=0.4, group_member_cells=6)
    assert clear_specks(OccupancyGrid(prob, RES), origins, ends, without, np.array([0]))[1] == 0
    out, n = clear_specks(OccupancyGrid(prob, RES), origins, ends, FAR, np.array([0]))
    assert n == 1
    assert not out.occupied().any()


def test_a_speck_seen_from_near_or_by_three_scans_keeps_the_test_of_every_speck() -> None:
    prob = _far_speck()
    near = _beam_to(30, 30, back=3.0)
    assert clear_specks(OccupancyGrid(prob, RES), *near, FAR, np.array([0]))[1] == 0
    o_far, e_far = _beam_to(30, 30, back=8.0)
    o_near, e_near = near
    both = np.concatenate([o_far, o_near]), np.concatenate([e_far, e_near])
    assert clear_specks(OccupancyGrid(prob, RES), *both, FAR, np.array([0, 1]))[1] == 0  # one near
    thrice = np.concatenate([o_far] * 3), np.concatenate([e_far] * 3)
    assert clear_specks(OccupancyGrid(prob, RES), *thrice, FAR, np.array([0, 1, 2]))[1] == 0
    alone = replace(FAR, far_group_scans=0)  # the lone test only: one scan
    assert clear_specks(OccupancyGrid(prob, RES), *thrice, alone, np.array([0, 1, 1]))[1] == 0
    assert clear_specks(OccupancyGrid(prob, RES), *thrice, alone, np.array([4, 4, 4]))[1] == 1
    # two scans: a group of one whose member was seen from afar (ring >= 40 %, behind >= 20 %)
    assert clear_specks(OccupancyGrid(prob, RES), *thrice, FAR, np.array([0, 1, 1]))[1] == 1


def test_a_far_face_with_nothing_seen_behind_or_around_stays() -> None:
    origins, ends = _beam_to(30, 30, back=8.0)
    prob = _far_speck()
    prob[28:33, 32:] = UNKNOWN  # nothing behind seen at all
    assert clear_specks(OccupancyGrid(prob, RES), origins, ends, FAR, np.array([0]))[1] == 0
    prob = _far_speck()
    prob[28:33, 28:30] = UNKNOWN  # ring 9 / 24 seen free
    assert clear_specks(OccupancyGrid(prob, RES), origins, ends, FAR, np.array([0]))[1] == 0


def test_the_far_test_needs_the_scan_of_each_beam() -> None:
    origins, ends = _beam_to(30, 30, back=8.0)
    with pytest.raises(ValueError, match="scan of each beam"):
        clear_specks(OccupancyGrid(_far_speck(), RES), origins, ends, FAR)


def test_a_group_of_specks_each_seen_from_afar_by_two_scans_needs_less_free_behind() -> None:
    """Two far visitors standing together, each hit by beams of two scans from 8 m: too many
    scans for the lone far test, too little seen behind for the test of every group."""
    prob = _floor()
    prob[30, 30] = OCC
    prob[34, 30] = OCC
    prob[28:37, 32:38] = UNKNOWN
    o1, e1 = _beam_to(30, 30, back=8.0)
    o2, e2 = _beam_to(34, 30, back=8.0)
    origins, ends = np.concatenate([o1, o1, o2, o2]), np.concatenate([e1, e1, e2, e2])
    scans = np.array([0, 1, 0, 1])
    ev = speck_evidence(OccupancyGrid(prob, RES), origins, ends, FAR, scans)
    assert ev.group[0] == ev.group[1] > 0
    assert 0.2 <= ev.group_behind_free[0] < 0.5
    assert list(ev.scans) == [2, 2]
    without = ConsistencyParams(ring_free=0.4, group_member_cells=6)
    assert clear_specks(OccupancyGrid(prob, RES), origins, ends, without, scans)[1] == 0
    assert clear_specks(OccupancyGrid(prob, RES), origins, ends, FAR, scans)[1] == 2
    three = np.array([0, 1, 0, 2])  # one member hit by scans 0 and 1, the other by 0 and 2: still two each
    assert clear_specks(OccupancyGrid(prob, RES), origins, ends, FAR, three)[1] == 2
    near = np.concatenate([o1, o1, e2[None, 0] - [3.0, 0.0], o2]), ends  # one member seen from 3 m
    assert clear_specks(OccupancyGrid(prob, RES), *near, FAR, scans)[1] == 0


MUTUAL = replace(FAR, mutual_range=4.0)


def _two_visitors() -> np.ndarray:
    """Two specks 2 cells apart (each in the other's ring) on seen-free floor, with little of the
    floor behind them seen: two visitors standing together, seen from 5 m."""
    prob = _floor()
    prob[30, 30] = OCC
    prob[32, 30] = OCC
    prob[26:37, 33:38] = UNKNOWN
    return prob


def _beams(*rows_backs: tuple[int, float]) -> tuple[np.ndarray, np.ndarray]:
    """One beam along +x to column 30 of each row, from the given distance."""
    beams = [_beam_to(row, 30, back=back) for row, back in rows_backs]
    return np.concatenate([o for o, _ in beams]), np.concatenate([e for _, e in beams])


def test_loose_specks_next_to_each_other_are_cleared_together() -> None:
    prob = _two_visitors()
    origins, ends = _beams((30, 5.0), (32, 5.0))
    scans = np.array([0, 0])
    ev = speck_evidence(OccupancyGrid(prob, RES), origins, ends, MUTUAL, scans)
    assert list(ev.ring_occupied > 0) == [True, True]  # the lone tests fail
    assert 0.2 <= ev.group_behind_free[0] < 0.5  # and so does the test of the group
    assert list(ev.nearest) == pytest.approx([5.0, 5.0])  # nearer than the far test's 6 m
    assert sorted(map(tuple, ev.neighbours.tolist())) == [(0, 1), (1, 0)]
    assert clear_specks(OccupancyGrid(prob, RES), origins, ends, FAR, scans)[1] == 0
    out, n = clear_specks(OccupancyGrid(prob, RES), origins, ends, MUTUAL, scans)
    assert n == 2
    assert not out.occupied().any()


def test_a_loose_speck_next_to_a_near_speck_a_face_or_a_speck_seen_twice_stays() -> None:
    grid = OccupancyGrid(_two_visitors(), RES)
    # the other speck seen from 3 m (within the leg detector's reach): both stay
    assert clear_specks(grid, *_beams((30, 5.0), (32, 3.0)), MUTUAL, np.array([0, 0]))[1] == 0
    # the other speck hit by two scans
    twice = _beams((30, 5.0), (32, 5.0), (32, 5.0))
    assert clear_specks(grid, *twice, MUTUAL, np.array([0, 0, 1]))[1] == 0
    # a face of three cells next to the speck: larger than a loose speck, the speck stays
    prob = _two_visitors()
    prob[32:35, 30] = OCC
    face = _beams((30, 5.0), (32, 5.0), (33, 5.0), (34, 5.0))
    assert clear_specks(OccupancyGrid(prob, RES), *face, MUTUAL, np.zeros(4, np.int64))[1] == 0
    # without scan indices the test cannot count the scans
    with pytest.raises(ValueError, match="scan of each beam"):
        clear_specks(grid, *_beams((30, 5.0), (32, 5.0)), replace(ConsistencyParams(), mutual_range=4.0))
