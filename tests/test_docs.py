"""Docs match the code (docs drift is a defect).

Every config key of every config class has a row in docs/configs.md whose type and default
are the code's; README's command table and docs/cli.md name every command and every option of
``gaitnet --help`` and no command that does not exist; README's test command is what CI runs;
declared dependencies are used and their extras documented; every document the project cites
is in the project.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import tomllib
import types
import typing
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gaitnet.cli import build_parser
from gaitnet.config import config_keys
from gaitnet.io.types import SessionCalibration
from gaitnet.pipeline.config import InferConfig
from gaitnet.sim.config import SimConfig
from gaitnet.training.predictor import PredictorTrainingConfig
from gaitnet.training.segmenter import SegmenterTrainingConfig
from gaitnet.vio.config import VioConfig

ROOT = Path(__file__).parents[1]
README = (ROOT / "README.md").read_text()
CLI_DOC = (ROOT / "docs" / "cli.md").read_text()
CONFIG_DOC = (ROOT / "docs" / "configs.md").read_text()

# --- config keys ---------------------------------------------------------------------------

#: docs/configs.md section heading (its start) → the config class it documents.
CONFIG_SECTIONS: dict[str, type] = {
    "## Simulator": SimConfig,
    "## Motion predictor training": PredictorTrainingConfig,
    "## Segmenter training": SegmenterTrainingConfig,
    "## Visual-inertial filter": VioConfig,
    "## Recorded session": SessionCalibration,
    "## Inference": InferConfig,
}
EXTRA_ROWS = {
    SessionCalibration: {"format_version": ("int", "required")},
    InferConfig: {"vio": ("mapping", "(section)")},
}
#: Sub-trees documented in another section: (config, prefix) → that section.
DOCUMENTED_ELSEWHERE = {(InferConfig, "vio."): "## Visual-inertial filter"}


def type_text(tp: Any) -> str:
    """How docs/configs.md writes a field's type."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        text = " or ".join(type_text(a) for a in args if a is not type(None))
        return f"{text} or null" if type(None) in args else text
    if origin is typing.Literal:
        return " \\| ".join(str(a) for a in args)
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"list of {type_text(args[0])}"
        return "[" + ", ".join(type_text(a) for a in args) + "]"
    if origin is list:
        return f"list of {type_text(args[0])}"
    if tp is dict or origin is dict or dataclasses.is_dataclass(tp):
        return "mapping"
    if tp is np.ndarray:
        return "nested list"
    if tp is Path:
        return "path"
    return getattr(tp, "__name__", str(tp))


