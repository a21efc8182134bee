"""The root of tourbot's exceptions.

Every error a user can cause (a bad file, a wrong option, an impossible request) is a
:class:`TourbotError`; each part raises its own subclass so callers can catch precisely. Errors
about input say *where*: the file, the line and the field. The command line prints them without a
traceback.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["InputError", "TourbotError"]


class TourbotError(Exception):
    """Something the user can fix: the message says what and where."""


class InputError(TourbotError):
    """Bad input data, located by file, line and field when known."""

    def __init__(
        self,
        message: str,
        *,
        path: str | Path | None = None,
        line: int | None = None,
        field: str | None = None,
    ) -> None:
        self.reason = message
        self.path = None if path is None else str(path)
        self.line = line
        self.field = field
        super().__init__(self._render())

    def _render(self) -> str:
        where = ""
        if self.path is not None:
            where = self.path
            if self.line is not None:
                where += f":{self.line}"
        if self.field is not None:
            where += f" (field {self.field})" if where else f"field {self.field}"
        return f"{where}: {self.reason}" if where else self.reason
