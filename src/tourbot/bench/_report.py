"""What every benchmark produces: a table on screen and a JSON file, with the command that made it."""

from __future__ import annotations

import json
import math
import os
import platform
import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from tourbot.io.output import write_text_whole

__all__ = ["BenchReport", "default_output"]


def default_output(name: str) -> Path:
    """Where ``tourbot bench NAME`` writes its JSON unless told otherwise."""
    return Path("bench-results") / f"{name}.json"


@dataclass
class BenchReport:
    """Rows of results for one benchmark; ``finish`` prints them and writes the JSON."""

    name: str
    columns: list[str]
    rows: list[dict[str, Any]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    meta: dict[str, Any] = field(default_factory=dict)

    def add(self, **row: Any) -> None:
        self.rows.append(row)

    def finish(self, output: Path | None = None, console: Console | None = None) -> Path:
        console = console or Console()
        table = Table(title=f"tourbot bench {self.name}")
        for col in self.columns:
            table.add_column(col, justify="left" if col == self.columns[0] else "right")
        for row in self.rows:
            table.add_row(*[_fmt(row.get(col, "")) for col in self.columns])
        console.print(table)
        for note in self.notes:
            console.print(f"- {note}")
        out = output or default_output(self.name)
        payload = {
            "benchmark": self.name,
            "command": "tourbot " + shlex.join(sys.argv[1:]) if sys.argv else "",
            "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "machine": {"cpus": os.cpu_count(), "platform": platform.platform(), "python": sys.version},
            "meta": self.meta,
            "rows": self.rows,
            "notes": self.notes,
        }
        write_text_whole(out, json.dumps(payload, indent=2, default=str) + "\n")
        console.print(f"wrote {out}")
        return out


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        if math.isnan(value):
            return "-"
        if abs(value) >= 1e5 or (0 < abs(value) < 1e-3):
            return f"{value:.3g}"
        return f"{value:.3f}" if abs(value) < 10 else f"{value:.1f}"
    return str(value)
