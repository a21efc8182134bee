"""Entry point of the ``tourbot`` command: builds the application and reports errors cleanly."""

from __future__ import annotations

import importlib
import pkgutil
import sys
from types import ModuleType

import typer
from rich.console import Console
from rich.markup import escape

import tourbot.bench
import tourbot.cli
from tourbot.errors import TourbotError

__all__ = ["build_app", "main", "usage_error_line"]

_err = Console(stderr=True)


def _modules_with(package: ModuleType, attribute: str) -> list[ModuleType]:
    """Modules of ``package`` that define ``attribute``, in name order."""
    found = []
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda m: m.name):
        if info.name.startswith("_") or info.name == "main":
            continue
        module = importlib.import_module(f"{package.__name__}.{info.name}")
        if hasattr(module, attribute):
            found.append(module)
    return found


def build_app() -> typer.Typer:
    """The whole ``tourbot`` application, with every part's commands and benchmarks."""
    app = typer.Typer(
        name="tourbot",
        help="Software for tour-guide robots in crowded exhibitions.",
        no_args_is_help=True,
        pretty_exceptions_enable=False,
        add_completion=False,
    )
    bench = typer.Typer(
        help="Benchmarks: each prints a table, writes JSON and says how to record it.",
        no_args_is_help=True,
    )
    for module in _modules_with(tourbot.cli, "register"):
        module.register(app)
    for module in _modules_with(tourbot.bench, "register"):
        module.register(bench)
    app.add_typer(bench, name="bench")
    return app


def main(argv: list[str] | None = None) -> None:
    """Run the command line; a :class:`TourbotError` is shown as one clear line, exit code 2."""
    app = build_app()
    try:
        # Without standalone mode typer turns Ctrl-C (and ``typer.Exit``) into a returned exit code
        code = app(args=argv, standalone_mode=False)
        if code == 130:
            raise KeyboardInterrupt
        if isinstance(code, int) and not isinstance(code, bool) and code != 0:
            sys.exit(code)
    except TourbotError as exc:
        # the message is plain text (it may hold brackets); one line however wide the terminal
        _err.print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False, markup=True, soft_wrap=True)
        sys.exit(2)
    except KeyboardInterrupt:
        _err.print("interrupted")
        sys.exit(130)
    except OSError as exc:
        # Missing or unreadable files are user errors: say which file, no traceback.
        _err.print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False, soft_wrap=True)
        sys.exit(2)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except typer.Abort:
        sys.exit(1)
    except Exception as exc:
        # Usage errors (unknown option, bad value): typer >= 0.24 vendors click as ``typer._click``,
        # whose exceptions are not click's; both give one line here, like every other error, exit 2.
        import click
        from typer.exceptions import TyperException

        if isinstance(exc, click.exceptions.ClickException | TyperException):
            line = escape(usage_error_line(exc))
            _err.print(f"[bold red]error:[/] {line}", highlight=False, soft_wrap=True)
            sys.exit(int(getattr(exc, "exit_code", 2)))
        raise


def usage_error_line(exc: Exception) -> str:
    """One line for a command-line usage error: click's message and where to find help.

    Click prints three lines (usage, a hint, the message); the message is the part a user needs.
    """
    format_message = getattr(exc, "format_message", None)
    message = format_message() if callable(format_message) else str(exc)
    # typer validates through pydantic, whose messages carry a "Value error, " prefix
    message = " ".join(str(message).replace("Value error, ", "").split())
    words: list[str] = []
    ctx = getattr(exc, "ctx", None)
    while ctx is not None and getattr(ctx, "parent", None) is not None:  # the root is the program
        words.insert(0, str(ctx.info_name))
        ctx = ctx.parent
    command = " ".join(["tourbot", *words])
    return f"{message} (see '{command} --help')"


if __name__ == "__main__":
    main()
