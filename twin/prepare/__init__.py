"""A recording made ready for fitting [Morel-2024 §5.1]: streams synchronised on one grid,
GNSS in local NED, the lever arm applied, body velocities, segments without dropouts,
operating regions; and the model-based smoother, and what `twin convert` writes; and how late a
log's heading is against its gyro (timing.py)."""
from ..geodesy import ned_from_geodetic as geodetic_to_ned
from .prepared import DEADBAND_US, Preparation, Prepared, Segment, hold, prepare, supply_reference, wind_series
from .timing import GyroLag, heading_lag_behind_gyro

__all__ = ["DEADBAND_US", "GyroLag", "Preparation", "Prepared", "Segment", "geodetic_to_ned", "heading_lag_behind_gyro",
           "hold", "prepare", "supply_reference", "wind_series"]
