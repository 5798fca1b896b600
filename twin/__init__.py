"""A MuJoCo digital twin of small twin-thruster autonomous surface vessels."""
__version__ = "0.1.0"

from .api import (InputSeries, Run, Vessel, compile_vessel, crosscheck, effective_parameters, load_vessel,  # noqa: F401
                  save_vessel, simulate)
