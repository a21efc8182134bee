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

__all__ = ["build_app", "main"]

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
        app(args=argv, standalone_mode=False)
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
        # whose exceptions are not click's; both have ``show()`` and print one usage line, exit 2.
        import click
        from typer.exceptions import TyperException

        if isinstance(exc, click.exceptions.ClickException | TyperException):
            show = getattr(exc, "show", None)
            if callable(show):
                show()
            else:
                _err.print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False, soft_wrap=True)
            sys.exit(exc.exit_code)
        raise


if __name__ == "__main__":
    main()
