"""TEMPORARY shim while helpers finish: use twin.drive."""
from .drive import PWM_COLUMNS, THRUST_COLUMNS, InputSeries, read_inputs_csv  # noqa: F401
