"""The bundled model's config read without pydantic (config_view.ConfigView) answers as the
validated Config does: every setting, of the same type; methods and settings newer than the
export from the validated tree; other models' configs validated as before."""

from __future__ import annotations

import copy
import pickle
import shutil

import pytest
from pydantic import BaseModel

from mlct.config import Config, config_from_dict
from mlct.config_view import ConfigView, model_config
from mlct.errors import MlctError
from mlct.generate.bundle import bundled_model_dir, read_config
from mlct.shipped import is_shipped_model


def _leaves(model: BaseModel, view: object, path: str = "") -> int:
    count = 0
    for name in type(model).model_fields:
        expected, got = getattr(model, name), getattr(view, name)
        if isinstance(expected, BaseModel):
            count += _leaves(expected, got, f"{path}{name}.")
            continue
        assert type(got) is type(expected) and got == expected, f"{path}{name}: {got!r}"
        count += 1
    return count


def test_the_bundled_config_validates_and_its_view_gives_every_setting() -> None:
    meta = read_config(bundled_model_dir())
    meta["model_dir"] = str(bundled_model_dir())
    config = config_from_dict(meta["config"], "model config")  # the shipped tree is valid
    view = model_config(meta)
    assert isinstance(view, ConfigView)
    assert _leaves(config, view) > 100
    assert view.to_dict() == config.to_dict()  # a method: the validated Config's
    assert view.ae.model_dump() == config.ae.model_dump()
    assert isinstance(view.validated(), Config)
    with pytest.raises(AttributeError, match="read-only"):
        view.schedule.latent_scale = 2.0
    with pytest.raises(AttributeError):
        view.no_such_setting  # noqa: B018
    for copied in (pickle.loads(pickle.dumps(view)), copy.deepcopy(view)):
        assert copied.schedule.latent_scale == config.schedule.latent_scale


def test_another_models_config_is_validated(tmp_path) -> None:
    folder = tmp_path / "model"
    folder.mkdir()
    shutil.copy(bundled_model_dir() / "config.json", folder / "config.json")
    meta = read_config(folder)
    meta["model_dir"] = str(folder)
    assert not is_shipped_model(folder) and is_shipped_model(bundled_model_dir())
    assert isinstance(model_config(meta), Config)
    meta["config"]["schedule"]["latent_scale"] = "much"  # damaged: said in one line
    with pytest.raises(MlctError, match="latent_scale"):
        model_config(meta)
