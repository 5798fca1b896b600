"""Environment: an earth-fixed water current acting through the relative
velocity ν_r = ν − ν_c [Fossen-2021 §10.3], and a simple wind load
([Fossen-2021 §10.1], the cosine/sine coefficient form). Both off by default.

Direction conventions, as in each field: the current's direction is where the
water flows *to* (oceanographic); the wind's is where it blows *from*
(meteorological). Both in degrees clockwise from north.

A sea the recording was made in moves the water too: `wave_drift_ned` holds its steady drift
at the hull (the Stokes drift of the waves [Stokes-1847], engine/sixdof.py `known_sea_drift`), a
known flow the hull moves through beside the current, so that a current fitted or diagnosed is the
one beyond the waves' own; `wave_load` holds the mean load the waves put on the hull by their
heading off the bow and the hull's speed (its added resistance and drift force), measured on the
vessel's own 6-DOF hull (engine/sixdof.py `mean_sea_load`).

The wind of one outing is not that of another: `wind_by_log` holds (log name, speed m/s, from
deg) triples that replace the constant wind for the recording of that name (a twin replaying
several logs sees each log's own wind; one without an entry sees the constant wind).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import TwinError
from .sensors import log_name

RHO_AIR_KG_M3 = 1.225
# beyond these no small vessel sails and no load form here holds: a tidal race runs under 10 m/s, a
# hurricane's sustained wind from 33 m/s
MAX_CURRENT_M_S = 10.0
MAX_WIND_M_S = 40.0


@dataclass(frozen=True)
class Environment:
    """The water and air the vessel moves in (module docstring): a current and a wind, each a speed
    (m/s, ≥ 0) and a direction (deg from north: where the current flows to, where the wind blows from);
    a wind per log (name, speed m/s, direction deg) that replaces the constant one on that log; a
    known sea's steady drift (m/s, NED) and mean load."""

    current_speed_m_s: float = 0.0
    current_dir_deg: float = 0.0
    wind_speed_m_s: float = 0.0
    wind_dir_deg: float = 0.0
    wind_by_log: tuple[tuple[str, float, float], ...] = ()
    wave_drift_ned: tuple[float, float] = (0.0, 0.0)  # m/s, a known sea's steady drift (module docstring)
    wave_load: tuple[float, ...] = ()  # a known sea's mean load (physics.seakeeping.pack_known_load)

    def __post_init__(self) -> None:
        # the direction carries the sense: a negative speed would be a flow the other way, said twice
        for name in ("current_speed_m_s", "wind_speed_m_s", "current_dir_deg", "wind_dir_deg"):
            value = getattr(self, name)
            if not math.isfinite(value) or (name.endswith("speed_m_s") and value < 0):
                raise TwinError(f"environment: {name} must be a finite number{' ≥ 0' if 'speed' in name else ''}, "
                                f"got {value!r}")
        for name, most in (("current_speed_m_s", MAX_CURRENT_M_S), ("wind_speed_m_s", MAX_WIND_M_S)):
            if getattr(self, name) > most:
                raise TwinError(f"environment: {name} must be at most {most:g} m/s, got {getattr(self, name)!r}")

    def for_log(self, source: str) -> "Environment":
        """The environment of the recording from `source` (a path or name): its own wind, if
        `wind_by_log` names it, as the constant wind."""
        own = {name: (speed, frm) for name, speed, frm in self.wind_by_log}.get(log_name(source))
        if own is None:
            return replace(self, wind_by_log=())
        return replace(self, wind_speed_m_s=own[0], wind_dir_deg=own[1], wind_by_log=())

    @property
    def current_ned(self) -> np.ndarray:
        a = np.deg2rad(self.current_dir_deg)
        return self.current_speed_m_s * np.array([np.cos(a), np.sin(a)])

    @property
    def flow_ned(self) -> np.ndarray:
        """The water's steady velocity the hull moves through (NED, m/s): current and wave drift."""
        return self.current_ned + np.asarray(self.wave_drift_ned, float)

    @property
    def has_flow(self) -> bool:
        return self.current_speed_m_s != 0.0 or any(x != 0.0 for x in self.wave_drift_ned)

    @property
    def wind_ned(self) -> np.ndarray:
        """Wind velocity (where the air goes) in NED, m/s."""
        a = np.deg2rad(self.wind_dir_deg)
        return -self.wind_speed_m_s * np.array([np.cos(a), np.sin(a)])


@dataclass(frozen=True)
class WindLoad:
    """Projected areas (m²), length (m) and load coefficients of the superstructure."""

    frontal_area_m2: float = 0.0
    lateral_area_m2: float = 0.0
    length_m: float = 0.0
    cx: float = 0.0
    cy: float = 0.0
    cn: float = 0.0


def current_body(psi_rad: float, current_ned: np.ndarray) -> np.ndarray:
    """ν_c = [u_c, v_c, 0]: the current seen in the body frame."""
    c, s = np.cos(psi_rad), np.sin(psi_rad)
    return np.array([c * current_ned[0] + s * current_ned[1], -s * current_ned[0] + c * current_ned[1], 0.0])


def current_body_rate(nu_c: np.ndarray, r: float) -> np.ndarray:
    """ν̇_c for an earth-fixed, irrotational current: [r·v_c, −r·u_c, 0]."""
    return np.array([r * nu_c[1], -r * nu_c[0], 0.0])


def wind_force(load: WindLoad, psi_rad: float, nu: np.ndarray, wind_ned: np.ndarray) -> np.ndarray:
    """τ_wind = ½ρ_a V_rw² [−c_x cos γ A_F, c_y sin γ A_L, c_n sin 2γ A_L L].

    γ = −atan2(v_rw, u_rw) is the angle of the relative wind seen from the bow
    (0 = head wind), with the relative wind u_rw = u − u_w, v_rw = v − v_w.
    """
    c, s = np.cos(psi_rad), np.sin(psi_rad)
    u_w = c * wind_ned[0] + s * wind_ned[1]
    v_w = -s * wind_ned[0] + c * wind_ned[1]
    u_rw, v_rw = nu[0] - u_w, nu[1] - v_w
    q = 0.5 * RHO_AIR_KG_M3 * (u_rw * u_rw + v_rw * v_rw)
    gamma = -np.arctan2(v_rw, u_rw)
    return q * np.array(
        [
            -load.cx * np.cos(gamma) * load.frontal_area_m2,
            load.cy * np.sin(gamma) * load.lateral_area_m2,
            load.cn * np.sin(2.0 * gamma) * load.lateral_area_m2 * load.length_m,
        ]
    )
