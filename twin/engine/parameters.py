"""The effective 3-DOF parameters of a vessel, as `twin params` prints them."""
from __future__ import annotations

from dataclasses import asdict

import numpy as np

from ..analytic import course_unstable_from_m_s, straight_run
from ..physics import mmg
from ..physics.thrusters import allocation_matrix, force_torque_bounds
from ..vessel import Vessel, environment_to_dict
from .mjcf import compile_vessel


def effective_parameters(vessel: Vessel) -> dict:
    """M, M_RB, M_A, damping ([Morel-2024 eq. 7] names, Fossen signs), thrusters, GNSS lever arm."""
    cv = compile_vessel(vessel)
    g, hydro = cv.geometry, cv.hydro()
    thrusters = asdict(vessel.thrusters)
    ship = vessel.thrusters.kind == "propeller_rudder"
    if ship:  # a propeller and a rudder: positions and input bounds, no thrust allocation
        thrusters["positions_m"] = {"propeller": g.thruster_pos_m[0].tolist(), "rudder": g.thruster_pos_m[1].tolist()}
        thrusters["input_bounds"] = {"n_rps": list(vessel.thrusters.channel_bounds()[0]),
                                     "rudder_rad": list(vessel.thrusters.channel_bounds()[1])}
    else:
        for key in ("rps_max", "rudder_max_deg"):  # a propeller and rudder's only
            thrusters.pop(key)
        thrusters["positions_m"] = {"left": g.thruster_pos_m[0].tolist(), "right": g.thruster_pos_m[1].tolist()}
        thrusters["allocation_B"] = allocation_matrix(g.thruster_y_m).tolist()
        thrusters["bounds_per_thruster_n"] = list(vessel.thrusters.bounds())
        thrusters.update(force_torque_bounds(vessel.thrusters, g.thruster_y_m))
    extra = {}
    if vessel.mmg is not None:
        extra["mmg"] = asdict(vessel.mmg)
        extra["mmg_packed"] = {k: x if np.isfinite(x) else None for k, x in zip(mmg.FIELDS, hydro.mmg.tolist())}
    if vessel.wind_regression is not None:
        extra["wind_regression"] = asdict(vessel.wind_regression)
    full_ahead = straight_run(cv, 1.0)
    if full_ahead is not None:
        extra["straight_run"] = {"throttle": 1.0, "speed_m_s": full_ahead.speed_m_s,
                                 "roots_per_s": [[r.real, r.imag] for r in full_ahead.roots_per_s],
                                 "stable": full_ahead.stable, "doubling_s": full_ahead.doubling_s,
                                 "course_unstable_from_m_s": course_unstable_from_m_s(cv)}
    return {
        "vessel": vessel.name,
        "case": vessel.case,
        "frames": "world NED (x north, y east, psi from north to east); body FRD, origin CO",
        "rigid_body": asdict(g.rigid),
        "M": hydro.M.tolist(),
        "M_RB": hydro.M_RB.tolist(),
        "M_A": hydro.M_A.tolist(),
        "added_mass": asdict(vessel.added_mass),
        "damping": asdict(vessel.damping),
        "thrusters": thrusters,
        "gnss_antenna_m": g.gnss_pos_m.tolist(),
        "gnss_lever_arm_OP_m": (-g.gnss_pos_m[:2]).tolist(),
        "imu_m": g.imu_pos_m.tolist(),
        "wind_load": asdict(vessel.wind_load),
        "environment": environment_to_dict(vessel.environment),
        **extra,
        "sources": vessel.sources,
    }
