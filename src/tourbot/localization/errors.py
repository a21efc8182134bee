"""The error of the localizers."""

from __future__ import annotations

from tourbot.errors import TourbotError

__all__ = ["LocalizationError"]


class LocalizationError(TourbotError):
    """A localizer used wrongly: no map free space, no start, a scan it cannot read."""
