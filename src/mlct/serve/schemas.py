"""The POST /generate request, checked before it is queued: pydantic models built from limits.

The model is built per app (`request_model`) so that its bounds are the server's settings and
the OpenAPI page shows them. A scalar `lengths`, `seconds` or `seed` stands for every text.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Annotated, Any, Literal

from pydantic import (AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field,
                      PlainValidator, ValidationError, model_validator)

from mlct.errors import MlctError
from mlct.generate.compose.critic import MAX_CANDIDATES
from mlct.generate.compose.prompts import clean_prompt

Format = Literal["json", "npy", "bvh", "gif", "glb", "fbx", "vrma", "npz"]
RigName = Literal["mixamo", "unreal", "unity", "vrm", "smpl"]  # motion/rigs.py's presets
MAX_SEED = 2**53 - 1  # the largest integer a browser's JSON keeps exactly


@dataclass(frozen=True)
class Limits:
    """What a request may ask for: settings resolved against the loaded model."""

    max_text_chars: int
    max_texts: int
    max_frames: int
    max_nfe: int
    fps: float

    @property
    def max_seconds(self) -> float:
        return self.max_frames / self.fps


def check_text(text: str, max_chars: int) -> str:
    """The prompt as the pipeline reads it (mlct.generate.compose.prompts.clean_prompt: whitespace collapsed; no
    control characters), within the server's length limit; ValueError naming the problem."""
    collapsed = " ".join(text.split())
    if len(collapsed) > max_chars:
        raise ValueError(f"the prompt has {len(collapsed)} characters; the limit is {max_chars}")
    try:
        return clean_prompt(text)
    except MlctError as error:
        raise ValueError(str(error)) from None


def _as_list(value: Any) -> Any:
    """A scalar stands for a one-item list (then for every text)."""
    return value if value is None or isinstance(value, list) else [value]


