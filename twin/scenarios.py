"""TEMPORARY shim while helpers finish: use twin.drive."""
from .drive import SCENARIOS, Controller, ZigZag, get, random_rc, spin, step, to_thruster_inputs, turn  # noqa: F401
