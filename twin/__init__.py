"""A MuJoCo digital twin of small twin-thruster autonomous surface vessels (see twin.api)."""
__version__ = "0.2.0"

from .api import (Evaluation, InputSeries, Run, Simulation, Validation, Vessel, calibrate,  # noqa: F401
                  compile_vessel, crosscheck, diagnose, effective_parameters, evaluate, identify, load_vessel,
                  judge, prepare, read_recording, save_vessel, simulate, simulate_run, validate)
