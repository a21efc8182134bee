"""The grid benchmark's bad options (its scoring is :mod:`tourbot.metrics`, tested there)."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from tourbot.cli.main import build_app


@pytest.mark.parametrize(("option", "value"), [("--filters", "foo"), ("--kidnap-seeds", "x")])
def test_bad_options_are_input_errors(option: str, value: str) -> None:
    from tourbot.errors import InputError

    result = CliRunner().invoke(build_app(), ["bench", "grid", option, value])
    assert isinstance(result.exception, InputError)
    assert option in str(result.exception)
