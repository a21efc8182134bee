"""Shared fixtures: the real robot logs in ``../shared/data`` (tests skip clearly without them)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tourbot.data import data_dir


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