def request_model(limits: Limits) -> type[BaseModel]:
    """The pydantic model of POST /generate's body under these limits."""
    Text = Annotated[str, Field(strict=True),
                     AfterValidator(lambda text: check_text(text, limits.max_text_chars))]
    Frames = Annotated[int, Field(strict=True, ge=1, le=limits.max_frames)]
    # strict: a number (an int is one), not "3" or true (which lax parsing read as 1 s)
    def seconds_item(value: Any) -> float | str:
        # a number (not "3" or true, which lax parsing read as 1 s), or "auto": from the text
        if value == "auto":
            return "auto"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"should be a number of seconds or 'auto', got {value!r}")
        if not math.isfinite(value):
            raise ValueError(f"should be a finite number of seconds, got {value}")
        if not 0 < value <= round(limits.max_seconds, 6):
            raise ValueError(f"should be more than 0 and at most "
                             f"{round(limits.max_seconds, 6):g} seconds, got {value}")
        return float(value)

    Seconds = Annotated[Any, PlainValidator(seconds_item)]
    Seed = Annotated[int, Field(strict=True, ge=0, le=MAX_SEED)]

    class GenerateRequest(BaseModel):
        """Texts to motions. Give `texts` (a list) or `text` (one); `lengths` (frames) or
        `seconds`, one per text or one for all (default 5 s, or what the prompt says: "... for
        3 seconds"; "auto": from the text);
        `candidates`: motions sampled per text, one the model's critic rates among the best
        kept (its margin; default: the model's); `seed`: an int s seeds text i with s + i (omitted: random,
        returned in the reply); `format`: json for every text, npy/bvh/gif/glb/fbx/vrma/npz
        for one text as a file download; `rig`: a retarget preset for bvh, glb and fbx
        (docs/export.md); `in_place`: the pelvis kept over its start, no travel over the
        ground (an engine's root-motion clip)."""

        model_config = ConfigDict(extra="forbid")

        texts: list[Text] | None = Field(None, min_length=1, max_length=limits.max_texts)
        text: Text | None = None
        lengths: Annotated[list[Frames] | None, BeforeValidator(_as_list)] = Field(
            None, min_length=1, max_length=limits.max_texts)
        seconds: Annotated[list[Seconds] | None, BeforeValidator(_as_list)] = Field(
            None, min_length=1, max_length=limits.max_texts)
        nfe: int | None = Field(None, strict=True, ge=1, le=limits.max_nfe)
        # best of N by the model's critic (generate/compose/critic.py); omitted: the model's default
        candidates: int | None = Field(None, strict=True, ge=1, le=MAX_CANDIDATES)
        seed: Annotated[list[Seed] | None, BeforeValidator(_as_list)] = Field(
            None, min_length=1, max_length=limits.max_texts)
        format: Format = "json"
        # path, keyframes, edit + parts, prefix, start/end pose (mlct.generate.control.schema); one text
        control: dict[str, Any] | None = None
        rig: RigName | None = None
        # the pelvis kept over its start (GeneratedMotion.in_place): an engine's root motion
        in_place: bool = Field(False, strict=True)

        @model_validator(mode="after")
        def _consistent(self) -> GenerateRequest:
            if self.texts is None and self.text is None:
                raise ValueError("no prompt: give 'text' (one string) or 'texts' (a list)")
            if self.texts is not None and self.text is not None:
                raise ValueError("give 'texts' (a list) or 'text' (one string), not both")
            if self.lengths is not None and self.seconds is not None:
                raise ValueError("give 'lengths' (frames) or 'seconds', not both")
            count = len(self.prompts)
            for name in ("lengths", "seconds", "seed"):
                given = getattr(self, name)
                if given is not None and len(given) not in (1, count):
                    raise ValueError(f"{len(given)} values of '{name}' for {count} texts: "
                                     "give one, or one per text")
            if self.control is not None and count != 1:
                raise ValueError(f"a control goes with one text, got {count}")
            if self.control is not None and "auto" in (self.seconds or []):
                raise ValueError("seconds 'auto' does not go with a control; give the seconds")
            if self.rig is not None:
                from mlct.generate.output.exports import check_rig

                try:
                    check_rig(self.rig, f".{self.format}")
                except MlctError as error:
                    raise ValueError(str(error).replace("--rig", "rig")) from None
            if self.format != "json" and count != 1:
                raise ValueError(f"format '{self.format}' is a file of one motion; "
                                 f"got {count} texts (use format 'json' for several)")
            for frames in self.frames(default=1):
                if frames is not None and frames < 1:
                    raise ValueError(f"seconds must be at least {0.5 / limits.fps:g} "
                                     f"(one frame at {limits.fps:g} fps)")
            return self

        @property
        def prompts(self) -> list[str]:
            return list(self.texts) if self.texts is not None else [self.text or ""]

        def frames(self, default: int) -> list[int | None]:
            """Frames per text: lengths, or seconds at the model's fps, or the default; None
            where the seconds are "auto" (the batcher asks the model, on its thread)."""
            count = len(self.prompts)
            if self.lengths is not None:
                values = list(self.lengths)
            elif self.seconds is not None:
                values = [None if s == "auto" else round(s * limits.fps)
                          for s in self.seconds]
            else:
                values = [default]
            return values * count if len(values) == 1 else values

        def seeds(self, draw: int) -> list[int]:
            """Seed per text: the given ones, s + i for one seed s, or `draw` + i when omitted."""
            count = len(self.prompts)
            if self.seed is not None and len(self.seed) == count:
                return list(self.seed)
            first = self.seed[0] if self.seed is not None else draw
            return [(first + i) % (MAX_SEED + 1) for i in range(count)]

    return GenerateRequest


_PREFIXES = re.compile(r"^(Value error|Assertion failed), ")


def one_line(error: ValidationError | list[dict[str, Any]]) -> str:
    """A pydantic error list as one line: where, what, and how many more."""
    errors = error.errors() if isinstance(error, ValidationError) else list(error)
    if not errors:
        return "invalid request"
    first = errors[0]
    where = ".".join(str(part) for part in first.get("loc", ()) if part != "body")
    where = re.sub(r"\.(\d+)", r"[\1]", where)
    message = _PREFIXES.sub("", str(first.get("msg", "invalid value")))
    if first.get("type") == "missing" and not where:
        message = "the request body is empty; send a JSON object such as {\"text\": \"...\"}"
    elif first.get("type") == "extra_forbidden":
        message = ("unknown field (expected texts or text, lengths or seconds, nfe, candidates, "
                   "seed, format, rig, in_place, control)")
    line = f"{where}: {message}" if where else message
    if len(errors) > 1:
        line += f" (and {len(errors) - 1} more)"
    return line.replace("\n", " ")
