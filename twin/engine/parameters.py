"""The effective 3-DOF parameters of a vessel, as `twin params` prints them."""
from __future__ import annotations

from dataclasses import asdict

from .mjcf import compile_vessel
from ..physics.thrusters import allocation_matrix, force_torque_bounds
from ..vessel import Vessel


def effective_parameters(vessel: Vessel) -> dict:
    """M, M_RB, M_A, damping (seed 004 eq. 7 names, Fossen signs), thrusters, GNSS lever arm."""
    cv = compile_vessel(vessel)
    g, hydro = cv.geometry, cv.hydro()
    thrusters = asdict(vessel.thrusters)
    thrusters["positions_m"] = {"left": g.thruster_pos_m[0].tolist(), "right": g.thruster_pos_m[1].tolist()}
    thrusters["allocation_B"] = allocation_matrix(g.thruster_y_m).tolist()
    thrusters["bounds_per_thruster_n"] = list(vessel.thrusters.bounds())
    thrusters.update(force_torque_bounds(vessel.thrusters, g.thruster_y_m))
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
        "environment": asdict(vessel.environment),
        "sources": vessel.sources,
    }
