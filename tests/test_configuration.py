from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import pytest

from tourbot.configuration import ConfigError, from_mapping, load_yaml, to_mapping, to_yaml
from tourbot.localization.beam_filters import BeamFilter


@dataclass(frozen=True)
class _Inner:
    a: float = 1.0
    pair: tuple[float, float] = (0.5, 0.25)


@dataclass(frozen=True)
class _Outer:
    n: int = 3
    flag: bool = False
    kind: BeamFilter = BeamFilter.NONE
    mode: Literal["x", "y"] = "x"
    period: float | None = None
    global_: _Inner = field(default_factory=_Inner)


def test_round_trip_through_yaml(tmp_path: Path) -> None:
    cfg = from_mapping(_Outer, {"n": 5, "kind": "entropy", "period": 2, "global": {"pair": [1, 2]}})
    assert cfg == _Outer(n=5, kind=BeamFilter.ENTROPY, period=2.0, global_=_Inner(pair=(1.0, 2.0)))
    assert to_mapping(cfg)["global"] == {"a": 1.0, "pair": [1.0, 2.0]}
    path = tmp_path / "c.yaml"
    path.write_text(to_yaml({"outer": cfg}))
    assert load_yaml(path, {"outer": _Outer}) == {"outer": cfg}
    path.write_text("")
    assert load_yaml(path, {"outer": _Outer}) == {"outer": _Outer()}


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"n": 1.5}, "o.n: must be an integer"),
        ({"n": True}, "o.n: must be an integer"),
        ({"flag": "yes"}, "o.flag: must be true or false"),
        ({"kind": "both"}, "o.kind: must be one of none, entropy, novelty"),
        ({"mode": "z"}, "o.mode: must be one of x, y"),
        ({"period": "soon"}, "o.period: must be a number"),
        ({"global": {"pair": [1]}}, "o.global.pair: must be a list of 2"),
        ({"global": 3}, "o.global: must be a mapping"),
        ({"other": 1}, "o.other: no such field"),
    ],
)
def test_wrong_values_name_their_field(data: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message.replace(".", r"\.").replace("(", r"\(")):
        from_mapping(_Outer, data, "o")


def test_files_that_are_not_profiles(tmp_path: Path) -> None:
    path = tmp_path / "c.yaml"
    path.write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match="must be a mapping of sections"):
        load_yaml(path, {"outer": _Outer})
    path.write_text("outer: 3\n")
    with pytest.raises(ConfigError, match="outer: must be a mapping of fields"):
        load_yaml(path, {"outer": _Outer})
    with pytest.raises(ConfigError, match="cannot read"):
        load_yaml(tmp_path / "missing.yaml", {"outer": _Outer})
