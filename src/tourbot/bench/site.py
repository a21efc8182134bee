"""``tourbot bench site``: a new site from one log to a served tour, timed (Burgard et al. Sec. 7.1).

The paper set a new exhibition up in under two days, mapping included. Here the whole path runs as
a member of staff would run it, on a log the site was never authored for:

1. ``tourbot site new LOG --name NAME -o FOLDER`` (one command: map, line map, doors, site file);
2. ``tourbot serve --site FOLDER`` (one command: the simulated robot on the new map, the web site);
3. in Chromium, the staff page: log in, open the first provisional exhibit, name it, place it with
   a click on the map, save;
4. in Chromium, the visitor page: take control, start the tour ``highlights``; the robot drives
   on its estimate to the tour's stops.

Reported per log: the compute time of each step, the commands typed and the clicks and fields
filled (the person's part: counted, not timed, since no person runs the bench), the time from the
first command until the robot arrived at the tour's first stop (the target: a served tour within
10 minutes, compute included), how many of the tour's stops it reached within ``--tour-seconds``
and when it reached the last one (the whole tour, from the visitor's click).
"""

from __future__ import annotations

import asyncio
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Annotated, Any

import typer

from tourbot.bench.web import CHROMIUM, CHROMIUM_FLAGS, ServedSite

__all__ = ["register"]

TARGET_SECONDS = 600.0  # a served tour on the new site within 10 minutes, compute included
_LOGS = {
    "aces": "carmen/aces-corrected.log.gz",
    "intel": "carmen/intel-corrected.log.gz",
    "fr079": "carmen/freiburg-079-corrected.log.gz",
    "fhw": "carmen/fhw-corrected.log.gz",
}


class _Person:
    """What a member of staff or a visitor does in the pages: clicks and fields, counted."""

    def __init__(self) -> None:
        self.clicks = 0
        self.fields = 0

    async def click(self, page: Any, selector: str) -> None:
        self.clicks += 1
        await page.click(selector)

    async def fill(self, page: Any, selector: str, text: str) -> None:
        self.fields += 1
        await page.fill(selector, text)


async def _staff_names_and_places(base: str, person: _Person, browser: Any) -> tuple[float, float]:
    """The staff page: the first provisional exhibit renamed and placed by a click on the map
    where ``site new`` put it; returns where the page placed it."""
    page = await browser.new_page()
    await page.goto(base + "/admin")
    await person.fill(page, "#username", "staff")
    await person.fill(page, "#password", "bench-password")
    await person.click(page, "#login button")
    await page.wait_for_selector("#work:not([hidden])")
    await page.wait_for_function("() => window.tourbot.map && window.tourbot.map.scale > 0")
    await person.click(page, "#exhibits tr:nth-child(2)")  # the first exhibit, stop-1
    await person.fill(page, "#exhibit [name=name]", "The first exhibit")
    x, y = await page.evaluate(
        "() => { const f = document.getElementById('exhibit').elements; return [+f.x.value, +f.y.value]; }"
    )
    px, py = await page.evaluate(
        """([x, y]) => {
            const map = window.tourbot.map, canvas = document.getElementById('map');
            const r = canvas.getBoundingClientRect(), [cx, cy] = map.toCanvas(x, y);
            return [r.left + cx * r.width / canvas.width, r.top + cy * r.height / canvas.height];
        }""",
        [x, y],
    )
    person.clicks += 1
    await page.mouse.click(px, py)
    await person.click(page, "#exhibit button:not([type])")
    await page.wait_for_function("() => document.getElementById('message').textContent.includes('saved')")
    placed = await page.evaluate(
        "() => { const f = document.getElementById('exhibit').elements; return [+f.x.value, +f.y.value]; }"
    )
    await page.close()
    return float(placed[0]), float(placed[1])


async def _visitor_tour(
    base: str, person: _Person, browser: Any, seconds: float, enough: int | None
) -> dict[str, Any]:
    """The visitor page: take control, start the tour; when the robot reached each stop (until
    every stop, or ``enough`` of them, or ``seconds``)."""
    page = await browser.new_page()
    await page.goto(base + "/")
    await page.wait_for_selector("#tours button[data-tour='highlights']", timeout=60000)
    await person.click(page, "#book")
    await page.wait_for_selector("#slot[data-role='holder']", timeout=60000)
    started = time.monotonic()
    await person.click(page, "#tours button[data-tour='highlights']")
    arrivals: list[float] = []
    seen: set[str] = set()
    stops = 0
    deadline = started + seconds
    while time.monotonic() < deadline:
        text = await page.evaluate("() => document.getElementById('state').textContent")
        if text.startswith("Arrived at ") and " (tour highlights, " in text:
            name, progress = text[len("Arrived at ") :].rsplit(" (tour highlights, ", 1)
            stops = int(progress.strip(" )").split("/")[1])
            if name not in seen:
                seen.add(name)
                arrivals.append(time.monotonic() - started)
        if (stops and len(seen) == stops) or (enough is not None and len(seen) >= enough):
            break
        await asyncio.sleep(0.5)
    await page.close()
    return {"arrivals": arrivals, "stops": stops}


