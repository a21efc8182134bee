"""``tourbot site``: bad input gives one clear line; nothing a user saved in the database is lost."""

from __future__ import annotations

from pathlib import Path

import pytest

from tourbot.cli.main import main


def _run(args: list[str]) -> int:
    try:
        main(args)
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


def test_database_in_a_new_folder_is_created(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "new" / "deeper" / "site.db"
    assert (
        _run(["site", "exhibit", "my-thing", "--x", "1", "--y", "2", "--database", f"sqlite:///{path}"]) == 0
    )
    assert path.is_file()
    assert _run(["site", "list", "--database", f"sqlite:///{path}"]) == 0
    assert "my-thing" in capsys.readouterr().out


def test_a_file_that_is_no_database_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    junk = tmp_path / "junk.db"
    junk.write_bytes(bytes(range(256)) * 8)
    assert _run(["site", "list", "--database", f"sqlite:///{junk}"]) == 2
    err = capsys.readouterr().err
    assert "junk.db" in err
    assert "file is not a database" in err
    assert len(err.strip().splitlines()) == 1
    assert "Traceback" not in err
    assert junk.read_bytes() == bytes(range(256)) * 8  # left as it was


def test_binary_site_file_names_the_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    junk = tmp_path / "junk.yaml"
    junk.write_bytes(b"\xd7\xff\x00" * 100)
    assert _run(["site", "import", "--site", str(junk), "--database", f"sqlite:///{tmp_path / 'x.db'}"]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"{junk}: not a text (UTF-8) YAML file" in err
    assert "Traceback" not in err


def test_import_keeps_what_the_user_added_and_edited(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = ["--database", f"sqlite:///{tmp_path / 'site.db'}"]
    assert _run(["site", "import", *db]) == 0
    assert _run(["site", "exhibit", "my-thing", "--x", "1", "--y", "2", "--name", "Mine", *db]) == 0
    assert _run(["site", "place", "marathon-runner", "3.5", "4.5", *db]) == 0
    capsys.readouterr()
    assert _run(["site", "import", *db]) == 0  # a second import must not undo the edits
    assert "0 exhibits and 0 tours" in capsys.readouterr().out
    assert _run(["site", "list", *db]) == 0
    out = capsys.readouterr().out
    assert "my-thing" in out
    row = next(line for line in out.splitlines() if "marathon-runner" in line)
    assert "3.50" in row
    assert "4.50" in row


def test_serve_start_keeps_the_database(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from tourbot.web.serve import ServeSettings, build_site_app

    monkeypatch.chdir(tmp_path)  # the server keeps its speech cache in the current folder

    url = f"sqlite:///{tmp_path / 'site.db'}"
    assert _run(["site", "import", "--database", url]) == 0
    assert _run(["site", "remove", "theatre-masks", "--database", url]) == 0
    assert (
        _run(["site", "exhibit", "my-thing", "--x", "1", "--y", "2", "--text", "mine", "--database", url])
        == 0
    )
    _, db = build_site_app(ServeSettings(site="fhw", database=url, crowd="empty", staff_password="pw-123456"))
    slugs = {e.slug for e in db.exhibits()}
    assert "my-thing" in slugs
    assert "theatre-masks" not in slugs  # a removal is not undone by re-importing the site file
    assert db.exhibit("my-thing").text == "mine"


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--slot-minutes", "-1"], "field --slot-minutes: must be positive"),
        (["--port", "70000"], "field --port: must be a TCP port"),
        (["--crowd", "crowded"], "unknown crowd 'crowded'"),
    ],
)
def test_serve_bad_options_are_refused_before_the_database_is_touched(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], expected: str
) -> None:
    db = tmp_path / "site.db"
    assert _run(["serve", "--database", f"sqlite:///{db}", *args]) == 2
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(lines) == 1
    assert expected in lines[0]
    assert not db.exists()


def test_a_new_database_file_is_announced_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A mistyped ``--database`` creates an empty database: the user is told where, the first time only."""
    db = ["--database", f"sqlite:///{tmp_path / 'typo.db'}"]
    assert _run(["site", "list", *db]) == 0
    assert f"created a new database {tmp_path / 'typo.db'}" in capsys.readouterr().err
    assert _run(["site", "list", *db]) == 0
    assert "created a new database" not in capsys.readouterr().err


def test_a_short_staff_password_is_refused_before_a_database_is_made(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "site.db"
    assert _run(["site", "staff", "bob", "--password", "short", "--database", f"sqlite:///{path}"]) == 2
    assert "at least 8 characters" in capsys.readouterr().err
    assert not path.exists()
    assert _run(["site", "staff", "bob", "--password", "long enough", "--database", f"sqlite:///{path}"]) == 0
    assert path.exists()


def test_staff_help_does_not_call_the_prompted_password_required(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("COLUMNS", "200")
    _run(["site", "staff", "--help"])
    line = next(x for x in capsys.readouterr().out.splitlines() if "--password" in x)
    assert "required" not in line


def test_a_javascript_link_is_refused_by_the_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    url = f"sqlite:///{tmp_path / 'site.db'}"
    code = _run(
        ["site", "exhibit", "x", "--x", "1", "--y", "2", "--link", "javascript:alert(1)", "--database", url]
    )
    assert code == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1
    assert "must start with http://" in err[0]
    assert "Traceback" not in err[0]


def test_the_staff_password_is_not_taken_from_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Every user of the machine can read a command line (``ps``): no ``--staff-password``."""
    db = tmp_path / "site.db"
    assert _run(["serve", "--database", f"sqlite:///{db}", "--staff-password", "s3cret-pass"]) == 2
    assert "No such option" in capsys.readouterr().err
    assert not db.exists()


@pytest.mark.parametrize(
    ("content", "expected"), [(None, "cannot read"), ("", "is empty"), ("short\n", "at least 8 characters")]
)
def test_a_bad_staff_password_file_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str | None, expected: str
) -> None:
    file = tmp_path / "password"
    if content is not None:
        file.write_text(content)
    db = tmp_path / "site.db"
    assert _run(["serve", "--database", f"sqlite:///{db}", "--staff-password-file", str(file)]) == 2
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(lines) == 1
    assert expected in lines[0]
    assert not db.exists()


