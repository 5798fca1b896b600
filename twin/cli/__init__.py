"""The `twin` command. app.py owns the typer app, errors and output checks; each other
module registers one group of commands on it and holds no domain logic (that lives in the
package, so the Python API does the same things)."""
from . import diagnose, ident, recordings, run, relay, scale, sitl  # noqa: F401  (each registers its commands)
from .app import flow_help, main

flow_help()

__all__ = ["main"]
