"""How long work tells what it is doing: a package function that can run for more than a
few seconds takes a `progress` callable and calls it with what it is doing now, and, where
it knows, how far it is (done of total). The command line shows it as a progress bar on a
terminal; a library caller passes its own or nothing."""
from __future__ import annotations

from typing import Callable, Optional

Progress = Callable[[str, Optional[int], Optional[int]], None]


def silent(what: str, done: int | None = None, total: int | None = None) -> None:
    """The default: say nothing."""


def steps(progress: Progress | None) -> Progress:
    """`progress`, or `silent` when None."""
    return progress or silent
