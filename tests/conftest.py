"""Shared fixtures: the real robot logs in ``../shared/data`` (tests skip clearly without them)."""

from __future__ import annotations

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
