"""The hydrodynamic forces installed as MuJoCo's `mjcb_passive` callback.

This is the readable Python reference. Per call it: reads ψ and the world
velocity of CO, rotates to ν = [u, v, r]; asks the engine for the actuator
forces it is about to apply (`mj_fwdActuation`, because in MuJoCo's pipeline
actuation comes after the passive forces); computes the body-frame
hydrodynamic force of `physics.hydrodynamics.hydrodynamic_force` (added mass
with the exact acceleration, C_A, D, current, wind); rotates it back to the
generalised forces of the north/east/yaw joints and adds it to qfrc_passive.
A propeller-and-rudder ship's inputs (n, δ) are the controls 0 and 1 (its actuators exert no
force), and a model with wind inputs (mjcf.add_wind_inputs) has the air's NED velocity in its
controls 2 and 3 (in place of the environment's constant wind).

MuJoCo holds one global passive callback, so vessels register here by model
address and the installed function looks its vessel up. Being one per process, it is also one
for every thread: a block that installs a callback (this module's or the native one) holds
HOOK_LOCK from installing it to restoring the one before, so that another thread's block cannot
take it away (restore its own previous callback, or none) while this one steps. Without it, twins
simulated from two threads at once would now and then step without their hydrodynamics.
"""
from __future__ import annotations

import contextlib
import threading
from dataclasses import dataclass

import mujoco
import numpy as np

from ..physics.hydrodynamics import HydroModel, hydrodynamic_force
from .mjcf import JOINTS, THRUSTERS, wind_control


@dataclass(frozen=True)
class _Entry:
    hydro: HydroModel
    qpos: tuple[int, int, int]
    dof: tuple[int, int, int]
    wind_ctrl: int = -1  # index of the wind's first control, −1: the environment's constant wind
    thrusters: tuple[int, ...] = ()  # actuator ids of the left and right thrusters (none: a propeller-rudder ship)


_REGISTRY: dict[int, _Entry] = {}


def _joint_indices(model: mujoco.MjModel) -> tuple[tuple[int, int, int], tuple[int, int, int]]:
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in JOINTS]
    return tuple(int(model.jnt_qposadr[i]) for i in ids), tuple(int(model.jnt_dofadr[i]) for i in ids)


def body_velocity(psi_rad: float, qvel_world: np.ndarray) -> np.ndarray:
    """ν = [u, v, r] from the joint velocities [ẋ_N, ẏ_E, ψ̇]."""
    c, s = np.cos(psi_rad), np.sin(psi_rad)
    return np.array([c * qvel_world[0] + s * qvel_world[1], -s * qvel_world[0] + c * qvel_world[1], qvel_world[2]])


def passive_force(entry: _Entry, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """Generalised hydrodynamic force on (north, east, yaw) for the current state."""
    qx, qy, qpsi = entry.qpos
    dx, dy, dpsi = entry.dof
    psi = data.qpos[qpsi]
    c, s = np.cos(psi), np.sin(psi)
    nu = body_velocity(psi, data.qvel[[dx, dy, dpsi]])
    mujoco.mj_fwdActuation(model, data)
    fa = data.qfrc_actuator
    tau = np.array([c * fa[dx] + s * fa[dy], -s * fa[dx] + c * fa[dy], fa[dpsi]])
    controls = data.ctrl[:2] if entry.hydro.mmg is not None else None
    k = entry.wind_ctrl
    wind = data.ctrl[k:k + 2] if k >= 0 else None
    thrusts = data.actuator_force[list(entry.thrusters)] if entry.hydro.advance_loss and entry.thrusters else None
    X = hydrodynamic_force(entry.hydro, psi, nu, tau, controls, wind, thrusts)
    return np.array([c * X[0] - s * X[1], s * X[0] + c * X[1], X[2]])


def _passive(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    entry = _REGISTRY.get(model._address)
    if entry is None:
        return
    f = passive_force(entry, model, data)
    dx, dy, dpsi = entry.dof
    data.qfrc_passive[dx] += f[0]
    data.qfrc_passive[dy] += f[1]
    data.qfrc_passive[dpsi] += f[2]


def register(model: mujoco.MjModel, hydro: HydroModel) -> None:
    qpos, dof = _joint_indices(model)
    ids = tuple(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in THRUSTERS)
    _REGISTRY[model._address] = _Entry(hydro, qpos, dof, wind_control(model), ids if min(ids) >= 0 else ())


def unregister(model: mujoco.MjModel) -> None:
    _REGISTRY.pop(model._address, None)


# held from installing a passive callback to restoring the previous one (module docstring);
# reentrant, so a block nested in the same thread installs over the outer one and restores it
HOOK_LOCK = threading.RLock()


@contextlib.contextmanager
def installed(model: mujoco.MjModel, hydro: HydroModel):
    """Register the vessel and install the Python passive callback for the block (other threads'
    blocks wait: HOOK_LOCK)."""
    with HOOK_LOCK:
        previous = mujoco.get_mjcb_passive()
        register(model, hydro)
        mujoco.set_mjcb_passive(_passive)
        try:
            yield
        finally:
            unregister(model)
            if not _REGISTRY:
                mujoco.set_mjcb_passive(previous)
