"""A MuJoCo digital twin of small surface vessels: simulate, identify from logs, evaluate,
diagnose what a twin lacks (see twin.api; the `twin` command does the same from a shell).

The public names below load twin.api on first use (PEP 562): a `twin info` or `twin --help` then
starts without the fitting, diagnosis and engine libraries (scipy.optimize, numba, mujoco), which
cost each command about a second of CPU before it reads its first argument."""
__version__ = "0.2.0"

__all__ = ["Diagnosis", "Effect", "Evaluation", "Identification", "InputSeries", "Judgement", "ManoeuvreBands", "Manoeuvres", "Parameter", "Run", "Score",
           "Simulation", "Table", "TwinError", "Validation", "Vessel", "calibrate", "compile_vessel", "crosscheck",
           "diagnose_recordings", "effective_parameters", "evaluate", "identify", "judge", "load_vessel", "manoeuvre_bands", "manoeuvres",
           "prepare_recording", "read_recording", "save_vessel", "simulate", "simulate_run", "validate"]


def __getattr__(name: str):
    if name in __all__:
        from . import api  # late (PEP 562): `import twin` takes 0.03 s, not the 1.2 s of twin.api
        return getattr(api, name)
    raise AttributeError(f"module 'twin' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
