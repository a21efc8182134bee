"""Typed configurations from and to YAML: one frozen dataclass per estimator, nested groups.

A profile file holds one section per estimator (``mcl:``, ``grid:``); each section names only
the fields it changes, at any depth, and everything else keeps the dataclass's defaults (the
papers' values). Unknown fields and values of the wrong type are errors naming the file and the
field (:class:`ConfigError`). A Python field with a trailing underscore (``global_``, a keyword)
is written without it.
"""

from __future__ import annotations

import dataclasses
import enum
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml

from tourbot.errors import TourbotError

__all__ = ["ConfigError", "from_mapping", "load_yaml", "to_mapping", "to_yaml"]

T = TypeVar("T")


class ConfigError(TourbotError):
    """A configuration file that cannot be read: names the file and the field."""


def _key(name: str) -> str:
    return name[:-1] if name.endswith("_") else name


def to_mapping(config: Any) -> dict[str, Any]:
    """A dataclass as plain YAML-able data (enums by value, tuples as lists)."""

    def plain(v: Any) -> Any:
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            return {_key(f.name): plain(getattr(v, f.name)) for f in dataclasses.fields(v)}
        if isinstance(v, enum.Enum):
            return v.value
        if isinstance(v, tuple | list):
            return [plain(x) for x in v]
        return v

    out = plain(config)
    assert isinstance(out, dict)
    return out


def to_yaml(sections: Mapping[str, Any]) -> str:
    """YAML of ``{section: dataclass}``."""
    return yaml.safe_dump({k: to_mapping(v) for k, v in sections.items()}, sort_keys=False)


def _convert(tp: Any, value: Any, where: str) -> Any:  # noqa: PLR0911 (one return per type)
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return _convert(a, value, where)
            except ConfigError as exc:
                errors.append(str(exc))
        raise ConfigError(errors[0] if errors else f"{where}: cannot be {value!r}")
    if origin is typing.Literal:
        if value not in args:
            raise ConfigError(f"{where}: must be one of {', '.join(map(str, args))}, not {value!r}")
        return value
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ConfigError(f"{where}: must be a list of {len(args)} numbers, not {value!r}")
        items = list(value)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], x, f"{where}[{i}]") for i, x in enumerate(items))
        if len(items) != len(args):
            raise ConfigError(f"{where}: must be a list of {len(args)} values, not {len(items)}")
        return tuple(
            _convert(a, x, f"{where}[{i}]") for i, (a, x) in enumerate(zip(args, items, strict=True))
        )
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        if not isinstance(value, Mapping):
            raise ConfigError(f"{where}: must be a mapping of fields, not {value!r}")
        return from_mapping(tp, value, where)
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        try:
            return tp(value)
        except ValueError:
            choices = ", ".join(str(m.value) for m in tp)
            raise ConfigError(f"{where}: must be one of {choices}, not {value!r}") from None
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: must be true or false, not {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: must be an integer, not {value!r}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{where}: must be a number, not {value!r}")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: must be a string, not {value!r}")
        return value
    raise ConfigError(f"{where}: fields of type {tp} cannot be set from a file")


def from_mapping(cls: type[T], data: Mapping[str, Any], where: str = "", base: T | None = None) -> T:
    """``cls`` with the fields named in ``data`` (nested groups as nested mappings) set over
    ``base`` (the defaults when None). ``where`` prefixes field names in errors."""
    assert dataclasses.is_dataclass(cls)
    hints = typing.get_type_hints(cls)
    fields = {_key(f.name): f for f in dataclasses.fields(cls)}
    current = base if base is not None else cls()
    changes: dict[str, Any] = {}
    for key, value in data.items():
        name = f"{where}.{key}" if where else str(key)
        f = fields.get(str(key))
        if f is None:
            raise ConfigError(f"{name}: no such field (fields: {', '.join(fields)})")
        tp = hints[f.name]
        if isinstance(tp, type) and dataclasses.is_dataclass(tp) and isinstance(value, Mapping):
            changes[f.name] = from_mapping(tp, value, name, getattr(current, f.name))
        else:
            changes[f.name] = _convert(tp, value, name)
    try:
        return dataclasses.replace(current, **changes)  # type: ignore[type-var]
    except TourbotError as exc:
        raise ConfigError(f"{where or cls.__name__}: {exc}") from None


def load_yaml(path: Path, sections: Mapping[str, type[Any]]) -> dict[str, Any]:
    """Read the profile ``path``: ``{section: dataclass}`` for every section in ``sections``
    (those the file does not name keep their defaults). :class:`ConfigError` names the file and
    field of anything wrong."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the configuration ({exc.strerror})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" line {mark.line + 1}" if mark is not None else ""
        raise ConfigError(f"{path}:{line} not YAML ({getattr(exc, 'problem', exc)})") from None
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise ConfigError(f"{path}: must be a mapping of sections ({', '.join(sections)})")
    out: dict[str, Any] = {}
    for key in data:
        if key not in sections:
            raise ConfigError(f"{path}: {key}: no such section (sections: {', '.join(sections)})")
    for key, cls in sections.items():
        section = data.get(key) or {}
        if not isinstance(section, Mapping):
            raise ConfigError(f"{path}: {key}: must be a mapping of fields")
        try:
            out[key] = from_mapping(cls, section, key)
        except ConfigError as exc:
            raise ConfigError(f"{path}: {exc}") from None
    return out
