"""Shared fixtures: the real robot logs in ``../shared/data`` (tests skip clearly without them)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pytest

from tourbot.data import data_dir
from tourbot.records import RobotLog


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The folder of real robot logs; the test is skipped, saying why, when it is absent."""
    root = data_dir()
    if root is None:
        pytest.skip("real robot logs not found: expected ../shared/data beside the checkout")
    return root


@pytest.fixture(scope="session")
def fhw_log_path(shared_data: Path) -> Path:
    return shared_data / "carmen" / "fhw-corrected.log.gz"


@pytest.fixture(scope="session")
def real_log(shared_data: Path) -> Callable[[str], RobotLog]:
    """``real_log("fhw")``: a corrected CARMEN log of ``carmen/``, read once per session (do not modify)."""
    from tourbot.io.carmen import read_carmen

    cache: dict[str, RobotLog] = {}

    def get(name: str) -> RobotLog:
        if name not in cache:
            cache[name] = read_carmen(shared_data / "carmen" / f"{name}-corrected.log.gz")
        return cache[name]

    return get


# `make test` sets TOURBOT_NO_SKIPS=1: there every test must run (the browser, PostgreSQL and speech
# tests included, scripts/test-services.sh provides what they need), so a skip fails the run.
_SKIPPED: list[str] = []


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if report.skipped and not hasattr(report, "wasxfail"):
        _SKIPPED.append(report.nodeid)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    if os.environ.get("TOURBOT_NO_SKIPS") == "1" and _SKIPPED and exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    if os.environ.get("TOURBOT_NO_SKIPS") == "1" and _SKIPPED:
        terminalreporter.write_line(
            f"TOURBOT_NO_SKIPS: {len(_SKIPPED)} test(s) skipped, and `make test` runs every test "
            "(see the reasons above; `make test-fast` allows skips)",
            red=True,
        )
