"""Typed config: partial YAML overrides, errors that name the field, resolved config written."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from graph_slam.config import load_config, write_config
from graph_slam.errors import ConfigError
from graph_slam.session.synthetic import SyntheticConfig


def test_partial_yaml_overrides_defaults(tmp_path: Path) -> None:
    path = tmp_path / "cfg.yaml"
    path.write_text("camera_rate_hz: 90\nseed: 3\n")
    cfg = load_config(SyntheticConfig, path)
    assert cfg.camera_rate_hz == 90.0 and cfg.seed == 3
    assert cfg.imu_rate_hz == SyntheticConfig().imu_rate_hz


def test_unknown_key_and_bad_value_name_the_field(tmp_path: Path) -> None:
    path = tmp_path / "cfg.yaml"
    path.write_text("camera_rate_hz: -5\nmystery: 1\n")
    with pytest.raises(ConfigError) as info:
        load_config(SyntheticConfig, path)
    message = str(info.value)
    assert str(path) in message
    assert "field 'camera_rate_hz'" in message and "greater than 0" in message
    assert "field 'mystery'" in message


def test_not_yaml_and_not_a_mapping(tmp_path: Path) -> None:
    path = tmp_path / "cfg.yaml"
    path.write_text("a: [1, 2\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(SyntheticConfig, path)
    path.write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match="must be a mapping"):
        load_config(SyntheticConfig, path)


def test_yaml_tags_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "cfg.yaml"
    path.write_text("seed: !!python/object/apply:os.system ['echo pwned']\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(SyntheticConfig, path)


def test_resolved_config_round_trips(tmp_path: Path) -> None:
    cfg = SyntheticConfig(seed=11, speed_m_s=1.4)
    path = write_config(cfg, tmp_path / "run" / "config.yaml")
    assert yaml.safe_load(path.read_text())["duration_s"] == cfg.duration_s
    assert load_config(SyntheticConfig, path) == cfg
