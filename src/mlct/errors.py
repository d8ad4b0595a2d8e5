"""The error users see: one line that names the problem (the CLI prints it and exits 2)."""


class MlctError(Exception):
    """A problem with the user's input or files, explained in one line."""
