from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tourbot.cli.main import main
from tourbot.localization.profile import FHW_PROFILE


def test_config_show_prints_the_effective_configuration(capsys: pytest.CaptureFixture[str]) -> None:
    main(["config", "show"])
    defaults = yaml.safe_load(capsys.readouterr().out)
    assert defaults["mcl"]["sampling"]["max_samples"] == 2000
    assert defaults["mcl"]["sensor"]["field"]["sigma_hit"] == 0.05
    assert defaults["grid"]["cell_size"] == 0.15
    main(["config", "show", "--config", str(FHW_PROFILE)])
    fhw = yaml.safe_load(capsys.readouterr().out)
    assert fhw["mcl"]["sampling"]["max_samples"] == 5000
    assert fhw["mcl"]["sensor"]["field"]["distance"] == "surface"
    assert fhw["mcl"]["global"] == defaults["mcl"]["global"]


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("mcl:\n  sampling:\n    max_samples: lots\n", "mcl.sampling.max_samples: must be an integer"),
        ("mcl:\n  sensr: {}\n", "mcl.sensr: no such field"),
        ("mcl: [\n", "line 2"),
        ("amcl: {}\n", "amcl: no such section"),
        ("mcl:\n  recovery: {verify_distance: [1.0]}\n", "mcl.recovery.verify_distance: must be a list of 2"),
        ("grid:\n  cell_size: -1\n", "cell_size must be positive"),
    ],
)
def test_a_bad_profile_is_one_line_naming_file_and_field(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, says: str
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(SystemExit) as exc:
        main(["config", "show", "--config", str(path)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert str(path) in err.replace("\n", "")
    if says != "line":
        assert says in err
