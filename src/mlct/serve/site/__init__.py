"""The static web site of `mlct export-web`: the model run in the browser (export.py), the npm
files it vendors (vendor.py), its page and modules (static/). The names below load export.py
(which writes graphs with torch) on first use, so that `mlct serve`, which takes only the
vendored three.js files, runs without torch."""

from __future__ import annotations

from typing import Any

__all__ = ["export_site", "load_site_reference", "site_size"]


def __getattr__(name: str) -> Any:
    if name not in __all__:
        raise AttributeError(f"module 'mlct.serve.site' has no attribute {name!r}")
    from mlct.serve.site import export

    return getattr(export, name)
