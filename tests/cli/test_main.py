"""The ``tourbot`` entry point: usage errors are one short message, exit code 2, no traceback."""

from __future__ import annotations

import pytest

from tourbot.cli.main import main


def _run(args: list[str]) -> int:
    try:
        main(args)
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["site", "place", "ada", "--x", "3"], "No such option: --x"),
        (["localize", "x.log", "--map", "m.yaml", "-o", "t.txt", "--method", "foo"], "'foo' is not one of"),
        (["no-such-command"], "No such command"),
        (["log", "info"], "Missing argument"),
        (["bench", "mcl", "--particles", "-5"], "Invalid value for '--particles'"),
    ],
)
def test_usage_errors_are_one_message_without_traceback(
    args: list[str], expected: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _run(args) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert expected in err
    assert "Traceback" not in err


@pytest.mark.parametrize(
    ("args", "command"),
    [
        (["localize", "x.log", "--map", "m.yaml", "-o", "t.txt", "--method", "foo"], "tourbot localize"),
        (["log", "infox"], "tourbot log"),
        (["site", "exhibit", "a", "--x", "abc", "--y", "1"], "tourbot site exhibit"),
        (["--no-such-option"], "tourbot"),
    ],
)
def test_usage_errors_are_a_single_line_naming_the_help_to_read(
    args: list[str], command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _run(args) == 2
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(lines) == 1, lines
    assert lines[0].startswith("error: ")
    assert lines[0].endswith(f"(see '{command} --help')")
    assert "Value error," not in lines[0]


def test_ctrl_c_during_a_command_exits_130_not_0(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import tourbot.io

    def interrupted(*_args: object, **_kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(tourbot.io, "load_log", interrupted)
    assert _run(["log", "info", "any.log"]) == 130
    assert "interrupted" in capsys.readouterr().err
