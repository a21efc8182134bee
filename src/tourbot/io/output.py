"""Output files written whole or not at all.

A command that fails or is interrupted while writing (a bad record found late, Ctrl-C, a full
disk) must neither leave a half-written file nor destroy the previous one of the same name. Every
writer therefore writes into a temporary file beside the target and renames it onto the target
only when the writing has finished (the rename is atomic on one file system).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from tourbot.errors import InputError

__all__ = ["check_output", "output_file", "partial_name", "write_text_whole"]

PARTIAL_PREFIX = ".partial-"


def partial_name(path: str | Path) -> Path:
    """The temporary file beside ``path`` that is written first (hidden, same suffixes)."""
    p = Path(path)
    return p.with_name(f"{PARTIAL_PREFIX}{os.getpid()}-{p.name}")


def check_output(path: str | Path, option: str = "--output") -> Path:
    """``path`` as a file to write: refused (one clear error) when it is an existing folder."""
    p = Path(path)
    if p.is_dir():
        raise InputError("is a folder; give a file name to write", path=p, field=option)
    return p


@contextmanager
def output_file(path: str | Path) -> Iterator[Path]:
    """Yield the temporary path to write ``path`` through; rename it onto ``path`` on success.

    On any error (and on Ctrl-C) the temporary file is removed and ``path``, if it existed, is
    left as it was. The folder of ``path`` is created as needed.
    """
    target = check_output(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = partial_name(target)
    try:
        yield tmp
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    os.replace(tmp, target)


def write_text_whole(path: str | Path, text: str) -> None:
    """``Path.write_text`` (UTF-8) through :func:`output_file`."""
    with output_file(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
