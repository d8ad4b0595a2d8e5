"""A validated config tree read as attributes without pydantic: the bundled model's load path.

Importing mlct.config's pydantic models (and yaml) takes ~0.1 s, a tenth of a cold start's
budget (docs/performance.md, "Cold start"). A bundle's config.json holds a whole validated tree
(Config.to_dict(), as `mlct export` writes it); where that tree is known to be valid (the model
shipped in the package, whose config the tests validate: tests/test_config_view.py),
model_config reads it through ConfigView instead. A section's values are
the tree's own; anything else (a method such as to_dict or model_dump, a key the tree lacks:
a setting newer than the export, at its default) comes from the tree validated by
mlct.config, made on first use, so a view answers as the Config does.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from mlct.shipped import is_shipped_model

if TYPE_CHECKING:
    from mlct.config import Config


class ConfigView:
    """Config.to_dict()'s tree (or a section of it) as read-only attributes; see above."""

    __slots__ = ("_tree", "_path", "_root", "_validated")

    def __init__(self, tree: dict[str, Any], path: tuple[str, ...] = (),
                 root: ConfigView | None = None) -> None:
        object.__setattr__(self, "_tree", tree)
        object.__setattr__(self, "_path", path)  # the section's keys from the root
        object.__setattr__(self, "_root", root)  # None: this is the root
        object.__setattr__(self, "_validated", None)  # the root's Config, once made

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):  # (copy and pickle ask for dunders before __init__ runs)
            raise AttributeError(name)
        tree = self._tree
        if name in tree:
            value = tree[name]
            if isinstance(value, dict):
                return ConfigView(value, (*self._path, name), self._root or self)
            return value
        section: Any = (self._root or self).validated()
        for key in self._path:
            section = getattr(section, key)
        return getattr(section, name)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"a model's config is read-only here; set "
                             f"{'.'.join((*self._path, name))} on config.validated()")

    def __reduce__(self) -> tuple[Any, ...]:  # (its __setattr__ refuses pickle's default way)
        return ConfigView, (self._tree, self._path, self._root)

    def __repr__(self) -> str:
        return f"ConfigView({'.'.join(self._path) or 'config'})"

    def validated(self) -> Config:
        """The whole tree validated into mlct.config's Config (made once, on first use)."""
        root = self._root or self
        if root._validated is None:
            from mlct.config import config_from_dict

            object.__setattr__(root, "_validated", config_from_dict(root._tree, "model config"))
        return root._validated


def model_config(meta: dict[str, Any]) -> Any:
    """The run config of a bundle read by generate/bundle.py (its config.json's "config", and
    "model_dir", where it was read from): for the model shipped in the package, read as it is
    (a ConfigView); for any other, validated into mlct.config's Config."""
    if is_shipped_model(meta.get("model_dir")):
        return ConfigView(meta["config"])
    from mlct.config import config_from_dict

    return config_from_dict(meta["config"], "model config")


def latent_clamp(config: Any) -> float | None:
    """Clamp bound of stage 2's latent: 1 for the quantized latent (tanh-bounded, Eq. 8) times
    schedule.latent_scale, none for the vae / plain ablations, whose latents are unbounded
    (a Config or a ConfigView)."""
    return config.schedule.latent_scale if config.ae.latent_type == "quantized" else None
