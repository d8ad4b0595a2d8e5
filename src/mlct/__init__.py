"""mlct: real-time text-to-motion generation with Motion Latent Consistency Training."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

if TYPE_CHECKING:
    from mlct.pipeline import MotionGenerator


def load(path: Any, device: Any = None) -> "MotionGenerator":
    """Load an inference bundle (`mlct export RUN --out DIR`): `mlct.load(DIR).generate(...)`."""
    from mlct.pipeline import load as _load  # lazy: `import mlct` stays light

    return _load(path, device)
