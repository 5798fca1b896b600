"""A MuJoCo digital twin of small twin-thruster autonomous surface vessels."""
__version__ = "0.1.0"

from .api import (InputSeries, Run, Validation, Vessel, compile_vessel, crosscheck,  # noqa: F401
                  effective_parameters, load_vessel, save_vessel, simulate, validate)
