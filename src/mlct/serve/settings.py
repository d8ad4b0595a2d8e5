"""The server's limits and batching knobs: every bound a request can hit, in one place."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from mlct.errors import MlctError
from mlct.generate.compose.prompts import MAX_PROMPT_CHARS


@dataclass(frozen=True)
class ServeSettings:
    """Limits of `mlct serve`. A request past any of them gets a 4xx (or 503) with one line."""

    max_text_chars: int = 300  # a sentence or two (HumanML3D's longest caption); <= 500
    max_texts: int = 32  # texts in one request; at most max_batch
    max_frames: int | None = None  # None: the model's maximum (196 frames = 9.8 s at 20 fps)
    max_nfe: int = 50  # sampling steps; the consistency grid has 50, the page offers 1-10
    max_body_bytes: int = 64 * 1024  # larger bodies get 413 before they are parsed
    queue_depth: int = 64  # requests waiting for the model; one more gets 503
    max_batch: int = 32  # texts the model runs at once (one forward pass per step)
    batch_wait_ms: float = 2.0  # how long the worker waits for more requests to join a batch
    warmup: bool = True  # generate once at start: the text encoder loads before any request
    # POST /generate then needs "Authorization: Bearer <token>" (mlct serve --token / MLCT_TOKEN)
    token: str | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        for name in ("max_text_chars", "max_texts", "max_nfe", "max_body_bytes", "queue_depth",
                     "max_batch"):
            if getattr(self, name) < 1:
                raise MlctError(f"serve setting {name} must be at least 1, "
                                f"got {getattr(self, name)}")
        if self.max_text_chars > MAX_PROMPT_CHARS:
            raise MlctError(f"serve setting max_text_chars ({self.max_text_chars}) exceeds the "
                            f"prompt limit of {MAX_PROMPT_CHARS} (mlct.generate.compose.prompts)")
        if self.max_frames is not None and self.max_frames < 1:
            raise MlctError(f"serve setting max_frames must be at least 1, got {self.max_frames}")
        if not 0 <= self.batch_wait_ms <= 1000:
            raise MlctError(f"serve setting batch_wait_ms must be within 0..1000 ms, "
                            f"got {self.batch_wait_ms}")
        if self.token is not None and len(self.token) < 8:
            raise MlctError("serve token must be at least 8 characters")
        if self.max_texts > self.max_batch:
            raise MlctError(f"serve setting max_texts ({self.max_texts}) exceeds max_batch "
                            f"({self.max_batch}): one request must fit in one batch")

    def frame_limit(self, model_max_frames: int) -> int:
        """The longest motion served: this setting, capped by what the model was trained on."""
        if self.max_frames is None:
            return model_max_frames
        return min(self.max_frames, model_max_frames)

    def as_dict(self) -> dict[str, Any]:
        """The settings, the token left out (it is a secret; whether one is set is shown)."""
        out = asdict(self)
        out["token"] = self.token is not None
        return out
