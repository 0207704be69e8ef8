"""Every config key and every command is documented (docs drift is a defect)."""

from __future__ import annotations

from pathlib import Path

from gaitnet.cli import build_parser
from gaitnet.config import config_keys
from gaitnet.sim.config import SimConfig

ROOT = Path(__file__).parents[1]


def test_every_sim_config_key_is_documented() -> None:
    text = (ROOT / "docs" / "simulator.md").read_text()
    missing = [k for k in config_keys(SimConfig) if f"`{k}`" not in text]
    assert not missing, f"undocumented keys in docs/simulator.md: {missing}"


def test_every_command_is_documented() -> None:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    readme = (ROOT / "README.md").read_text()
    cli_doc = (ROOT / "docs" / "cli.md").read_text()
    for name in sub.choices:
        assert f"gaitnet {name}" in readme, name
        assert f"## `gaitnet {name}" in cli_doc, name
