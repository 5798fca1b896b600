"""One exception type for bad input: the CLI prints it on one line and exits 2."""


class TwinError(Exception):
    """A user-facing error: bad input, unknown name, inconsistent parameters."""
