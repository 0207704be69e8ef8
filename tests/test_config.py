"""Typed YAML configs: validation, base inheritance, overrides, resolved-config round trip."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import pytest

from gaitnet.config import dump_config, load_config
from gaitnet.errors import ConfigError


@dataclass(frozen=True)
class Optim:
    lr: float = 5e-4
    gamma: float = 0.96
    kind: Literal["adam", "sgd"] = "adam"


@dataclass(frozen=True)
class Example:
    name: str
    epochs: int = 50
    optim: Optim = field(default_factory=Optim)
    sizes: tuple[int, ...] = (1, 2)
    pair: tuple[float, float] = (0.0, 1.0)
    note: str | None = None

    def __post_init__(self) -> None:
        if self.epochs < 1:
            raise ValueError("epochs must be at least 1")


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_defaults_and_values(tmp_path: Path) -> None:
    cfg = load_config(Example, write(tmp_path / "a.yaml", "name: x\noptim: {lr: 1}\n"))
    assert cfg == Example(name="x", optim=Optim(lr=1.0))
    assert isinstance(cfg.optim.lr, float)


def test_unknown_key_names_key_and_file(tmp_path: Path) -> None:
    path = write(tmp_path / "bad.yaml", "name: x\noptim: {lrr: 1}\n")
    with pytest.raises(ConfigError, match=r"bad.yaml: unknown key 'optim.lrr'"):
        load_config(Example, path)


def test_unknown_key_suggests_the_closest_known_one(tmp_path: Path) -> None:
    """A misspelt key gets "did you mean" with its dotted path; a key like no other lists
    the known ones; an override names the command line as its source."""
    path = write(tmp_path / "bad.yaml", "name: x\noptim: {lrr: 1}\n")
    with pytest.raises(ConfigError, match=r"unknown key 'optim.lrr'; did you mean 'optim.lr'\?$"):
        load_config(Example, path)
    with pytest.raises(ConfigError, match=r"unknown key 'optim.zzz' \(known keys: .*lr"):
        load_config(Example, None, ["name=x", "optim.zzz=1"])
    with pytest.raises(ConfigError, match=r"^command-line overrides: unknown key 'epoch';"):
        load_config(Example, None, ["name=x", "epoch=3"])


def test_wrong_type_names_key_and_file(tmp_path: Path) -> None:
    path = write(tmp_path / "bad.yaml", "name: x\nepochs: ten\n")
    with pytest.raises(ConfigError, match=r"bad.yaml: key 'epochs' expects int, got 'ten'"):
        load_config(Example, path)
    path = write(tmp_path / "bad2.yaml", "name: x\nepochs: 2.5\n")
    with pytest.raises(ConfigError, match="key 'epochs' expects int"):
        load_config(Example, path)
    path = write(tmp_path / "bad3.yaml", "name: x\nsizes: [1, b]\n")
    with pytest.raises(ConfigError, match=r"key 'sizes\[1\]' expects int"):
        load_config(Example, path)
    path = write(tmp_path / "bad4.yaml", "name: x\noptim: {kind: rmsprop}\n")
    with pytest.raises(ConfigError, match="'optim.kind' must be one of 'adam', 'sgd'"):
        load_config(Example, path)
    path = write(tmp_path / "bad5.yaml", "name: x\npair: [1, 2, 3]\n")
    with pytest.raises(ConfigError, match="'pair' expects 2 values, got 3"):
        load_config(Example, path)


def test_missing_required_and_range_check(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="missing required key 'name'"):
        load_config(Example, write(tmp_path / "a.yaml", "epochs: 3\n"))
    with pytest.raises(ConfigError, match="epochs must be at least 1"):
        load_config(Example, write(tmp_path / "b.yaml", "name: x\nepochs: 0\n"))


def test_overrides(tmp_path: Path) -> None:
    path = write(tmp_path / "a.yaml", "name: x\n")
    cfg = load_config(Example, path, ["optim.lr=0.1", "sizes=[3, 4]", "note=hello", "epochs=7"])
    assert cfg.optim.lr == 0.1 and cfg.sizes == (3, 4) and cfg.note == "hello"
    assert cfg.epochs == 7
    with pytest.raises(ConfigError, match="unknown key 'optim.beta'"):
        load_config(Example, path, ["optim.beta=1"])
    with pytest.raises(ConfigError, match="expected key=value"):
        load_config(Example, path, ["epochs"])


def test_one_level_base(tmp_path: Path) -> None:
    write(tmp_path / "base.yaml", "name: base\nepochs: 10\noptim: {lr: 0.5, kind: sgd}\n")
    child = write(tmp_path / "child.yaml", "_base_: base.yaml\noptim: {lr: 0.25}\n")
    cfg = load_config(Example, child)
    assert cfg == Example(name="base", epochs=10, optim=Optim(lr=0.25, kind="sgd"))
    write(tmp_path / "b2.yaml", "_base_: base.yaml\nname: y\n")
    grandchild = write(tmp_path / "c.yaml", "_base_: b2.yaml\n")
    with pytest.raises(ConfigError, match="may not have its own '_base_'"):
        load_config(Example, grandchild)


def test_resolved_config_round_trip(tmp_path: Path) -> None:
    cfg = Example(name="r", epochs=3, sizes=(5,), note=None)
    path = tmp_path / "config.yaml"
    path.write_text(dump_config(cfg), encoding="utf-8")
    assert load_config(Example, path) == cfg
    assert "optim:" in dump_config(cfg)


def test_invalid_yaml_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(Example, write(tmp_path / "a.yaml", "name: [x\n"))
    with pytest.raises(ConfigError, match="config file not found"):
        load_config(Example, tmp_path / "none.yaml")


def test_exponent_numbers_duplicate_keys_and_literal_types(tmp_path: Path) -> None:
    """YAML 1.1 reads ``5e-4`` as a string: configs read it as a number (YAML 1.2); a key
    given twice is an error (YAML would keep the last one silently); a literal matches by type."""
    cfg = load_config(Example, write(tmp_path / "a.yaml", "name: x\noptim: {lr: 5e-4}\n"))
    assert cfg.optim.lr == 5e-4
    assert load_config(Example, None, ["name=x", "optim.gamma=1e-1"]).optim.gamma == 0.1
    with pytest.raises(ConfigError, match="duplicate key 'epochs'"):
        load_config(Example, write(tmp_path / "b.yaml", "name: x\nepochs: 3\nepochs: 4\n"))

    @dataclass(frozen=True)
    class Choice:
        level: Literal[1, 2] = 1

    with pytest.raises(ConfigError, match="'level' must be one of 1, 2, got True"):
        load_config(Choice, None, ["level=true"])
    assert load_config(Choice, None, ["level=2"]).level == 2


def test_a_replaced_key_names_its_replacement(tmp_path: Path) -> None:
    from gaitnet.pipeline.config import InferConfig

    path = tmp_path / "old_infer_config.yaml"
    path.write_text("pipeline:\n  bridge_gaps: true\n")
    with pytest.raises(
        ConfigError,
        match=r"old_infer_config.yaml.*'pipeline.bridge_gaps' was "
        r"replaced by 'pipeline.gap_fill",
    ):
        load_config(InferConfig, path)
    # the replacement is accepted
    assert (
        load_config(InferConfig, None, ["pipeline.gap_fill=bridge"]).pipeline.gap_fill == "bridge"
    )


def test_the_stance_camera_scale_names_the_walking_line_scale() -> None:
    from gaitnet.vio.config import VioConfig

    with pytest.raises(
        ConfigError, match=r"'stance.camera_sigma_m' was replaced by 'stance.line_sigma_m"
    ):
        load_config(VioConfig, None, ["stance.camera_sigma_m=0.15"])
    assert load_config(VioConfig, None, ["stance.line_sigma_m=0.05"]).stance.line_sigma_m == 0.05
