"""The grid benchmark's scoring: recovery times as Fox et al. 1998 define them, and bad options."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from tourbot.bench.grid import recovery_times
from tourbot.cli.main import build_app


def test_recovery_is_the_start_of_the_first_stretch_of_ten_seconds_within_45_cm() -> None:
    times = np.arange(0.0, 60.0, 2.0)
    errors = np.full(times.size, 2.0)
    errors[5:8] = 0.1  # 10 s to 14 s: only 4 s, too short
    errors[10:] = 0.2  # from 20 s on: recovered
    assert recovery_times(times, errors, [4.0]) == [16.0]


def test_a_kidnap_never_recovered_before_the_next_one_is_nan() -> None:
    times = np.arange(0.0, 100.0, 2.0)
    errors = np.full(times.size, 2.0)
    errors[30:] = 0.1  # recovered at 60 s, after the second kidnap at 50 s
    rec = recovery_times(times, errors, [10.0, 50.0])
    assert math.isnan(rec[0])
    assert rec[1] == pytest.approx(10.0)


def test_an_estimate_right_at_the_kidnap_recovers_in_zero_seconds() -> None:
    times = np.arange(0.0, 30.0, 1.0)
    assert recovery_times(times, np.full(times.size, 0.1), [5.0]) == [0.0]


@pytest.mark.parametrize(("option", "value"), [("--filters", "foo"), ("--kidnap-seeds", "x")])
def test_bad_options_are_input_errors(option: str, value: str) -> None:
    from tourbot.errors import InputError

    result = CliRunner().invoke(build_app(), ["bench", "grid", option, value])
    assert isinstance(result.exception, InputError)
    assert option in str(result.exception)
