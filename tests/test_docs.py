"""Every config key and every command is documented (docs drift is a defect)."""

from __future__ import annotations

import dataclasses
import typing
from pathlib import Path

from gaitnet.cli import build_parser
from gaitnet.sim.config import SimConfig

ROOT = Path(__file__).parents[1]


def leaf_keys(cls: type, prefix: str = "") -> list[str]:
    keys = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        if dataclasses.is_dataclass(hints[f.name]):
            keys += leaf_keys(hints[f.name], f"{prefix}{f.name}.")
        else:
            keys.append(f"{prefix}{f.name}")
    return keys


def test_every_sim_config_key_is_documented() -> None:
    text = (ROOT / "docs" / "simulator.md").read_text()
    missing = [k for k in leaf_keys(SimConfig) if f"`{k}`" not in text]
    assert not missing, f"undocumented keys in docs/simulator.md: {missing}"


def test_every_command_is_documented() -> None:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    readme = (ROOT / "README.md").read_text()
    cli_doc = (ROOT / "docs" / "cli.md").read_text()
    for name in sub.choices:
        assert f"gaitnet {name}" in readme, name
        assert f"## `gaitnet {name}" in cli_doc, name
