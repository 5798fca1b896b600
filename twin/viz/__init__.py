"""Visualisation exports: MCAP for Foxglove, .rrd recordings for the rerun viewer."""
from .mcap_io import read_run_mcap, write_run_mcap
from .rerun_log import write_runs_rrd

__all__ = ["read_run_mcap", "write_run_mcap", "write_runs_rrd"]
