"""Where the real robot logs live: ``../shared/data`` beside the checkout, or ``TOURBOT_DATA``."""

from __future__ import annotations

import os
from pathlib import Path

from tourbot.errors import TourbotError

__all__ = ["DataNotFoundError", "data_dir", "find_data"]


class DataNotFoundError(TourbotError):
    """The real robot logs were not found."""


def data_dir() -> Path | None:
    """The folder of real robot logs, or None when it is absent.

    Looked up, in order: ``$TOURBOT_DATA``; ``shared/data`` beside the folder that holds the
    current directory or this package's checkout (the project's layout: ``../shared/data``).
    """
    env = os.environ.get("TOURBOT_DATA")
    if env:
        return Path(env) if Path(env).is_dir() else None
    starts = [Path.cwd(), Path(__file__).resolve()]
    for start in starts:
        for parent in [start, *start.parents]:
            candidate = parent / "shared" / "data"
            if candidate.is_dir():
                return candidate
    return None


def find_data(relative: str) -> Path:
    """A file of the real data set, e.g. ``carmen/fhw-corrected.log.gz``; a clear error if absent."""
    root = data_dir()
    if root is None:
        raise DataNotFoundError(
            "the real robot logs were not found: put them in ../shared/data beside the checkout "
            "or set TOURBOT_DATA"
        )
    path = root / relative
    if not path.exists():
        raise DataNotFoundError(f"{path}: no such file in the robot log folder")
    return path
