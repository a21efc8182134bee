"""``tourbot config show``: the effective configuration of the localizers, as YAML."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    config_app = typer.Typer(
        help="The localizers' configuration (defaults and profiles).", no_args_is_help=True
    )
    app.add_typer(config_app, name="config")

    @config_app.command("show")
    def show(
        config: Annotated[
            Path | None,
            typer.Option(
                "--config",
                help="Profile to apply over the defaults (e.g. src/tourbot/sites/fhw/localization.yaml).",
            ),
        ] = None,
    ) -> None:
        """Print the effective configuration (the defaults, with --config FILE applied) as YAML."""
        from tourbot.localization.profile import LocalizationProfile

        typer.echo(LocalizationProfile.load(config).to_yaml(), nl=False)
