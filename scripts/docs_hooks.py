"""MkDocs hooks of the documentation site (``hooks:`` in mkdocs.yml), run by every ``mkdocs build``.

- The configuration reference (``docs/configuration.md``) is generated from the code: every
  dataclass of ``tourbot`` whose name ends in ``Config`` is listed with its fields (type, default,
  and the field's own documentation: an attribute docstring or ``metadata["doc"]``). A field whose
  type is itself a dataclass (a nested group, ``MCLConfig.sampling``) is listed as its own table
  beneath, recursively. So the page is true to the code on every build and needs no edit when a
  configuration gains, loses or regroups fields.
- The result pages that branches drop into ``docs/results/`` appear in the navigation under
  "Results" and are listed on ``docs/results.md``, and a new API page in ``docs/api/`` appears
  under "API reference", without editing mkdocs.yml.

- The API pages (``docs/api/``) name packages, ``<!-- tourbot:api tourbot.maps -->``; the hook
  turns each into mkdocstrings directives for the package and every module in it.

The page markers are HTML comments, ``<!-- tourbot:config-reference -->``,
``<!-- tourbot:results-pages -->`` and ``<!-- tourbot:api PACKAGE -->``; a marker whose content
cannot be generated fails the build.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import inspect
import re
import sys
import typing
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src"
DOCS = ROOT / "docs"
CONFIG_MARKER = "<!-- tourbot:config-reference -->"
RESULTS_MARKER = "<!-- tourbot:results-pages -->"
# Navigation sections that list every page of a folder of docs/, those not named in mkdocs.yml last.
NAV_FOLDERS = {"Results": "results", "API reference": "api"}
API_MARKER = re.compile(r"^<!-- tourbot:api ([\w.]+) -->$", re.MULTILINE)
_ROLE = re.compile(r":(?:class|meth|func|attr|mod|data|obj):`~?([^`]+)`")


# ---------------------------------------------------------------------------------------------
# Result pages dropped into docs/results/


def _title(path: Path) -> str:
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# "):
            return line[2:].strip()
    return path.stem.replace("-", " ").replace("_", " ").capitalize()


def _pages(folder_name: str) -> list[tuple[str, str]]:
    """(title, path relative to docs/) of every page in docs/FOLDER/, sorted by file name."""
    folder = DOCS / folder_name
    if not folder.is_dir():
        return []
    return [(_title(p), p.relative_to(DOCS).as_posix()) for p in sorted(folder.glob("*.md"))]


def _listed(section: list[Any]) -> set[str]:
    return {item if isinstance(item, str) else next(iter(item.values())) for item in section}


def on_config(config: Any) -> Any:
    """Add the pages of docs/results/ and docs/api/ that mkdocs.yml does not list to their sections."""
    nav = config["nav"]
    for section_name, folder in NAV_FOLDERS.items():
        sections = [e[section_name] for e in nav if isinstance(e, dict) and section_name in e]
        if not sections:
            raise ValueError(f"mkdocs.yml: the navigation has no {section_name!r} section")
        listed = _listed(sections[0])
        sections[0].extend({title: path} for title, path in _pages(folder) if path not in listed)
    return config


# ---------------------------------------------------------------------------------------------
# Configuration reference


@functools.cache
def _griffe_objects() -> dict[str, Any]:
    """Every class of tourbot by its path, read statically (no import) by griffe, once per build."""
    import griffe

    package = griffe.load("tourbot", search_paths=[str(SRC)], allow_inspection=False)
    objects: dict[str, Any] = {}

    def walk(module: Any) -> None:
        for member in module.members.values():
            if member.is_alias:
                continue
            if member.is_module:
                walk(member)
            elif member.is_class:
                objects[member.path] = member

    walk(package)
    return objects


def _config_classes() -> list[str]:
    """Import paths of the dataclasses named ``*Config`` in tourbot."""
    return sorted(
        path
        for path, cls in _griffe_objects().items()
        if cls.name.endswith("Config") and "dataclass" in cls.labels
    )


def _attribute_docs(path: str) -> dict[str, str]:
    """Field name -> its attribute docstring (the string literal below the field), via griffe."""
    cls = _griffe_objects().get(path)
    if cls is None:
        return {}
    return {
        member.name: member.docstring.value
        for member in cls.members.values()
        if member.is_attribute and member.docstring is not None
    }


def _import(path: str) -> type:
    module_path, _, name = path.rpartition(".")
    if str(SRC) not in sys.path:
        sys.path.insert(0, str(SRC))
    cls = getattr(importlib.import_module(module_path), name)
    if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)):
        raise TypeError(f"{path} is not a dataclass")
    return cls


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _is_heading(line: str, following: str) -> bool:
    """A section heading of a class docstring: a short unindented line above an indented body."""
    indented = following.startswith((" ", "\t"))
    return bool(line) and not line[0].isspace() and indented and len(line.split()) <= 3


def _prose(docstring: str | None) -> str:
    """A class docstring as Markdown: rST roles as code, indented section bodies as paragraphs."""
    if not docstring:
        return ""
    lines = inspect.cleandoc(docstring).splitlines()
    out: list[str] = []
    for i, line in enumerate(lines):
        nxt = lines[i + 1] if i + 1 < len(lines) else ""
        if _is_heading(line, nxt):
            out.extend(["", f"**{line.strip().rstrip(':')}**", ""])  # a section heading
        else:
            out.append(line.strip())
    return _ROLE.sub(r"`\1`", "\n".join(out)).strip()


def _short(value: Any) -> str:
    """repr with floats to 6 significant digits (0.0349066 rather than 0.03490658503988659)."""
    if isinstance(value, float):
        return repr(float(f"{value:.6g}"))
    if isinstance(value, tuple):
        inner = ", ".join(_short(v) for v in value)
        return f"({inner},)" if len(value) == 1 else f"({inner})"
    return repr(value)


def _mentioned(docstring: str, name: str) -> str:
    """The first sentence of the class docstring that names the field (``name``), else ""."""
    lines = inspect.cleandoc(docstring).splitlines()
    body = [
        line for i, line in enumerate(lines) if not (i + 1 < len(lines) and _is_heading(line, lines[i + 1]))
    ]
    # A bullet ("- ``name``: ...") is a sentence of its own.
    text = " ".join("\x00" + line.strip()[2:] if line.strip().startswith("- ") else line for line in body)
    pieces = [" ".join(item.split()) for item in text.split("\x00")]
    for sentence in (s for item in pieces for s in re.split(r"(?<=\.)\s+(?=[A-Z`(])", item)):
        if f"``{name}``" in sentence:
            found = _ROLE.sub(r"`\1`", sentence)
            return found if len(found) <= 300 else found[:297] + "..."
    return ""


def _default(field: dataclasses.Field[Any]) -> tuple[str, Any]:
    if field.default is not dataclasses.MISSING:
        value = field.default
    elif field.default_factory is not dataclasses.MISSING:
        value = field.default_factory()
    else:
        return "required", None
    text = _short(value)
    return (text if len(text) <= 60 else text[:57] + "..."), value


def _nested(cls: type, field: dataclasses.Field[Any], value: Any) -> type | None:
    """The dataclass type of a nested configuration group, else None."""
    if value is not None and dataclasses.is_dataclass(value) and not isinstance(value, type):
        return type(value)
    try:
        hint = typing.get_type_hints(cls).get(field.name)
    except Exception:
        return None
    return hint if isinstance(hint, type) and dataclasses.is_dataclass(hint) else None


def _table(path: str, cls: type, title: str, level: int, seen: set[type]) -> list[str]:
    docs = _attribute_docs(path)
    rows = ["| field | type | default | description |", "| --- | --- | --- | --- |"]
    groups: list[tuple[str, str, type]] = []
    for field in dataclasses.fields(cls):
        shown, value = _default(field)
        doc = (
            docs.get(field.name)
            or str(field.metadata.get("doc", field.metadata.get("help", "")))
            or _mentioned(cls.__doc__ or "", field.name)
        )
        group = _nested(cls, field, value)
        kind = field.type if isinstance(field.type, str) else getattr(field.type, "__name__", str(field.type))
        if group is not None and group not in seen:
            anchor = f"{title}.{field.name}"
            groups.append((anchor, f"{group.__module__}.{group.__qualname__}", group))
            shown = f"see `{anchor}` below"
        rows.append(f"| `{field.name}` | `{_cell(str(kind))}` | {_cell(shown)} | {_cell(doc)} |")
    out = [f"{'#' * level} `{title}`", "", f"`{path}`", ""]
    prose = _prose(cls.__doc__ if cls.__doc__ and not cls.__doc__.startswith(cls.__name__ + "(") else "")
    if prose:
        out += [prose, ""]
    out += [*rows, ""]
    for anchor, group_path, group in groups:
        out += _table(group_path, group, anchor, min(level + 1, 6), seen | {cls})
    return out


def config_reference() -> str:
    """The Markdown of every typed configuration of tourbot, grouped by package."""
    paths = _config_classes()
    if not paths:
        raise RuntimeError("no configuration dataclass (*Config) found under src/tourbot")
    classes = {path: _import(path) for path in paths}
    nested = {group for cls in classes.values() for group in _groups(cls)}
    out: list[str] = [
        "Groups nested in another configuration are listed under it "
        f"({len(classes) - sum(c in nested for c in classes.values())} top-level configurations).",
        "",
    ]
    package = ""
    for path, cls in classes.items():
        if cls in nested:
            continue
        top = ".".join(path.split(".")[:2])
        if top != package:
            package = top
            out += [f"## `{package}`", ""]
        out += _table(path, cls, cls.__name__, 3, set())
    return "\n".join(out)


def _groups(cls: type, seen: frozenset[type] = frozenset()) -> set[type]:
    """The configuration groups nested in ``cls``, at any depth."""
    found: set[type] = set()
    for field in dataclasses.fields(cls):
        group = _nested(cls, field, _default(field)[1])
        if group is not None and group not in seen:
            found |= {group} | _groups(group, seen | {cls})
    return found


# ---------------------------------------------------------------------------------------------
# API pages


def api_directives(package: str) -> str:
    """mkdocstrings directives documenting a package and all its modules.

    A package with an ``__init__.py`` is one directive (its submodules follow, ``show_submodules``);
    a folder without one (a namespace package, which mkdocstrings cannot collect) gets one
    directive per module file, so the page follows the tree through renames either way.
    """
    folder = SRC.joinpath(*package.split("."))
    if (folder / "__init__.py").is_file() or folder.with_suffix(".py").is_file():
        return f"::: {package}"
    modules = sorted(p.stem for p in folder.glob("*.py") if not p.stem.startswith("_"))
    if not modules:
        raise FileNotFoundError(f"API page: no package or module {package} under {SRC}")
    return "\n\n".join(f"::: {package}.{name}" for name in modules)


def on_page_markdown(markdown: str, page: Any, **_: Any) -> str:
    """Fill the markers of the configuration reference, the results page and the API pages."""
    markdown = API_MARKER.sub(lambda m: api_directives(m.group(1)), markdown)
    if CONFIG_MARKER in markdown:
        markdown = markdown.replace(CONFIG_MARKER, config_reference())
    if RESULTS_MARKER in markdown:
        here = Path(page.file.src_uri).parent
        pages = _pages("results")
        listing = "\n".join(
            f"- [{title}]({Path(path).relative_to(here).as_posix() if here != Path('.') else path})"
            for title, path in pages
        )
        markdown = markdown.replace(RESULTS_MARKER, listing or "(none yet)")
    return markdown
