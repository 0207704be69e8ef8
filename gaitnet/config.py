"""YAML configs validated into frozen, typed dataclasses.

Every runnable thing (simulator, trainers, pipeline) declares its config as a tree of frozen
dataclasses. :func:`load_config` reads a YAML file with ``yaml.safe_load``, optionally merges
one base file named by the ``_base_`` key (at most one level of inheritance, a path relative to
the file), applies ``a.b=value`` overrides (values parsed as YAML scalars/lists) and builds the
dataclasses. An unknown key, a missing required key or a value of the wrong type is a
:class:`~gaitnet.errors.ConfigError` naming the file and the dotted key.

:func:`config_to_dict` turns a config back into plain YAML-able data; :func:`save_config`
writes the resolved config (atomically) next to a run's outputs.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import yaml

from gaitnet.errors import ConfigError

T = TypeVar("T")

BASE_KEY = "_base_"


def load_config(cls: type[T], path: str | Path | None, overrides: Sequence[str] = ()) -> T:
    """Build ``cls`` from the YAML file ``path`` (or defaults when None) plus overrides."""
    source = str(path) if path is not None else "<defaults>"
    data: dict[str, Any] = {}
    if path is not None:
        data = _read_yaml_with_base(Path(path))
    for item in overrides:
        _apply_override(data, item)
    return _build(cls, data, source, prefix="")


def parse_config(cls: type[T], data: Mapping[str, Any], source: str) -> T:
    """Build ``cls`` from an already-loaded mapping; ``source`` names it in errors."""
    return _build(cls, dict(data), source, prefix="")


def config_to_dict(cfg: Any) -> Any:
    """Plain dicts/lists/scalars of a config dataclass tree (YAML-serialisable)."""
    if dataclasses.is_dataclass(cfg) and not isinstance(cfg, type):
        return {f.name: config_to_dict(getattr(cfg, f.name)) for f in dataclasses.fields(cfg)}
    if isinstance(cfg, (list, tuple)):
        return [config_to_dict(v) for v in cfg]
    if isinstance(cfg, Path):
        return str(cfg)
    if isinstance(cfg, np.ndarray):
        return cfg.tolist()
    return cfg


def dump_config(cfg: Any) -> str:
    """The resolved config as YAML text."""
    return yaml.safe_dump(config_to_dict(cfg), sort_keys=False)


def save_config(cfg: Any, path: str | Path) -> Path:
    """Write the resolved config as YAML (atomically) and return the path."""
    from gaitnet.io.atomic import atomic_write_text  # io imports config: import here

    path = Path(path)
    atomic_write_text(path, dump_config(cfg))
    return path


def config_keys(cls: type, prefix: str = "") -> list[str]:
    """Dotted names of every key of a config dataclass tree (for docs and their tests).

    A section typed ``Section | None`` is a key itself and its fields are listed too.
    """
    keys: list[str] = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp = hints[f.name]
        inner = [a for a in typing.get_args(tp) if dataclasses.is_dataclass(a)]
        if dataclasses.is_dataclass(tp) or inner:
            if inner:
                keys.append(f"{prefix}{f.name}")
            keys += config_keys(inner[0] if inner else tp, f"{prefix}{f.name}.")
        else:
            keys.append(f"{prefix}{f.name}")
    return keys


def _read_yaml(path: Path) -> dict[str, Any]:
    if not path.is_file():
        raise ConfigError(f"{path}: config file not found")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({exc})".replace("\n", " ")) from exc
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: top level must be a mapping of keys, got {type(data).__name__}")
    return data


def _read_yaml_with_base(path: Path) -> dict[str, Any]:
    data = _read_yaml(path)
    base_name = data.pop(BASE_KEY, None)
    if base_name is None:
        return data
    if not isinstance(base_name, str):
        raise ConfigError(f"{path}: key '{BASE_KEY}' must be a file path")
    base_path = (path.parent / base_name).resolve()
    base = _read_yaml(base_path)
    if BASE_KEY in base:
        raise ConfigError(f"{base_path}: a base config may not have its own '{BASE_KEY}'")
    return _deep_merge(base, data)


def _deep_merge(base: dict[str, Any], top: dict[str, Any]) -> dict[str, Any]:
    merged = dict(base)
    for key, value in top.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = _deep_merge(merged[key], value)
        else:
            merged[key] = value
    return merged


def _apply_override(data: dict[str, Any], item: str) -> None:
    if "=" not in item:
        raise ConfigError(f"override {item!r}: expected key=value (e.g. train.epochs=5)")
    key, _, raw = item.partition("=")
    key = key.strip()
    if not key:
        raise ConfigError(f"override {item!r}: empty key")
    try:
        value = yaml.safe_load(raw) if raw.strip() else ""
    except yaml.YAMLError as exc:
        raise ConfigError(f"override {item!r}: value is not valid YAML") from exc
    node = data
    parts = key.split(".")
    for part in parts[:-1]:
        child = node.get(part)
        if child is None:
            child = {}
            node[part] = child
        if not isinstance(child, dict):
            raise ConfigError(f"override {item!r}: '{part}' is not a section")
        node = child
    node[parts[-1]] = value


def _build(cls: type[T], data: Any, source: str, prefix: str) -> T:
    where = prefix.rstrip(".") or "<top level>"
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: key '{where}' must be a mapping, got {data!r}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    for key in data:
        if key not in fields:
            known = ", ".join(sorted(fields))
            raise ConfigError(f"{source}: unknown key '{prefix}{key}' (known keys: {known})")
    kwargs: dict[str, Any] = {}
    for name, field in fields.items():
        if name in data:
            kwargs[name] = _convert(hints[name], data[name], source, f"{prefix}{name}")
        elif field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING:
            nested = hints[name]
            if dataclasses.is_dataclass(nested):
                kwargs[name] = _build(nested, {}, source, f"{prefix}{name}.")
            else:
                raise ConfigError(f"{source}: missing required key '{prefix}{name}'")
    try:
        return cls(**kwargs)
    except (ValueError, TypeError) as exc:  # __post_init__ range checks
        raise ConfigError(f"{source}: {where}: {exc}") from exc


def _type_name(tp: Any) -> str:
    return getattr(tp, "__name__", None) or str(tp).replace("typing.", "")


def _convert(tp: Any, value: Any, source: str, key: str) -> Any:
    def fail() -> ConfigError:
        return ConfigError(f"{source}: key '{key}' expects {_type_name(tp)}, got {value!r}")

    origin = typing.get_origin(tp)
    if tp is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(tp)
        if value is None and type(None) in args:
            return None
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(arg, value, source, key)
            except ConfigError:
                continue
        raise fail()
    if origin is typing.Literal:
        if value in typing.get_args(tp):
            return value
        choices = ", ".join(repr(a) for a in typing.get_args(tp))
        raise ConfigError(f"{source}: key '{key}' must be one of {choices}, got {value!r}")
    if origin in (tuple, list):
        if not isinstance(value, (list, tuple)):
            raise fail()
        args = typing.get_args(tp)
        if origin is tuple and args and args[-1] is not Ellipsis:
            if len(value) != len(args):
                raise ConfigError(
                    f"{source}: key '{key}' expects {len(args)} values, got {len(value)}"
                )
            items = [
                _convert(a, v, source, f"{key}[{i}]")
                for i, (a, v) in enumerate(zip(args, value, strict=True))
            ]
        else:
            item_tp = args[0] if args else Any
            items = [_convert(item_tp, v, source, f"{key}[{i}]") for i, v in enumerate(value)]
        return tuple(items) if origin is tuple else items
    if origin is dict or tp is dict:
        if not isinstance(value, dict):
            raise fail()
        return dict(value)
    if dataclasses.is_dataclass(tp):
        return _build(tp, value, source, f"{key}.")
    if tp is bool:
        if isinstance(value, bool):
            return value
        raise fail()
    if tp is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise fail()
    if tp is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            try:
                number = float(value)
            except OverflowError:
                raise fail() from None
            if not math.isfinite(number):
                raise ConfigError(f"{source}: key '{key}' must be a finite number, got {value!r}")
            return number
        raise fail()
    if tp is np.ndarray:
        try:
            array = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError, OverflowError):
            raise fail() from None
        if array.dtype == object or not np.all(np.isfinite(array)):
            raise ConfigError(f"{source}: key '{key}' must be an array of finite numbers")
        return array
    if tp is str:
        if isinstance(value, str):
            return value
        raise fail()
    if tp is Path:
        if isinstance(value, str):
            return Path(value)
        raise fail()
    raise ConfigError(f"{source}: key '{key}' has an unsupported type {_type_name(tp)}")
