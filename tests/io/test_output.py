"""Output files are written whole or not at all: an error keeps the previous file, no leftovers."""

from __future__ import annotations

from pathlib import Path

import pytest

from tourbot.errors import InputError
from tourbot.io.output import output_file, write_text_whole


def test_success_replaces_the_file_and_creates_its_folder(tmp_path: Path) -> None:
    target = tmp_path / "new" / "out.txt"
    write_text_whole(target, "one\n")
    write_text_whole(target, "two\n")
    assert target.read_text() == "two\n"
    assert [p.name for p in target.parent.iterdir()] == ["out.txt"]


@pytest.mark.parametrize("error", [ValueError("bad record"), KeyboardInterrupt()])
def test_an_error_while_writing_keeps_the_previous_file(tmp_path: Path, error: BaseException) -> None:
    target = tmp_path / "out.csv"
    target.write_text("previous\n")

    def write_half() -> None:
        with output_file(target) as tmp:
            tmp.write_text("half of the new")
            raise error

    with pytest.raises(type(error)):
        write_half()
    assert target.read_text() == "previous\n"
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


def test_the_temporary_file_keeps_the_suffixes(tmp_path: Path) -> None:
    with output_file(tmp_path / "a.log.gz") as tmp:
        assert tmp.name.endswith("a.log.gz")
        assert tmp.parent == tmp_path
        tmp.write_bytes(b"")


def test_a_folder_is_refused_with_the_option_named(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="is a folder") as info, output_file(tmp_path):
        pass
    assert info.value.field == "--output"
