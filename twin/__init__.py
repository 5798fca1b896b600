"""A MuJoCo digital twin of small surface vessels: simulate, identify from logs, evaluate,
diagnose what a twin lacks (see twin.api; the `twin` command does the same from a shell)."""
__version__ = "0.2.0"

from .api import (Diagnosis, Effect, Evaluation, InputSeries, Judgement, Parameter, Run, Score,  # noqa: F401
                  Simulation, Table, TwinError, Validation, Vessel, calibrate, compile_vessel, crosscheck,
                  diagnose_recordings, effective_parameters, evaluate, identify, judge, load_vessel,
                  prepare_recording, read_recording, save_vessel, simulate, simulate_run, validate)
