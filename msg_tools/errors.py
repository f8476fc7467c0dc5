"""Errors of the msg_tools apps: an input that cannot be replayed, an output not written."""


class ReplayError(ValueError):
    """The input cannot be replayed at all (no such file, no usable wrench topic)."""


class OutputError(ReplayError):
    """An output file cannot be written (found before reading, or a write error)."""
