"""Real recordings: read ArduPilot logs, CSV and MCAP into a Recording, prepare them
as in seed 004 §5.1 (synchronise, NED, lever arm, velocities, segments, regions),
and write a Recording (synthetic sensor logs, conversions) as .csv, .tlog, .bin or .mcap.

This package does not know the twin exists: it only produces data for the layers above.
"""
from .prepare import Prepared, Segment, geodetic_to_ned, prepare
from .readers import read_recording
from .recording import Recording, Stream, format_summary
from .writers import write_recording

__all__ = ["Prepared", "Recording", "Segment", "Stream", "format_summary", "geodetic_to_ned", "prepare",
           "read_recording", "write_recording"]
