"""Imports run one way (docs/design.md, *Layers*): every ``import`` in gaitnet/ is checked."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "gaitnet"

#: package → layer; a package may import only packages of a lower layer (and itself).
LAYERS = {
    "errors": 0,
    "checks": 1,
    "config": 1,
    "filters": 1,
    "geometry": 1,
    "io": 2,
    "evaluation": 3,
    "motion": 4,
    "vio": 4,
    "segmentation": 4,
    "sim": 5,
    "training": 5,
    "pipeline": 5,
    "batch": 6,
    "cli": 7,
    "__init__": 7,
}


def _package_of(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] != "gaitnet":
        return None
    return parts[1] if len(parts) > 1 else "__init__"


def _imports(path: Path) -> list[tuple[int, str]]:
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.lineno, node.module))
            if node.module == "gaitnet":  # from gaitnet import sim (a module, not a name)
                found += [
                    (node.lineno, f"gaitnet.{a.name}")
                    for a in node.names
                    if (PACKAGE / a.name).is_dir() or (PACKAGE / f"{a.name}.py").is_file()
                ]
        elif isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
    return found


def _source_files() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def test_every_package_has_a_layer() -> None:
    packages = {p.relative_to(PACKAGE).parts[0].removesuffix(".py") for p in _source_files()}
    assert packages <= set(LAYERS), f"give these a layer: {packages - set(LAYERS)}"


@pytest.mark.parametrize("path", _source_files(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_run_one_way(path: Path) -> None:
    own = path.relative_to(PACKAGE).parts[0].removesuffix(".py")
    for lineno, module in _imports(path):
        assert module.split(".")[0] not in ("tests", "train", "export", "data", "benchmarks"), (
            f"{path}:{lineno}: the library imports a script or test module {module}"
        )
        target = _package_of(module)
        if target is None or target == own or (own, target) == ("cli", "__init__"):
            continue  # the command prints the package's __version__
        assert LAYERS[target] < LAYERS[own], (
            f"{path}:{lineno}: gaitnet.{own} (layer {LAYERS[own]}) imports {module} "
            f"(layer {LAYERS[target]}); imports must run downwards (docs/design.md)"
        )


def test_the_checker_sees_an_upward_import(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("import numpy\nfrom gaitnet.sim.gait import generate_walk\n")
    assert (2, "gaitnet.sim.gait") in _imports(bad)
    assert LAYERS[_package_of("gaitnet.sim.gait")] > LAYERS["motion"]
