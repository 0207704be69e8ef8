"""The config surface survives broken input: files, ``_base_`` and ``key=value`` overrides.

Every broken config or override must raise :class:`ConfigError` (nothing else) with one line
naming the file or override and the key; valid configs still load. The inputs are generated
here, from hand-picked cases and from seeded random mutations of the shipped configs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from oneline import assert_one_line_message

from gaitnet.config import MAX_ALIASES, MAX_DEPTH, MAX_FILE_BYTES, load_config
from gaitnet.errors import ConfigError
from gaitnet.sim.config import SimConfig
from gaitnet.training.predictor import PredictorTrainingConfig

ROOT = Path(__file__).parents[1]
SIM_CONFIGS = sorted((ROOT / "configs" / "sim").glob("*.yaml"))
PREDICTOR_CONFIGS = sorted((ROOT / "configs" / "predictor").glob("*.yaml"))

BILLION_LAUGHS = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{n}: &{n} [{', '.join(['*' + p] * 9)}]\n" for p, n in zip("abcdefgh", "bcdefghi", strict=True)
)


# (file name, file bytes, substrings the one-line message must contain); {path} is the file.
BROKEN_FILES: list[tuple[str, bytes, list[str]]] = [
    ("latin1", b"gait:\n  speed_mps: 1.2\n# caf\xe9\n", ["{path}", "not UTF-8", "line 3"]),
    ("deep-list", b"x: " + b"[" * 5000 + b"]" * 5000 + b"\n", ["{path}", f"{MAX_DEPTH} levels"]),
    (
        "deep-map",
        b"".join(b"  " * i + b"a:\n" for i in range(60)) + b"  " * 60 + b"1\n",
        ["{path}", "nested deeper"],
    ),
    (
        "int-overflow",
        b"camera:\n  width: 99999999999999999999999\n",
        ["{path}", "'camera.width'", "64-bit"],
    ),
    (
        "int-overflow-list",
        b"mount:\n  offset_m: [0.1, 0, -99999999999999999999999]\n",
        ["{path}", "'mount.offset_m[2]'", "64-bit"],
    ),
    ("float-overflow", b"gait:\n  speed_mps: 1.0e400\n", ["{path}", "'gait.speed_mps'", "finite"]),
    ("nan", b"gait:\n  speed_mps: .nan\n", ["{path}", "'gait.speed_mps'", "finite"]),
    ("huge", b"# padding\n" * (MAX_FILE_BYTES // 10 + 1), ["{path}", "larger than"]),
    ("billion-laughs", BILLION_LAUGHS.encode(), ["{path}", "alias"]),
    (
        "many-aliases",
        b"a: &a 1\nb: [" + b", ".join([b"*a"] * (MAX_ALIASES + 1)) + b"]\n",
        ["{path}", f"more than {MAX_ALIASES} YAML aliases"],
    ),
    ("bad-yaml", b"gait: [speed\n", ["{path}", "not valid YAML"]),
    (
        "duplicate-key",
        b"gait:\n  speed_mps: 1.2\n  speed_mps: 1.4\n",
        ["{path}", "duplicate key 'speed_mps'"],
    ),
    ("top-level-list", b"- gait\n- camera\n", ["{path}", "top level must be a mapping"]),
    ("nul-byte", b"gait:\n  speed_mps: 1.2\x00\n", ["{path}", "not valid YAML"]),
    (
        "python-tag",
        b"gait: !!python/object/apply:os.system ['true']\n",
        ["{path}", "not valid YAML"],
    ),
    ("unknown-key", b"gait:\n  sped_mps: 1.2\n", ["{path}", "unknown key 'gait.sped_mps'"]),
    ("wrong-type", b"camera:\n  width: wide\n", ["{path}", "'camera.width' expects int"]),
    ("bool-for-int", b"camera:\n  width: yes\n", ["{path}", "'camera.width' expects int"]),
    ("section-scalar", b"gait: 5\n", ["{path}", "'gait' must be a mapping"]),
    ("out-of-range", b"mount:\n  pitch_deg: 5\n", ["{path}", "mount", "pitch_deg"]),
    ("base-not-string", b"_base_: 5\n", ["{path}", "'_base_' must be a file path"]),
    ("base-empty", b"_base_: ''\n", ["{path}", "'_base_' must be a file path"]),
    ("base-missing", b"_base_: nowhere.yaml\n", ["{path}", "nowhere.yaml", "not found"]),
    ("base-folder", b"_base_: sub\n", ["{path}", "is a folder"]),
    ("base-itself", b"_base_: base-itself.yaml\n", ["{path}", "names the file itself"]),
    ("base-cycle", b"_base_: cycle-b.yaml\n", ["cycle-b.yaml", "may not have its own '_base_'"]),
    ("base-broken", b"_base_: latin1.yaml\n", ["{path}", "latin1.yaml", "not UTF-8"]),
]


@pytest.fixture
def config_dir(tmp_path: Path) -> Path:
    for name, text, _ in BROKEN_FILES:
        (tmp_path / f"{name}.yaml").write_bytes(text)
    (tmp_path / "sub").mkdir()
    (tmp_path / "cycle-b.yaml").write_text("_base_: base-cycle.yaml\n")
    return tmp_path


@pytest.mark.parametrize(("name", "expected"), [(n, e) for n, _, e in BROKEN_FILES])
def test_broken_config_file_is_one_line_config_error(
    config_dir: Path, name: str, expected: list[str]
) -> None:
    path = config_dir / f"{name}.yaml"
    with pytest.raises(ConfigError) as excinfo:
        load_config(SimConfig, path)
    fragments = [part.format(path=path) for part in expected]
    assert_one_line_message(excinfo, *fragments, error_type=ConfigError)


def test_config_path_that_is_not_a_file(tmp_path: Path) -> None:
    cases = {
        tmp_path / "missing.yaml": "config file not found",
        tmp_path: "is a folder",
        tmp_path / "file.yaml" / "below.yaml": "cannot read",
        Path("/dev/null/x.yaml"): "cannot read",
    }
    (tmp_path / "file.yaml").write_text("gait: {}\n")
    for path, expected in cases.items():
        with pytest.raises(ConfigError) as excinfo:
            load_config(SimConfig, path)
        assert_one_line_message(excinfo, str(path), expected, error_type=ConfigError)


# (override, substrings of the one-line message)
BROKEN_OVERRIDES: list[tuple[str, list[str]]] = [
    ("=5", ["override '=5'", "empty key"]),
    ("a..b=1", ["override 'a..b=1'", "not a dotted key"]),
    (".a=1", ["override '.a=1'", "not a dotted key"]),
    ("gait.=1", ["override 'gait.=1'", "not a dotted key"]),
    ("mount.offset_m[0]=1", ["not a dotted key"]),
    ("gait.speed_mps", ["override 'gait.speed_mps'", "expected key=value"]),
    ("", ["override ''", "expected key=value"]),
    ("gait.speed_mps=1.2\udcff", ["override 'gait.speed_mps=1.2\\xff'", "not UTF-8"]),
    ("gait.speed_mps=[1", ["override 'gait.speed_mps=[1'", "not valid YAML"]),
    ("gait.speed_mps=.nan", ["'gait.speed_mps'", "finite"]),
    ("camera.width=99999999999999999999", ["'camera.width'", "64-bit"]),
    ("camera.width=" + "[" * 100 + "]" * 100, ["override 'camera.width=[[[", "levels"]),
    ("gait.speed_mps=*a", ["not valid YAML"]),
    ("gait.sped_mps=1", ["unknown key 'gait.sped_mps'", "did you mean 'gait.speed_mps'"]),
    ("gait=1", ["'gait' must be a mapping"]),
]


@pytest.mark.parametrize(("item", "expected"), BROKEN_OVERRIDES)
def test_broken_override_is_one_line_config_error(item: str, expected: list[str]) -> None:
    with pytest.raises(ConfigError) as excinfo:
        load_config(SimConfig, None, [item])
    assert_one_line_message(excinfo, *expected, error_type=ConfigError)


def test_override_below_a_scalar_names_the_section() -> None:
    with pytest.raises(ConfigError) as excinfo:
        load_config(SimConfig, None, ["gait.speed_mps=1", "gait.speed_mps.x=2"])
    assert_one_line_message(excinfo, "'gait.speed_mps' is not a section", error_type=ConfigError)


@pytest.mark.parametrize("path", SIM_CONFIGS, ids=lambda p: p.name)
def test_shipped_sim_configs_load(path: Path) -> None:
    assert isinstance(load_config(SimConfig, path), SimConfig)


@pytest.mark.parametrize("path", PREDICTOR_CONFIGS, ids=lambda p: p.name)
def test_shipped_predictor_configs_load(path: Path) -> None:
    assert isinstance(load_config(PredictorTrainingConfig, path), PredictorTrainingConfig)


def test_valid_yaml_features_still_load(tmp_path: Path) -> None:
    """Anchors, aliases, merge keys, a base file and overrides are fine within the limits."""
    (tmp_path / "base.yaml").write_text("camera: {width: 320, height: 240}\nsubject: {}\n")
    path = tmp_path / "child.yaml"
    path.write_text(
        "_base_: base.yaml\n"
        "subject: {height_m: 1.7, height_range_m: &r [1.6, 1.8]}\n"
        "scene: {exposure_range: *r}\n"
        "camera: {<<: {width: 160, height: 120}, fx: 193.0, fy: 193.0, cx: 79.5, cy: 59.5}\n"
    )
    cfg = load_config(SimConfig, path, ["gait.speed_mps=1.4", "mount.offset_m=[0.1, 0, 0.05]"])
    assert (cfg.camera.width, cfg.camera.height, cfg.camera.fx) == (160, 120, 193.0)
    assert cfg.subject.height_m == 1.7 and cfg.gait.speed_mps == 1.4
    assert cfg.mount.offset_m == (0.1, 0.0, 0.05)
    assert cfg.scene.exposure_range == cfg.subject.height_range_m == (1.6, 1.8)


def _mutate(text: bytes, rng: np.random.Generator) -> bytes:
    data = bytearray(text)
    for _ in range(int(rng.integers(1, 4))):
        kind = int(rng.integers(5))
        i = int(rng.integers(len(data)))
        if kind == 0:  # flip a byte
            data[i] = int(rng.integers(256))
        elif kind == 1:  # truncate
            del data[i:]
        elif kind == 2:  # insert YAML punctuation
            data[i:i] = bytes(rng.choice(list(b":-[]{}&*!|>'\"#%@`,? \n\t"), 3))
        elif kind == 3:  # duplicate a line
            start = data.rfind(b"\n", 0, i) + 1
            end = data.find(b"\n", i) + 1 or len(data)
            data[start:start] = data[start:end]
        else:  # replace a number with an extreme one
            extreme = [b"1e400", b"-0", b".inf", b"99999999999999999999", b"-1", b"0"]
            data[i:i] = extreme[int(rng.integers(len(extreme)))]
        if not data:
            data = bytearray(b"\n")
    return bytes(data)


@pytest.mark.parametrize("path", SIM_CONFIGS, ids=lambda p: p.name)
def test_random_mutations_load_or_raise_one_line_config_error(tmp_path: Path, path: Path) -> None:
    """Seeded random damage to a shipped config: it loads, or it is a one-line ConfigError
    naming the file (never another exception type)."""
    rng = np.random.default_rng(sum(path.name.encode()))
    original = path.read_bytes()
    outcomes = {"loaded": 0, "refused": 0}
    for i in range(150):
        broken = tmp_path / f"m{i}.yaml"
        broken.write_bytes(_mutate(original, rng))
        try:
            load_config(SimConfig, broken)
        except ConfigError as exc:
            assert_one_line_message(exc, str(broken), error_type=ConfigError)
            outcomes["refused"] += 1
        else:
            outcomes["loaded"] += 1
    assert outcomes["refused"] > 30, outcomes  # the mutations do break configs
