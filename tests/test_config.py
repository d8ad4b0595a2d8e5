"""Typed configs: presets, overrides, one-line errors on unknown keys and wrong types."""

from __future__ import annotations

import pytest

from mlct.config import PRESETS, Config, config_from_dict, load_config
from mlct.errors import MlctError


@pytest.mark.parametrize("name", PRESETS)
def test_presets_load_and_validate(name: str) -> None:
    config = load_config(name)
    assert config.preset == name
    assert config.ae.layers % 2 == 1 and config.denoiser.layers % 2 == 1


def test_paper_preset_has_paper_sizes() -> None:
    hml, kit = load_config("humanml3d"), load_config("kit")
    assert (hml.ae.layers, hml.ae.latent_dim, hml.ae.n_tokens, hml.ae.levels) == (7, 256, 3, 1000)
    assert (hml.denoiser.layers, hml.denoiser.width) == (11, 512)
    assert (hml.schedule.beta_min, hml.schedule.beta_max) == (0.1, 20.0)  # authors' code
    assert (hml.consistency.guidance, kit.consistency.guidance) == (1.0, 2.0)
    assert hml.consistency.target_decay == 0.995 and hml.consistency.huber_c == 0.001
    assert hml.train.cm.grad_clip == 10.0 and hml.train.cm.lr == 1e-4


def test_overrides_parse_as_yaml_values() -> None:
    config = load_config("tiny", ["train.cm.max_steps=7", "consistency.guidance=2",
                                  "schedule.beta_min=0.002", "consistency.target=online"])
    assert config.train.cm.max_steps == 7 and isinstance(config.train.cm.max_steps, int)
    assert config.consistency.guidance == 2.0
    assert config.schedule.beta_min == 0.002
    assert config.consistency.target == "online"


@pytest.mark.parametrize("override, message", [
    ("ae.latnt_dim=3", "unknown config key 'ae.latnt_dim'"),
    ("ae.layers=abc", "bad value for 'ae.layers'"),
    ("ae.latent_type=fsq", "bad value for 'ae.latent_type'"),
    ("consistency.target_decay=1.5", "bad value for 'consistency.target_decay'"),
    ("nokey", "not of the form key=value"),
    ("ae.layers.x=1", "'layers' is a value, not a section"),
])
def test_bad_overrides_are_one_line_errors(override: str, message: str) -> None:
    with pytest.raises(MlctError, match=message) as info:
        load_config("tiny", [override])
    assert "\n" not in str(info.value)


def test_yaml_file_with_base_preset(tmp_path) -> None:
    path = tmp_path / "mine.yaml"
    path.write_text("base: small\nconsistency: {guidance: 3.5}\n")
    config = load_config(path)
    assert config.consistency.guidance == 3.5
    assert config.ae.latent_dim == load_config("small").ae.latent_dim


def test_bad_files(tmp_path) -> None:
    with pytest.raises(MlctError, match="neither a preset"):
        load_config(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("ae: [unclosed\n")
    with pytest.raises(MlctError, match="not valid YAML"):
        load_config(bad)


def test_round_trip_through_dict() -> None:
    config = load_config("small", ["consistency.guidance=1.5"])
    assert config_from_dict(config.to_dict()) == config
    assert Config().to_dict() == config_from_dict({}).to_dict()