def _yaml_text(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_yaml_text(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{}" if not value else str(value)
    return str(value)


def default_text(field: dataclasses.Field) -> str:
    """How docs/configs.md writes a field's default."""
    if field.default is not dataclasses.MISSING:
        value = field.default
    elif field.default_factory is not dataclasses.MISSING:
        value = field.default_factory()
    else:
        return "required"
    return "(section)" if dataclasses.is_dataclass(value) else f"`{_yaml_text(value)}`"


def config_rows(cls: type) -> dict[str, tuple[str, str]]:
    """``key → (type, default)`` of every key of a config dataclass tree (config_keys order)."""
    rows: dict[str, tuple[str, str]] = dict(EXTRA_ROWS.get(cls, {}))
    elsewhere = tuple(prefix for owner, prefix in DOCUMENTED_ELSEWHERE if owner is cls)
    for key in config_keys(cls):
        if key.startswith(elsewhere or ("\0",)):
            continue
        parts = key.split(".")
        owner = cls
        for part in parts[:-1]:
            tp = typing.get_type_hints(owner)[part]
            inner = [a for a in typing.get_args(tp) if dataclasses.is_dataclass(a)]
            owner = inner[0] if inner else tp
        field = {f.name: f for f in dataclasses.fields(owner)}[parts[-1]]
        rows[key] = (type_text(typing.get_type_hints(owner)[parts[-1]]), default_text(field))
    return rows


def documented_rows(heading: str) -> dict[str, tuple[str, str, str]]:
    """``key → (type, default, meaning)`` of the table under ``heading`` in docs/configs.md."""
    start = CONFIG_DOC.index(heading)
    end = CONFIG_DOC.find("\n## ", start + 1)
    rows = {}
    for line in CONFIG_DOC[start : end if end > 0 else None].splitlines():
        m = re.fullmatch(r"\| `([^`]+)` \| (.*?) \| (.*?) \| (.*) \|", line)
        if m:
            assert m.group(1) not in rows, f"{heading}: key {m.group(1)} documented twice"
            rows[m.group(1)] = (m.group(2), m.group(3), m.group(4).strip())
    return rows


@pytest.mark.parametrize("heading", list(CONFIG_SECTIONS))
def test_every_config_key_has_a_matching_row(heading: str) -> None:
    expected = config_rows(CONFIG_SECTIONS[heading])
    documented = documented_rows(heading)
    assert sorted(documented) == sorted(expected), (
        f"docs/configs.md {heading}: missing {sorted(set(expected) - set(documented))}, "
        f"not in the code {sorted(set(documented) - set(expected))}"
    )
    for key, (tp, default) in expected.items():
        doc_tp, doc_default, meaning = documented[key]
        assert (doc_tp, doc_default) == (tp, default), f"{key}: docs say {doc_tp} {doc_default}"
        assert meaning, f"{key}: no meaning"


def test_every_sim_config_key_is_documented_in_the_simulator_doc() -> None:
    text = (ROOT / "docs" / "simulator.md").read_text()
    missing = [k for k in config_keys(SimConfig) if f"`{k}`" not in text]
    assert not missing, f"undocumented keys in docs/simulator.md: {missing}"


# --- commands ------------------------------------------------------------------------------


def subcommands() -> dict[str, argparse.ArgumentParser]:
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    return dict(sub.choices)  # type: ignore[arg-type]


def usage_tokens(parser: argparse.ArgumentParser) -> list[str]:
    """``--opt METAVAR`` / ``--flag`` / ``POSITIONAL`` for every argument but --help."""
    tokens = []
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        if action.option_strings:
            opt = max(action.option_strings, key=len)
            tokens.append(f"{opt} {action.metavar}" if action.nargs != 0 else opt)
        else:
            assert action.metavar, f"{parser.prog}: positional {action.dest} needs a metavar"
            tokens.append(str(action.metavar))
    return tokens


def readme_row(name: str) -> str:
    rows = [line for line in README.splitlines() if line.startswith(f"| `gaitnet {name} ")]
    assert len(rows) == 1, f"README needs one command-table row for gaitnet {name}"
    return rows[0].split("|")[1]


@pytest.mark.parametrize("name", list(subcommands()))
def test_readme_and_cli_doc_name_every_option(name: str) -> None:
    parser = subcommands()[name]
    heading = re.search(rf"^## `gaitnet {re.escape(name)}( [^`]*)?`$", CLI_DOC, re.MULTILINE)
    assert heading, f"docs/cli.md needs a '## `gaitnet {name} ...`' section"
    end = CLI_DOC.find("\n## ", heading.end())
    section = CLI_DOC[heading.end() : end if end > 0 else None]
    row = readme_row(name)
    for token in usage_tokens(parser):
        assert token in row, f"README row of gaitnet {name} lacks {token!r}"
        assert token in heading.group(0), f"docs/cli.md heading of gaitnet {name} lacks {token!r}"
        assert f"`{token.split()[0]}" in section, f"docs/cli.md gaitnet {name}: {token} unexplained"
    assert "```" in section, f"docs/cli.md gaitnet {name}: no example"
    assert "Exit status" in section, f"docs/cli.md gaitnet {name}: exit status not documented"


def test_global_options_and_exit_codes_are_documented() -> None:
    parser = build_parser()
    for action in parser._actions:
        for opt in action.option_strings:
            if opt not in ("-h", "--help"):
                assert opt in CLI_DOC and opt in README, opt
    for code in ("| 0 |", "| 1 |", "| 2 |", "| 130 |", "| 143 |"):
        assert code in CLI_DOC, f"docs/cli.md exit-status table lacks {code}"
    help_text = parser.format_help()
    assert "docs/cli.md" in help_text and "130/143" in help_text


def test_no_document_promises_a_command_that_does_not_exist() -> None:
    names = set(subcommands())
    texts = {"README.md": README}
    texts |= {f"docs/{p.name}": p.read_text() for p in sorted((ROOT / "docs").glob("*.md"))}
    inline = re.compile(r"(?:`|\$ |bin/)gaitnet ([a-z][a-z-]*)")
    in_code = re.compile(r"^gaitnet ([a-z][a-z-]*)", re.MULTILINE)
    for path, text in texts.items():
        code = "\n".join(re.findall(r"```[a-z]*\n(.*?)```", text, re.DOTALL))
        for found in inline.findall(text) + in_code.findall(code):
            assert found in names, f"{path} mentions `gaitnet {found}`, which does not exist"


# --- install, CI, dependencies -------------------------------------------------------------


def readme_commands() -> list[str]:
    blocks = re.findall(r"```bash\n(.*?)```", README, re.DOTALL)
    return [line for b in blocks for line in b.splitlines() if line.startswith("python3.11")]


def test_ci_runs_readme_test_command_verbatim() -> None:
    install, tests = readme_commands()
    assert "pip install -q -e . " in install and "pip install -q -e '.[dev]'" in tests
    ci_lines = (ROOT / ".ci" / "run").read_text().splitlines()
    assert tests in ci_lines, ".ci/run must run README command 2 verbatim"


#: distribution name → the module the project imports it as
IMPORT_NAMES = {
    "opencv-contrib-python-headless": "cv2",
    "PyYAML": "yaml",
    "pillow": "PIL",
    "zlib-ng": "zlib_ng",
}


def test_core_dependencies_are_used_and_extras_documented() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    sources = "\n".join(p.read_text() for p in (ROOT / "gaitnet").rglob("*.py"))
    for requirement in project["dependencies"]:
        name, _, version = requirement.partition("==")
        assert version, f"{requirement}: pin it exactly"
        module = IMPORT_NAMES.get(name, name)
        assert re.search(rf"^\s*(from|import) {module}\b", sources, re.MULTILINE), (
            f"core dependency {name} is never imported by gaitnet/: drop it or make it an extra"
        )
    for extra, requirements in project["optional-dependencies"].items():
        assert f"`.[{extra}]`" in README, f"README does not document the [{extra}] extra"
        for requirement in requirements:
            assert "==" in requirement or requirement.startswith("gaitnet["), requirement


# --- citations -----------------------------------------------------------------------------


def test_every_cited_document_is_in_the_project() -> None:
    files = [ROOT / "README.md", *(ROOT / "docs").glob("*.md")]
    for folder in ("gaitnet", "train", "export", "data", "benchmarks", "tests"):
        files += (ROOT / folder).rglob("*.py")
    cited = re.compile(r"(?<![\w/.])((?:docs/)?[\w-]+\.md)\b")
    outside = re.compile(r"(?<![\w.])/work/|\.\./(?:seeds|shared|docs)/")
    missing: set[tuple[str, str]] = set()
    for path in files:
        if path == Path(__file__):
            continue
        text = path.read_text()
        assert not outside.search(text), f"{path}: cites a path outside the project"
        for name in cited.findall(text):
            candidates = [ROOT / name, ROOT / "docs" / name, path.parent / name]
            if not any(c.is_file() for c in candidates):
                missing.add((path.relative_to(ROOT).as_posix(), name))
    assert not missing, f"cited, not in the project: {sorted(missing)}"
