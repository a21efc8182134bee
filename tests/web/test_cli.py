from __future__ import annotations

from pathlib import Path

import pytest

from tourbot.cli.main import main
from tourbot.web.db import open_database

SITE = """
name: hall
description: 'Test hall: a square room'
map:
  walls:
  - [[0, 0], [10, 0], [10, 0.2], [0, 0.2]]
  - [[0, 0], [0.2, 0], [0.2, 8], [0, 8]]
  resolution: 0.1
exhibits:
- {name: marble-head, position: [3, 3], viewing_pose: [2, 3, 0], text: A marble head.}
- {name: bronze-cup, position: [6, 5], viewing_pose: [6, 4, 1.57], text: A cup.}
tours:
- {name: quick, exhibits: [bronze-cup, marble-head]}
"""


@pytest.fixture
def site_file(tmp_path: Path) -> Path:
    path = tmp_path / "hall.yaml"
    path.write_text(SITE)
    return path


def run(*args: str) -> None:
    main(list(args))


def test_site_commands_author_a_new_site(
    site_file: Path, sqlite_url: str, capsys: pytest.CaptureFixture[str]
) -> None:
    common = ["--site", str(site_file), "--database", sqlite_url]
    run("site", "import", *common)
    assert "2 exhibits and 1 tours" in capsys.readouterr().out
    run("site", "import", *common)  # again: content edited since is kept
    assert "0 exhibits and 0 tours" in capsys.readouterr().out
    run(
        "site",
        "exhibit",
        "lyre",
        "--x",
        "4",
        "--y",
        "6",
        "--summary",
        "A lyre.",
        "--picture",
        "/p/lyre.jpg",
        *common,
    )
    run("site", "place", "marble-head", "2.5", "3.5", *common)
    run("site", "tour", "music", "lyre", "bronze-cup", *common)
    run("site", "list", *common)
    out = capsys.readouterr().out
    assert "music: lyre -> bronze-cup" in out
    db = open_database(sqlite_url)
    head = db.exhibit("marble-head")
    assert (head.name, head.x, head.y, head.summary) == ("Marble head", 2.5, 3.5, "A marble head.")
    assert db.exhibit("lyre").pictures == (("/p/lyre.jpg", ""),)
    assert db.tour("quick").exhibits == ("bronze-cup", "marble-head")
    run("site", "remove", "lyre", *common)
    assert db.tour("music").exhibits == ("bronze-cup",)


def test_unknown_exhibit_is_a_one_line_error(
    site_file: Path, sqlite_url: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as stopped:
        run("site", "place", "nowhere", "1", "1", "--site", str(site_file), "--database", sqlite_url)
    assert stopped.value.code == 2
    err = capsys.readouterr().err
    assert "no exhibit 'nowhere'" in err
    assert "Traceback" not in err
