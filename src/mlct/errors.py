"""The error users see: one line that names the problem (the CLI prints it and exits 2)."""


class MlctError(Exception):
    """A problem with the user's input or files, explained in one line."""


class MlctWarning(UserWarning):
    """A one-line notice that mlct did something other than asked, and why (the CLI prints it
    as "mlct: note: ..."); e.g. float32 where the CPU has no bfloat16 kernels."""


def first_line(error: BaseException, empty: str | None = None) -> str:
    """The first line of an exception's message, to quote inside a one-line MlctError; for an
    empty message, `empty` (by default the exception's type name)."""
    lines = str(error).strip().splitlines()
    if lines:
        return lines[0]
    return type(error).__name__ if empty is None else empty


TRAIN_EXTRA = "pip install 'mlct[train]'"  # torch and the training/evaluation libraries


class MissingExtra(MlctError):
    """A feature whose libraries a light install (`pip install mlct`) leaves out: one line
    naming the extra that brings them (the CLI prints it and exits 2, as any MlctError)."""


def require_torch(what: str) -> None:
    """Import PyTorch, or raise MissingExtra when it is not installed; `what` names the feature
    that needs it ("training", "the torch backend", ...). Called where torch is needed next."""
    try:
        import torch  # noqa: F401
    except ImportError:
        raise MissingExtra(f"{what} needs PyTorch, which this install lacks: {TRAIN_EXTRA}"
                           ) from None
