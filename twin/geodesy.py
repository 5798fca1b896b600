"""Flat-earth local NED around a reference point, with WGS-84 radii of curvature.

Over the few kilometres of an ASV run the tangent-plane approximation is
accurate to millimetres: x_N = (φ − φ0)·(R_M + h), y_E = (λ − λ0)·(R_N + h)·cos φ0.
"""
from __future__ import annotations

import numpy as np

WGS84_A_M = 6378137.0
WGS84_E2 = 6.69437999014e-3


def radii_m(lat0_deg: float) -> tuple[float, float]:
    """Meridian (R_M) and prime-vertical (R_N) radii of curvature at lat0 (m)."""
    s2 = np.sin(np.deg2rad(lat0_deg)) ** 2
    r_n = WGS84_A_M / np.sqrt(1 - WGS84_E2 * s2)
    r_m = r_n * (1 - WGS84_E2) / (1 - WGS84_E2 * s2)
    return float(r_m), float(r_n)


def ned_from_geodetic(lat_deg, lon_deg, lat0_deg: float, lon0_deg: float, h0_m: float = 0.0):
    """(north, east) in m of points relative to (lat0, lon0)."""
    r_m, r_n = radii_m(lat0_deg)
    north = np.deg2rad(np.asarray(lat_deg) - lat0_deg) * (r_m + h0_m)
    dlon = (np.asarray(lon_deg, float) - lon0_deg + 180.0) % 360.0 - 180.0  # across the antimeridian
    east = np.deg2rad(dlon) * (r_n + h0_m) * np.cos(np.deg2rad(lat0_deg))
    return north, east


def geodetic_from_ned(north_m, east_m, lat0_deg: float, lon0_deg: float, h0_m: float = 0.0):
    """Inverse of `ned_from_geodetic`: (lat, lon) in degrees."""
    r_m, r_n = radii_m(lat0_deg)
    lat = lat0_deg + np.rad2deg(np.asarray(north_m) / (r_m + h0_m))
    lon = lon0_deg + np.rad2deg(np.asarray(east_m) / ((r_n + h0_m) * np.cos(np.deg2rad(lat0_deg))))
    return lat, lon
