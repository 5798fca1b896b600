"""One exception type for bad input: the CLI prints it on one line and exits 2."""


class TwinError(Exception):
    """A user-facing error: bad input, unknown name, inconsistent parameters."""


class TooShort(TwinError):
    """A recording too short for the job: not a fault of the log or the tool (a batch lists it and goes on)."""
