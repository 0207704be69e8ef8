"""Fuzz the simulator's inputs: every config key with generated bad values, on both commands.

For every key of :class:`SimConfig` (from :func:`gaitnet.config.config_keys`, so a new key is
fuzzed without editing this file) values are generated from its type: NaN, ±inf, ±1e9 for
numbers, negative / huge / fractional / text for integers, non-booleans for flags, unknown
names for choices, wrong lengths and bad elements for tuples. Each goes through ``gaitnet
simulate`` and ``gaitnet simulate-dataset`` (as a ``key=value`` override, and a sample as a
config file), in-process: exit 1, exactly one stderr line naming the key, no traceback, nothing
written at ``--out`` and no staging leftovers. The same values given to the config dataclasses
from Python raise ``ValueError`` naming the key (the path that used to hang ``simulate``).
Valid tiny inputs still pass, and the library functions refuse bad seeds / counts themselves.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from pathlib import Path

import pytest
from oneline import assert_one_line_exit

from gaitnet.cli import main
from gaitnet.config import config_keys
from gaitnet.errors import InputError
from gaitnet.sim.config import SimConfig
from gaitnet.sim.dataset import simulate_dataset
from gaitnet.sim.session import simulate_session

ROOT = Path(__file__).parents[1]
TINY = str(ROOT / "configs" / "sim" / "tiny.yaml")
DEFAULT = str(ROOT / "configs" / "sim" / "default.yaml")
NUMBERS = [".nan", ".inf", "-.inf", "1e9", "-1e9"]
INTS = ["-1", "1000000000", "2.5", "many"]
BOOLS = ["maybe", "3"]
CHOICES = {
    "scene.floor_family": ["marble", "7"],
    "gait.first_foot": ["both", "0"],
    "motion.clip": ["7", "''", "'   '", "[a, b]"],
}


def _leaf_type(cls: type, dotted: str) -> typing.Any:
    tp: typing.Any = cls
    for part in dotted.split("."):
        tp = typing.get_type_hints(tp)[part]
    return tp


def bad_values(key: str) -> list[str]:
    """YAML texts that no valid config may accept for ``key``."""
    if key in CHOICES:
        return CHOICES[key]
    tp = _leaf_type(SimConfig, key)
    args = [a for a in typing.get_args(tp) if a is not type(None)]
    if tp is bool:
        return BOOLS
    if tp is int:
        return INTS
    if tp is float or (args and float in args):  # float, float | None, float | (lo, hi)
        values = [*NUMBERS, "text"]
        if any(typing.get_origin(a) is tuple for a in args):
            values += ["[.nan, 60]", "[30, 1e9]", "[60, 30]", "[1, 2, 3]"]
        return values
    if typing.get_origin(tp) is tuple:
        n = len(typing.get_args(tp))
        same = [", ".join([v] * n) for v in (".nan", "1e9", "-1e9")]
        return [*(f"[{v}]" for v in same), f"[{', '.join(['0.1'] * (n + 1))}]", "[]", "7"]
    raise AssertionError(f"no bad values for {key} of type {tp}")


KEYS = config_keys(SimConfig)
OVERRIDE_CASES = [(key, value) for key in KEYS for value in bad_values(key)]
COMMANDS = {
    "simulate": ["simulate", "--config", TINY],
    "simulate-dataset": ["simulate-dataset", "--config", TINY, "--n", "1"],
}


def run_cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    try:
        rc = main(argv)
    except SystemExit as exc:  # main must return, not exit
        rc = -1000 if exc.code is None else int(exc.code)
    return rc, capsys.readouterr().err


def assert_refused(rc: int, err: str, tmp_path: Path, names: list[str]) -> None:
    line = assert_one_line_exit(err, rc)
    assert any(name in line for name in names), (names, line)
    assert list(tmp_path.iterdir()) == [], "something was written"


def key_names(key: str) -> list[str]:
    """Ways an error line may name ``key``: dotted, or as its section's field."""
    section, _, leaf = key.rpartition(".")
    return [key, f"{section}: {leaf}", f"'{key}", f"{leaf} "]


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize(
    ("key", "value"), OVERRIDE_CASES, ids=[f"{k}={v}" for k, v in OVERRIDE_CASES]
)
def test_bad_config_value_exit_1_one_line_naming_the_key(
    command: str, key: str, value: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = [*COMMANDS[command], "--out", str(tmp_path / "out"), f"{key}={value}"]
    rc, err = run_cli(argv, capsys)
    assert_refused(rc, err, tmp_path, key_names(key))


FILE_CASES = [
    ("camera:\n  fx: .nan\n", "camera.fx"),
    ("mount:\n  offset_m: [.nan, 0, 0]\n", "offset_m"),
    ("mount:\n  pitch_deg: [80, 40]\n", "pitch_deg"),
    ("imu:\n  gyro_noise_density: -1.0\n", "gyro_noise_density"),
    ("sensor:\n  max_range_m: 0.5\n", "max_range_m"),
    ("sensor:\n  white_balance: [0, 0, 0]\n", "white_balance"),
    ("gait:\n  speed_mps: 9\n", "speed_mps"),
    ("subject:\n  height_m: 0.3\n", "height_m"),
    ("scene:\n  exposure_range: [0, 100]\n", "exposure_range"),
    ("scene:\n  texel_m: 0.0\n", "texel_m"),
    ("gait:\n  walk_length_m: 100\nscene:\n  texel_m: 0.002\n", "texel_m"),
    ("camera:\n  width: 64.5\n", "camera.width"),
    ("camera:\n  lens: fisheye\n", "camera.lens"),
    ("scene: 5\n", "scene"),
    ("output:\n  preview_frames: -2\n", "preview_frames"),
]


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize(("text", "key"), FILE_CASES, ids=[c[1] for c in FILE_CASES])
def test_bad_config_file_exit_1_one_line_naming_the_key(
    command: str, text: str, key: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "cfg" / "bad.yaml"
    config.parent.mkdir()
    config.write_text(f"_base_: {DEFAULT}\n{text}")
    out = tmp_path / "run"
    out.mkdir()
    argv = [COMMANDS[command][0], *COMMANDS[command][3:], "--config", str(config), "--out",
            str(out / "out")]  # fmt: skip
    rc, err = run_cli(argv, capsys)
    assert_refused(rc, err, out, key_names(key) if "." in key else [key])
    assert "bad.yaml" in err


@pytest.mark.parametrize(
    ("key", "value"),
    [("camera.fps", "15"), ("imu.rate_hz", "400"), ("imu.noise_free", "true"),
     ("mount.imu_rpy_deg", "[0, 0, 90]"), ("scene.exposure_drift", "0.2"),
     ("output.labels", "false")],
)  # fmt: skip
def test_dataset_refuses_keys_without_meaning_for_single_frames(
    key: str, value: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = [*COMMANDS["simulate-dataset"], "--out", str(tmp_path / "out"), f"{key}={value}"]
    rc, err = run_cli(argv, capsys)
    assert_refused(rc, err, tmp_path, [f"'{key}'"])


def _numeric_fields() -> list[tuple[str, type, str]]:
    """(section, its class, field) of every number or tuple-of-numbers field."""
    out = []
    for f in dataclasses.fields(SimConfig):
        cls = typing.get_type_hints(SimConfig)[f.name]
        for g in dataclasses.fields(cls):
            if not isinstance(getattr(cls(), g.name), (bool, str)):
                out.append((f.name, cls, g.name))
    return out


@pytest.mark.parametrize(("section", "cls", "name"), _numeric_fields(), ids=lambda v: str(v))
def test_python_constructors_refuse_non_finite_values(section: str, cls: type, name: str) -> None:
    """``SimConfig`` sections built in Python (no YAML loader) check every value too."""
    default = getattr(cls(), name)
    bad = tuple(math.nan for _ in default) if isinstance(default, tuple) else math.nan
    with pytest.raises(ValueError, match=name):
        cls(**{name: bad})
    if not isinstance(default, tuple):
        with pytest.raises(ValueError, match=name):
            cls(**{name: 1e12})


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("target", ["file", "nonempty", "below-file"])
def test_bad_output_paths_exit_1_and_keep_what_is_there(
    command: str, target: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "file").write_text("keep")
    (tmp_path / "nonempty").mkdir()
    (tmp_path / "nonempty" / "x").write_text("keep")
    out = {"file": "file", "nonempty": "nonempty", "below-file": "file/sub"}[target]
    before = sorted(str(p) for p in tmp_path.rglob("*"))
    rc, err = run_cli([*COMMANDS[command], "--out", str(tmp_path / out)], capsys)
    assert_one_line_exit(err, rc, str(tmp_path / out.split("/")[0]))
    assert sorted(str(p) for p in tmp_path.rglob("*")) == before
    assert (tmp_path / "file").read_text() == "keep"


@pytest.mark.parametrize("seed", [-1, 2**32, 10**30, True, 2.0, "3"])
def test_library_functions_refuse_bad_seeds(seed: object, tmp_path: Path) -> None:
    cfg = SimConfig()
    with pytest.raises(InputError, match="seed"):
        simulate_session(cfg, seed, tmp_path / "s")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="seed"):
        simulate_dataset(cfg, 1, seed, tmp_path / "d")  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("n", [0, -3, 10**7, 1.0, True])
def test_library_dataset_refuses_bad_counts(n: object, tmp_path: Path) -> None:
    with pytest.raises(InputError, match="--n"):
        simulate_dataset(SimConfig(), n, 0, tmp_path / "d")  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []


def test_valid_tiny_inputs_still_pass(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fast = ["camera.fps=2", "output.preview_frames=1"]
    rc, err = run_cli(["simulate", "--config", TINY, "--out", str(tmp_path / "s"), *fast], capsys)
    assert rc == 0 and "Traceback" not in err
    assert (tmp_path / "s" / "session.yaml").is_file()
    argv = ["simulate-dataset", "--config", TINY, "--n", "2", "--out", str(tmp_path / "d"),
            "--pitch-min", "40", "--pitch-max", "50", "mount.offset_m=[0.2, 0.05, 0]"]  # fmt: skip
    rc, err = run_cli(argv, capsys)
    assert rc == 0 and "Traceback" not in err
    assert len(list((tmp_path / "d" / "images").glob("*.png"))) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d", "s"]  # no staging leftovers