async def _pages(base: str, tour_seconds: float, enough: int | None) -> dict[str, Any]:
    from playwright.async_api import Error, async_playwright

    person = _Person()
    step = "the staff page"
    async with async_playwright() as p:
        browser = await p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_FLAGS, headless=True)
        try:
            t0 = time.monotonic()
            placed = await _staff_names_and_places(base, person, browser)
            staff_s = time.monotonic() - t0
            step = "the visitor page"
            tour = await _visitor_tour(base, person, browser, tour_seconds, enough)
        except Error as exc:  # a page that did not do what a person would see it do
            raise typer.BadParameter(f"{step}: {str(exc).splitlines()[0]}") from None
        finally:
            await browser.close()
    return {"placed": placed, "staff_s": staff_s, "clicks": person.clicks, "fields": person.fields, **tour}


def _one(
    name: str, log: Path, folder: Path, crowd: str, tour_seconds: float, enough: int | None = None
) -> dict[str, Any]:
    """The whole path for one log; ``enough`` stops the tour's clock after that many stops."""
    site = folder / name
    t0 = time.monotonic()
    made = subprocess.run(
        [sys.executable, "-m", "tourbot", "site", "new", str(log), "--name", name, "-o", str(site)],
        check=False,
        capture_output=True,
        text=True,
    )
    if made.returncode != 0:
        raise typer.BadParameter(f"{log}: site new failed: {made.stderr.strip().splitlines()[-1:]}")
    site_new_s = time.monotonic() - t0
    server = ServedSite(str(site), crowd, seed=0)
    try:
        server.wait(300.0)
        serve_s = time.monotonic() - t0 - site_new_s
        pages = asyncio.run(_pages(server.base, tour_seconds, enough))
    finally:
        server.close()
    first = pages["arrivals"][0] if pages["arrivals"] else float("nan")
    whole = len(pages["arrivals"]) == pages["stops"] > 0
    done = pages["arrivals"][-1] if whole else float("nan")
    served = site_new_s + serve_s + pages["staff_s"] + first
    return {
        "log": name,
        "site new s": site_new_s,
        "serve start s": serve_s,
        "staff page s": pages["staff_s"],
        "to 1st stop s": first,
        "served tour s": served,
        "stops reached": f"{len(pages['arrivals'])}/{pages['stops'] or '?'}",
        "tour done s": done,
        "commands": 2,
        "clicks": pages["clicks"],
        "fields": pages["fields"],
        "met": bool(served <= TARGET_SECONDS),
        "arrivals s": pages["arrivals"],
        "placed": pages["placed"],
    }


def register(bench: typer.Typer) -> None:
    @bench.command("site")
    def site(
        logs: Annotated[
            str, typer.Option(help=f"comma-separated logs of ../shared/data: {', '.join(_LOGS)}")
        ] = "aces,intel",
        data: Annotated[Path, typer.Option(help="the shared data folder")] = Path("../shared/data"),
        crowd: Annotated[str, typer.Option(help="visitors on the new site: empty, sparse or a number")] = "5",
        tour_seconds: Annotated[float, typer.Option(help="how long the tour may run")] = 600.0,
        output: Annotated[
            Path | None, typer.Option("-o", "--output", help="JSON file (default bench-results/).")
        ] = None,
    ) -> None:
        """A new site from one log to a served tour: compute time, commands and clicks."""
        from tourbot.bench._report import BenchReport

        names = [n.strip() for n in logs.split(",") if n.strip()]
        unknown = [n for n in names if n not in _LOGS]
        if unknown or not names:
            raise typer.BadParameter(
                f"unknown log {unknown}; choose from {', '.join(_LOGS)}", param_hint="--logs"
            )
        if not CHROMIUM.exists():
            raise typer.BadParameter(f"{CHROMIUM} is missing (apt-get install chromium)")
        paths = {n: data / _LOGS[n] for n in names}
        for path in paths.values():
            if not path.is_file():
                raise typer.BadParameter(f"{path}: no such log", param_hint="--data")
        columns = ["log", "site new s", "serve start s", "staff page s", "to 1st stop s", "served tour s",
                   "stops reached", "tour done s", "commands", "clicks", "fields", "met"]  # fmt: skip
        report = BenchReport("site", columns, meta={"crowd": crowd, "tour_seconds": tour_seconds})
        with tempfile.TemporaryDirectory(prefix="tourbot-bench-site-") as folder:
            for n in names:
                report.add(**_one(n, paths[n].resolve(), Path(folder), crowd, tour_seconds))
        report.notes.append(
            "served tour s: from `site new` to the robot at the tour's first stop; "
            f"target <= {TARGET_SECONDS:.0f} s"
        )
        report.notes.append("commands, clicks and fields: the person's part of the path, counted (not timed)")
        report.finish(output)
