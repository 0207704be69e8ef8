"""YAML configs validated into frozen, typed dataclasses.

Every runnable thing (simulator, trainers, pipeline) declares its config as a tree of frozen
dataclasses. :func:`load_config` reads a YAML file with a ``yaml.SafeLoader``, optionally merges
one base file named by the ``_base_`` key (at most one level of inheritance, a path relative to
the file), applies ``a.b=value`` overrides (values parsed as YAML scalars/lists) and builds the
dataclasses. An unknown key, a missing required key or a value of the wrong type is a
:class:`~gaitnet.errors.ConfigError` naming the file and the dotted key.

The whole config surface raises only :class:`~gaitnet.errors.ConfigError`, with one-line
messages: files that are missing, folders, unreadable, larger than :data:`MAX_FILE_BYTES` or not
UTF-8; invalid YAML, duplicate keys, nesting deeper than :data:`MAX_DEPTH`, alias bombs
(:data:`MAX_ALIASES`, :data:`MAX_NODES`); integers outside int64; malformed overrides
(``=5``, ``a..b=1``, ``a.b``, non-UTF-8 bytes); a ``_base_`` that is missing, a folder or
recursive.

:func:`config_to_dict` turns a config back into plain YAML-able data and :func:`dump_config`
into the YAML text that every run writes (atomically, through :mod:`gaitnet.io.atomic`) next
to its outputs. This module imports nothing of gaitnet but its errors.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
import types
import typing
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import yaml

from gaitnet.errors import ConfigError, one_line

T = TypeVar("T")

BASE_KEY = "_base_"
MAX_FILE_BYTES = 1024 * 1024  # a config or session.yaml is a few KiB
MAX_DEPTH = 32  # nesting levels of mappings and lists (our configs use at most 4)
MAX_ALIASES = 256  # YAML aliases per document
MAX_NODES = 100_000  # values after alias expansion
INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1
_KEY_PART = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def load_config(cls: type[T], path: str | Path | None, overrides: Sequence[str] = ()) -> T:
    """Build ``cls`` from the YAML file ``path`` (or defaults when None) plus overrides.

    Every failure (unreadable or oversized file, bad YAML, a bad override, a key or value the
    dataclasses refuse) is a :class:`ConfigError` with a one-line message naming the file or
    override and the key.
    """
    source = (
        str(path) if path is not None else "command-line overrides" if overrides else "<defaults>"
    )
    data: dict[str, Any] = {}
    if path is not None:
        data = _read_yaml_with_base(Path(path))
    for item in overrides:
        _apply_override(data, item)
    check_tree(data, source)
    return _build(cls, data, source, prefix="")


def parse_config(cls: type[T], data: Mapping[str, Any], source: str) -> T:
    """Build ``cls`` from an already-loaded mapping; ``source`` names it in errors."""
    data = dict(data)
    check_tree(data, source)
    return _build(cls, data, source, prefix="")


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


class _StrictLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses a key given twice in one mapping (YAML keeps the last
    one silently, so a doubled key would hide a typo)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=True)
            try:
                duplicate = key in seen
                seen.add(key)
            except TypeError:  # unhashable: the base class reports it
                continue
            if duplicate:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r}", key_node.start_mark
                )
        return super().construct_mapping(node, deep=deep)


# YAML 1.1 (PyYAML) reads ``5e-4`` and ``1.0e5`` as strings: accept exponents without a dot or
# a sign as numbers, as YAML 1.2 and JSON do.
_StrictLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def parse_yaml(text: str, source: str) -> Any:
    """Parse YAML ``text`` safely; ``source`` names it (a file, an override) in errors.

    Refuses, before building any object, nesting deeper than :data:`MAX_DEPTH` and more than
    :data:`MAX_ALIASES` aliases; refuses duplicate keys. Raises :class:`ConfigError`.
    """
    depth = aliases = 0
    try:
        for event in yaml.parse(text, Loader=_StrictLoader):
            if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                depth += 1
                if depth > MAX_DEPTH:
                    raise ConfigError(f"{source}: nested deeper than {MAX_DEPTH} levels")
            elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                depth -= 1
            elif isinstance(event, yaml.AliasEvent):
                aliases += 1
                if aliases > MAX_ALIASES:
                    raise ConfigError(f"{source}: more than {MAX_ALIASES} YAML aliases")
        return yaml.load(text, Loader=_StrictLoader)  # a SafeLoader subclass
    except yaml.YAMLError as exc:
        raise ConfigError(f"{source}: not valid YAML ({one_line(exc)})") from exc
    except RecursionError as exc:  # belt and braces: the depth check should prevent it
        raise ConfigError(f"{source}: nested too deeply") from exc


def read_yaml(path: str | Path) -> Any:
    """Read and parse one YAML file (UTF-8, at most :data:`MAX_FILE_BYTES`) safely.

    A missing file, a folder, an unreadable or oversized file, bytes that are not UTF-8 and
    invalid YAML are config errors naming the file.
    """
    path = Path(path)
    try:
        if path.is_dir():
            raise ConfigError(f"{path}: is a folder, expected a YAML file")
        if path.exists() and not path.is_file():  # a FIFO or device would block or never end
            raise ConfigError(f"{path}: not a regular file")
        with path.open("rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)
    except FileNotFoundError as exc:
        raise ConfigError(f"{path}: config file not found") from exc
    except (OSError, ValueError) as exc:  # permission denied, a file used as a folder, NUL byte
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise ConfigError(f"{path}: cannot read ({reason})") from exc
    if len(raw) > MAX_FILE_BYTES:
        raise ConfigError(f"{path}: larger than {MAX_FILE_BYTES // 1024} KiB, not a config file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise ConfigError(f"{path}: not UTF-8 text (byte {exc.start}, line {line})") from exc
    return parse_yaml(text, str(path))


def _read_yaml(path: Path) -> dict[str, Any]:
    data = read_yaml(path)
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: top level must be a mapping of keys, got {type(data).__name__}")
    return data


def _read_yaml_with_base(path: Path) -> dict[str, Any]:
    data = _read_yaml(path)
    if BASE_KEY not in data:
        return data
    base_name = data.pop(BASE_KEY)
    if not isinstance(base_name, str) or not base_name.strip():
        raise ConfigError(f"{path}: key '{BASE_KEY}' must be a file path, got {base_name!r}")
    try:
        base_path = (path.parent / base_name).resolve()
        itself = base_path == path.resolve()
    except (OSError, RuntimeError, ValueError) as exc:  # symlink loop, NUL byte
        raise ConfigError(
            f"{path}: key '{BASE_KEY}': cannot resolve {base_name!r} ({exc})"
        ) from exc
    if itself:
        raise ConfigError(f"{path}: key '{BASE_KEY}' names the file itself")
    try:
        base = _read_yaml(base_path)
    except ConfigError as exc:
        raise ConfigError(f"{path}: base config (key '{BASE_KEY}'): {exc}") from exc
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
    shown = one_line(item)
    try:
        item.encode("utf-8")
    except UnicodeEncodeError:
        raise ConfigError(f"override '{shown}': not UTF-8 text") from None
    if "=" not in item:
        raise ConfigError(f"override '{shown}': expected key=value (e.g. gait.speed_mps=1.4)")
    key, _, raw = item.partition("=")
    key = key.strip()
    if not key:
        raise ConfigError(f"override '{shown}': empty key (expected key=value)")
    parts = key.split(".")
    for part in parts:
        if not _KEY_PART.fullmatch(part):
            raise ConfigError(
                f"override '{shown}': {key!r} is not a dotted key (letters, digits and _ "
                "between dots, e.g. gait.speed_mps)"
            )
    value = parse_yaml(raw, f"override '{shown}'") if raw.strip() else ""
    node = data
    for i, part in enumerate(parts[:-1]):
        child = node.get(part)
        if child is None:
            child = {}
            node[part] = child
        if not isinstance(child, dict):
            raise ConfigError(f"override '{shown}': '{'.'.join(parts[: i + 1])}' is not a section")
        node = child
    node[parts[-1]] = value


def check_tree(data: Any, source: str) -> None:
    """Refuse loaded data no config can be: nesting deeper than :data:`MAX_DEPTH`, more than
    :data:`MAX_NODES` values (e.g. YAML aliases expanding exponentially), integers outside
    int64. Raises :class:`ConfigError` naming ``source`` and the dotted key."""
    budget = MAX_NODES
    stack: list[tuple[Any, str, int]] = [(data, "", 0)]
    while stack:
        value, key, depth = stack.pop()
        budget -= 1
        if budget < 0:
            raise ConfigError(f"{source}: more than {MAX_NODES} values (YAML alias expansion?)")
        if depth > MAX_DEPTH:
            raise ConfigError(f"{source}: key '{key}' is nested deeper than {MAX_DEPTH} levels")
        if isinstance(value, bool):
            continue
        if isinstance(value, int) and not INT64_MIN <= value <= INT64_MAX:
            raise ConfigError(
                f"{source}: key '{key or '<top level>'}' is an integer outside the 64-bit range"
            )
        if isinstance(value, Mapping):
            for k, v in value.items():
                stack.append((v, f"{key}.{k}" if key else str(k), depth + 1))
        elif isinstance(value, (list, tuple)):
            for i, v in enumerate(value):
                stack.append((v, f"{key}[{i}]", depth + 1))


def _build(cls: type[T], data: Any, source: str, prefix: str) -> T:
    where = prefix.rstrip(".") or "<top level>"
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: key '{where}' must be a mapping, got {data!r}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    replaced: dict[str, str] = getattr(cls, "REPLACED_KEYS", {})
    for key in data:
        if key in replaced and key not in fields:
            raise ConfigError(
                f"{source}: key '{prefix}{key}' was replaced by '{prefix}{replaced[key]}'"
            )
        if key not in fields:
            close = difflib.get_close_matches(str(key), list(fields), n=1, cutoff=0.6)
            if close:
                raise ConfigError(
                    f"{source}: unknown key '{prefix}{key}'; did you mean '{prefix}{close[0]}'?"
                )
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
    except (ValueError, TypeError, ArithmeticError) as exc:  # __post_init__ range checks
        if prefix:
            raise ConfigError(f"{source}: {where}: {exc}") from exc
        raise ConfigError(f"{source}: {exc}") from exc


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
        candidates = [a for a in args if a is not type(None)]
        if len(candidates) == 1:  # Optional[X]: X's own message names the inner key
            return _convert(candidates[0], value, source, key)
        for arg in candidates:
            try:
                return _convert(arg, value, source, key)
            except ConfigError:
                continue
        raise fail()
    if origin is typing.Literal:
        if any(type(value) is type(a) and value == a for a in typing.get_args(tp)):
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