def test_the_staff_password_comes_from_a_file_the_environment_or_a_prompt(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from tourbot.cli.web import read_staff_password
    from tourbot.errors import InputError

    monkeypatch.delenv("TOURBOT_STAFF_PASSWORD", raising=False)
    file = tmp_path / "password"
    file.write_text("from the file\nignored\n")
    assert read_staff_password(file, False) == "from the file"
    assert read_staff_password(None, False) is None
    monkeypatch.setattr("typer.prompt", lambda *_, **__: "typed, hidden")
    assert read_staff_password(None, True) == "typed, hidden"
    monkeypatch.setenv("TOURBOT_STAFF_PASSWORD", "from the environment")
    assert read_staff_password(None, False) == "from the environment"
    with pytest.raises(InputError, match="one way"):
        read_staff_password(file, False)


def test_the_demo_takes_the_staff_password_as_serve_does(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``demo`` serves the same staff pages: no ``--staff-password`` in its argv either, and a
    short password from its file is refused before anything is built."""
    out = tmp_path / "demo"
    assert _run(["demo", "--out", str(out), "--staff-password", "s3cret-pass"]) == 2
    assert "No such option" in capsys.readouterr().err
    short = tmp_path / "short"
    short.write_text("short\n")
    assert _run(["demo", "--out", str(out), "--staff-password-file", str(short)]) == 2
    err = capsys.readouterr().err
    assert "at least 8 characters" in err
    assert "Traceback" not in err
    assert not out.exists()
