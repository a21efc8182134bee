"""Fox et al.'s localization figures on synthetic error curves: errors, failures, recovery, censoring."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tourbot.metrics import (
    Recovery,
    converged_index,
    failure_rate,
    mean_ci,
    pose_errors,
    recovery,
    settle_index,
)


def test_pose_errors_wrap_headings() -> None:
    est = np.array([[1.0, 1.0, math.pi - 0.1], [0.0, 0.0, 0.0]])
    ref = np.array([[1.3, 1.4, -math.pi + 0.1], [0.0, 0.0, 0.5]])
    pos, head = pose_errors(est, ref)
    np.testing.assert_allclose(pos, [0.5, 0.0])
    np.testing.assert_allclose(head, [0.2, 0.5])
    with pytest.raises(ValueError, match="same length"):
        pose_errors(est, ref[:1])


def test_a_failure_is_more_than_45_cm_off() -> None:
    assert failure_rate([0.1, 0.45, 0.46, 2.0]) == 0.5
    assert math.isnan(failure_rate([]))


def test_settling_needs_more_than_ten_seconds_below_45_cm() -> None:
    times = np.arange(30.0) * 2.0  # a scan every 2 s
    err = np.full(30, 1.0)
    err[5:10] = 0.1  # 8 s below: not enough
    err[12:] = 0.2  # from scan 12 on, for good
    assert settle_index(err, times, 0, 30) == 12
    err[20] = 0.5  # a failure at 40 s: 12..19 spans 14 s, still enough
    assert settle_index(err, times, 0, 30) == 12
    err[17] = 0.5  # now 12..16 spans 8 s; 18..19 too short; 21.. runs to the end
    assert settle_index(err, times, 0, 30) == 21
    assert settle_index(np.full(30, 1.0), times, 0, 30) is None


def test_converged_is_below_45_cm_from_some_scan_to_the_end() -> None:
    err = np.array([2.0, 0.1, 0.9, 0.2, 0.1, 0.3])
    assert converged_index(err) == 3
    assert converged_index(np.full(4, 0.1)) == 0
    assert converged_index(np.array([0.1, 1.0])) is None


def test_recovery_per_kidnap_until_the_next() -> None:
    times = np.arange(40.0)
    path = np.arange(40.0) * 0.5
    err = np.full(40, 0.05)
    err[10:13] = 2.0  # kidnap at 10, back at 13 (stays below until 25: > 10 s)
    err[25:] = 2.0  # kidnap at 25, never back (14 s to the end of the log)
    out = recovery(err, times, [10, 25], path)
    assert out[0] == Recovery(True, 3.0, 1.5)
    assert out[1] is not None
    assert out[1].recovered is False
    assert math.isnan(out[1].seconds)


def test_recovery_is_the_start_of_the_first_stretch_of_more_than_ten_seconds() -> None:
    times = np.arange(0.0, 60.0, 2.0)
    err = np.full(times.size, 2.0)
    err[5:8] = 0.1  # 10 s to 14 s: only 4 s, too short
    err[10:] = 0.2  # from 20 s on: recovered
    (out,) = recovery(err, times, [2])  # kidnapped at 4 s
    assert out is not None
    assert out.seconds == 16.0
    assert math.isnan(out.metres)  # no path given
    (right_away,) = recovery(np.full(times.size, 0.1), times, [5])  # never lost: 0 s
    assert right_away is not None
    assert right_away.seconds == 0.0


def test_a_kidnap_followed_by_another_within_ten_seconds_is_censored() -> None:
    times = np.arange(40.0)
    path = np.arange(40.0)
    err = np.full(40, 0.05)
    err[10:15] = 2.0
    out = recovery(err, times, [10, 14, 30], path)
    assert out[0] is None  # the next kidnap comes 4 s later: it cannot be judged
    assert out[1] == Recovery(True, 1.0, 1.0)
    assert out[2] == Recovery(True, 0.0, 0.0)
    err[10:25] = 2.0
    judged = recovery(err, times, [10, 22], path)[0]  # 12 s to the next kidnap: judged, failed
    assert judged is not None
    assert judged.recovered is False


def test_a_kidnap_within_ten_seconds_of_the_end_is_censored_unless_settled() -> None:
    times = np.arange(40.0)
    path = np.arange(40.0)
    err = np.full(40, 0.05)
    err[35:] = 2.0  # kidnap at 35, 4 s before the end: cannot be judged
    assert recovery(err, times, [35], path) == [None]
    err[37:] = 0.05  # ... unless it has settled by the end of the log
    assert recovery(err, times, [35], path) == [Recovery(True, 2.0, 2.0)]
    err[28:] = 2.0  # 11 s before the end and never back: judged, failed
    late = recovery(err, times, [28], path)[0]
    assert late is not None
    assert late.recovered is False


def test_mean_ci() -> None:
    m, h = mean_ci([1.0, 2.0, 3.0, 4.0, 5.0])
    assert m == 3.0
    # t(0.975, 4) = 2.776; sd = 1.581; h = 2.776 * 1.581 / sqrt(5)
    assert h == pytest.approx(1.963, abs=1e-3)
    assert mean_ci([7.0]) == (7.0, 0.0)
    assert all(math.isnan(v) for v in mean_ci([math.nan]))
