"""The filter's config: the shipped file is the defaults, bad keys and values are refused."""

from __future__ import annotations

from pathlib import Path

import pytest

from gaitnet.config import load_config
from gaitnet.errors import ConfigError
from gaitnet.io.types import ImuNoise
from gaitnet.vio.config import VioConfig

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "vio" / "default.yaml"


def test_the_shipped_default_file_is_the_built_in_default() -> None:
    assert load_config(VioConfig, DEFAULT) == VioConfig()


@pytest.mark.parametrize(
    "override, key",
    [
        ("filter.vo_gate_probability=1.5", "vo_gate_probability"),
        ("filter.foot_std_m=0", "foot_std_m"),
        ("filter.gravity_mps2=3", "gravity_mps2"),
        ("gait.max_stride_time_s=-1", "max_stride_time_s"),
        ("imu.scale=0", "scale"),
        ("filter.foot_std_m=1e308", "foot_std_m"),  # finite, but its square overflowed
        ("imu.scale=1e308", "scale"),
        ("filter.bogus=1", "filter.bogus"),
        ("filter.tag_recovery_frames=1", "tag_recovery_frames"),
        ("filter.tag_recovery_frames=-2", "tag_recovery_frames"),
    ],
)
def test_bad_values_are_one_line_config_errors(override: str, key: str) -> None:
    with pytest.raises(ConfigError, match=key) as info:
        load_config(VioConfig, DEFAULT, [override])
    assert "\n" not in str(info.value)


def test_imu_noise_comes_from_the_session_unless_told_otherwise(tiny_sim_session: Path) -> None:
    from gaitnet.io import open_session

    calib = open_session(tiny_sim_session).calibration
    assert calib.imu_noise is not None
    cfg = load_config(VioConfig, None, ["imu.scale=2"])
    assert cfg.imu_noise(calib).gyro_noise_density == pytest.approx(
        2 * calib.imu_noise.gyro_noise_density
    )
    own = load_config(VioConfig, None, ["imu.from_session=false", "imu.gyro_noise_density=0.001"])
    assert isinstance(own.imu_noise(calib), ImuNoise)
    assert own.imu_noise(calib).gyro_noise_density == pytest.approx(0.001)
