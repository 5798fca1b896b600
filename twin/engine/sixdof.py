"""The 6-DOF hull: the vessel's MJCF with heave, roll and pitch freed, floating on its own meshes.

The planar joints stay (north, east, yaw) and three more join them in the vessel body, so that the
body frame is R = Rz(ψ) Ry(θ) Rx(φ) [Fossen-2021] (zyx Euler angles) and the 3-DOF code finds η = (x, y,
ψ) where it always did: north, east (slides), down (slide, z), yaw (hinge about z), pitch (hinge
about the yawed y) and roll (hinge about the body x). The horizontal model is the 3-DOF twin's:
its callback computes surge, sway and yaw forces from (u, v, r) in the heading frame and applies
them to the north, east and yaw joints; in waves it sees the hull's velocity relative to the
water's orbital velocity and accelerates its added mass with the sea's load (docs/method/sea-state.md). Two things a trimmed or heeled hull
would change there are kept level (engine/native.py), as the 3-DOF twin was identified level:
the thrusters' load on the horizontal joints is the 3-DOF model's (a thruster tilted with the
hull still pushes it along its tilted axis in heave, pitch and roll), and the horizontal joints
see the 3-DOF rigid body's inertia, the 6-DOF body's own (its centre of gravity moved as it trims,
the rates of heave, pitch and roll) taken off them at the twin's own acceleration. The vertical
modes keep their full coupling. The engine adds (physics/seakeeping.py):

- the pressure load over the wetted hydrodynamic mesh (hydrostatics, and Froude-Krylov in waves);
- heave, roll and pitch added mass A33, A44, A55 as the joints' armature (the added inertia on
  each joint's own axis: no cross terms);
- the strips' radiation damping and diffraction forces, and the wave drift.

In calm water the hull floats at its equilibrium (heave, trim, heel solved from the same meshes)
and its horizontal motion is the 3-DOF twin's (tests/test_sea.py, `twin crosscheck`'s
`six_dof_calm` case). A vessel without hull meshes has no 6-DOF mode.
"""
from __future__ import annotations

import copy
import json
import math
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from ..errors import TwinError
from ..physics import seakeeping as sk
from ..physics import waves
from ..physics.hydrodynamics import Terms
from ..physics.hydrostatics import RHO_FRESH_KG_M3, equilibrium, submerged_volume, waterline_for_mass
from ..vessel import Vessel
from . import native
from .mjcf import JOINTS, CompiledVessel, compile_vessel, edited_spec

SIX_JOINTS = ("down", "pitch", "roll")
ORDER = ("north", "east", "down", "yaw", "pitch", "roll")
SEA_NAME = "twin_sea"
N_STRIPS = 12  # per hull
GRID_MAX_NODES = 25  # per side of the wave grid
POINTS_PER_WAVE = 8  # grid nodes per shortest wavelength
POINTS_PER_MEAN_WAVE = 28  # grid nodes per energy-mean wavelength
STEPS_PER_PERIOD = 10  # time steps per shortest wave period


@dataclass(frozen=True)
class SeaTerms:
    """Switches of the sea loads, so that each can be checked alone (hydrostatics is always on)."""

    waves: bool = True  # incident pressure (Froude-Krylov) in the pressure integration
    diffraction: bool = True
    damping: bool = True
    drift: bool = True


@dataclass(frozen=True)
class HullModel:
    """The hull as the 6-DOF engine sees it (module docstring), in the body frame (FRD, m, kg)."""

    meshes: list  # [(vertices, faces)] hydrodynamic meshes
    mass_kg: float
    cg_m: np.ndarray
    inertia_cg: np.ndarray  # (3,) Ixx, Iyy, Izz about the centre of gravity
    strips: list
    radiation: sk.Radiation
    waterplane: sk.Waterplane
    restoring: dict
    periods: dict
    omega_heave: float
    equilibrium: tuple[float, float, float]  # down (m), pitch, roll (rad) of the body origin at rest
    drift: np.ndarray  # (72, 3) per ½ρg a² in short waves
    draft_m: float
    footprint: tuple[float, float, float, float]  # x_min, x_max, y_min, y_max of the meshes
    z_keel_m: float
    rho: float = RHO_FRESH_KG_M3

    def to_dict(self) -> dict:
        r, c = self.radiation, self.restoring
        return {"mass_kg": self.mass_kg, "cg_m": self.cg_m.tolist(), "inertia_cg_kgm2": self.inertia_cg.tolist(),
                "A33_kg": r.A33, "A44_kgm2": r.A44, "A55_kgm2": r.A55,
                "B33_Ns_m": float(np.sum(r.b33 * [s.dx for s in self.strips])),
                "waterplane_area_m2": self.waterplane.area, "GM_T_m": c["GM_T"], "GM_L_m": c["GM_L"],
                "C33_N_m": c["C33"], "C44_Nm_rad": c["C44"], "C55_Nm_rad": c["C55"],
                "natural_periods_s": self.periods, "equilibrium": {"down_m": self.equilibrium[0],
                                                                   "pitch_deg": math.degrees(self.equilibrium[1]),
                                                                   "roll_deg": math.degrees(self.equilibrium[2])},
                "draft_m": self.draft_m, "triangles": int(sum(len(f) for _, f in self.meshes))}


def vessel_meshes(model: mujoco.MjModel) -> list[tuple[np.ndarray, np.ndarray]]:
    """Every mesh geom of a compiled vessel model at q = 0 (world = body frame there), as
    (vertices, faces) with outward faces."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    out = []
    for g in range(model.ngeom):
        if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        m = model.geom_dataid[g]
        v = model.mesh_vert[model.mesh_vertadr[m]:model.mesh_vertadr[m] + model.mesh_vertnum[m]].astype(float)
        f = model.mesh_face[model.mesh_faceadr[m]:model.mesh_faceadr[m] + model.mesh_facenum[m]].astype(np.int64)
        v = v @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
        if sk._signed_volume(v, f) < 0:
            f = f[:, ::-1].copy()
        out.append((v, f))
    return out


def _spec(vessel: Vessel, wind_inputs: bool, armature: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> mujoco.MjSpec:
    """The vessel's edited spec with the joints of ORDER (yaw re-added after down)."""
    spec = edited_spec(vessel, wind_inputs)
    yaw = next((j for j in spec.joints if j.name == JOINTS[2]), None)
    if yaw is None:
        raise TwinError(f"{vessel.mjcf.name}: missing planar joint 'yaw'")
    body = yaw.parent
    spec.delete(yaw)
    for name, kind, axis, arm in (("down", mujoco.mjtJoint.mjJNT_SLIDE, (0, 0, 1), armature[0]),
                                  ("yaw", mujoco.mjtJoint.mjJNT_HINGE, (0, 0, 1), 0.0),
                                  ("pitch", mujoco.mjtJoint.mjJNT_HINGE, (0, 1, 0), armature[1]),
                                  ("roll", mujoco.mjtJoint.mjJNT_HINGE, (1, 0, 0), armature[2])):
        j = body.add_joint()
        j.name, j.type, j.axis, j.armature = name, kind, list(axis), arm
    return spec


def joint_addresses(model: mujoco.MjModel) -> tuple[tuple[int, ...], tuple[int, ...]]:
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in ORDER]
    if min(ids) < 0:
        raise TwinError("not a 6-DOF vessel model")
    return tuple(int(model.jnt_qposadr[i]) for i in ids), tuple(int(model.jnt_dofadr[i]) for i in ids)


def _mass_properties(vessel: Vessel) -> tuple[float, np.ndarray, np.ndarray, list]:
    model = _spec(vessel, False).compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "vessel")
    mass = float(model.body_subtreemass[body])
    cg = data.subtree_com[body].copy()
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    _, dof = joint_addresses(model)
    i_co = np.array([M[dof[5], dof[5]], M[dof[4], dof[4]], M[dof[3], dof[3]]])
    i_cg = i_co - mass * np.array([cg[1] ** 2 + cg[2] ** 2, cg[0] ** 2 + cg[2] ** 2, cg[0] ** 2 + cg[1] ** 2])
    return mass, cg, i_cg, vessel_meshes(model)


_HULLS: dict[tuple, HullModel] = {}


def _hull(vessel: Vessel) -> HullModel:
    mass, cg, i_cg, full = _mass_properties(vessel)
    if not full:
        raise TwinError(f"vessel '{vessel.name}' has no hull meshes: a sea (the 6-DOF hull) needs them")
    rho = RHO_FRESH_KG_M3 if vessel.mmg is None else vessel.mmg.rho_kg_m3
    hydro = _centred_on_full([sk.hydro_mesh(v, f) for v, f in full], full, mass, rho)
    level = waterline_for_mass(hydro, mass, rho)
    z_w = level["waterline_z_m"]
    strips = [s for v, f in hydro for s in sk.strips(v, f, z_w, N_STRIPS)]
    wp = sk.waterplane(hydro, z_w)
    restoring = sk.restoring(wp, mass, float(cg[2]), rho)
    # the heave natural frequency with the strips' added mass (of infinite frequency: no iteration)
    omega = math.sqrt(restoring["C33"] / (mass + sk.radiation(strips, rho, None).A33))
    rad = sk.radiation(strips, rho, omega)
    periods = sk.natural_periods(wp, restoring, mass, cg, i_cg, rad, rho)
    eq = equilibrium(hydro, mass, cg, rho)
    segs = np.vstack([sk.waterline_segments(v, f, z_w) for v, f in hydro])
    allv = np.vstack([v for v, _ in full])
    draft = float(np.mean([s.draft for s in strips if s.draft > 0]))
    return HullModel(hydro, mass, cg, i_cg, strips, rad, wp, restoring, periods, omega, eq, sk.drift_table(segs),
                     draft, (float(allv[:, 0].min()), float(allv[:, 0].max()), float(allv[:, 1].min()),
                             float(allv[:, 1].max())), float(allv[:, 2].max()), rho)


def _centred_on_full(hydro: list, full: list, mass_kg: float, rho: float) -> list:
    """The hydrodynamic meshes placed where they float the vessel as its full meshes do: each moved
    horizontally so that its centre of buoyancy at the level flotation is its full mesh's, and all
    vertically so that they float the mass at the full meshes' waterline. Resampling moves the
    centre of buoyancy by a fraction of a millimetre, which trims and heels the hull by hundredths
    of a degree and so moves its centre of gravity in the heading frame: placed, a vessel whose full
    meshes float it level floats level on its hydrodynamic meshes too."""
    z_full = waterline_for_mass(full, mass_kg, rho)["waterline_z_m"]
    z_hydro = waterline_for_mass(hydro, mass_kg, rho)["waterline_z_m"]
    out = []
    for (hv, hf), (fv, ff) in zip(hydro, full):
        shift = submerged_volume(fv, ff, z_full)[1] - submerged_volume(hv, hf, z_hydro)[1]
        out.append((hv + [shift[0], shift[1], z_full - z_hydro], hf))
    return out


def hull_model(vessel: Vessel) -> HullModel:
    """The vessel's hull for the 6-DOF engine (cached per MJCF, mass case and CG offset)."""
    case = vessel.cases.get(vessel.case)
    key = (str(vessel.mjcf), vessel.case, tuple(vessel.cg_offset_m), repr(case),
           None if vessel.mmg is None else vessel.mmg.rho_kg_m3)
    if key not in _HULLS:
        _HULLS[key] = _hull(vessel)
    return _HULLS[key]


@dataclass(frozen=True)
class Grid:
    nx: int
    ny: int
    gx0: float
    gy0: float
    dx: float
    dy: float
    i0: int
    j0: int

    def to_pack(self, zh: float) -> dict:
        return {"nx": self.nx, "ny": self.ny, "gx0": self.gx0, "gy0": self.gy0, "dx": self.dx, "dy": self.dy,
                "zh": zh, "i0": self.i0, "j0": self.j0}


def _axis(lo: float, hi: float, spacing: float) -> tuple[int, float, int]:
    """Nodes on [lo, hi] ∋ 0 with 0 on a node: (count, first node's coordinate, index of 0)."""
    below = max(1, math.ceil(-lo / spacing))
    above = max(1, math.ceil(hi / spacing))
    return below + above + 1, -below * spacing, below


def wave_grid(hull: HullModel, comps: waves.Components) -> Grid:
    """A heading-frame grid over the hull's footprint (a margin for its roll, pitch and yaw about
    the heading) with POINTS_PER_WAVE nodes per shortest wavelength and POINTS_PER_MEAN_WAVE per
    energy-mean wavelength (bilinear interpolation loses about (kΔ)²/12 of an amplitude: 0.4 % at
    the mean) and at least four cells across the hull's footprint, at most GRID_MAX_NODES a side."""
    x0, x1, y0, y1 = hull.footprint
    margin = 0.1 * (x1 - x0) + 0.05
    x0, x1, y0, y1 = x0 - margin, x1 + margin, y0 - margin, y1 + margin
    energy = comps.amplitude_m ** 2
    k_mean = float(np.sum(energy * comps.k_rad_m) / np.sum(energy))
    spacing = min(2 * math.pi / comps.k_rad_m.max() / POINTS_PER_WAVE, 2 * math.pi / k_mean / POINTS_PER_MEAN_WAVE,
                  min(x1 - x0, y1 - y0) / 4)  # a secant across the hull would flatten the pressure's slope
    spacing = max(spacing, (x1 - x0) / (GRID_MAX_NODES - 2), (y1 - y0) / (GRID_MAX_NODES - 2))
    nx, gx0, i0 = _axis(x0, x1, spacing)
    ny, gy0, j0 = _axis(y0, y1, spacing)
    return Grid(nx, ny, gx0, gy0, spacing, spacing, i0, j0)


def shortest_period(hull: HullModel, timestep_s: float) -> float:
    """The shortest wave period the engine resolves: STEPS_PER_PERIOD time steps, and a wavelength
    of POINTS_PER_WAVE nodes of the finest grid the hull allows."""
    x0, x1, y0, y1 = hull.footprint
    margin = 0.1 * (x1 - x0) + 0.05
    finest = max((x1 - x0 + 2 * margin) / (GRID_MAX_NODES - 2), (y1 - y0 + 2 * margin) / (GRID_MAX_NODES - 2))
    lam = POINTS_PER_WAVE * finest
    return max(STEPS_PER_PERIOD * timestep_s, math.sqrt(2 * math.pi * lam / waves.G))


def sea_components(hull: HullModel, sea: waves.Sea, timestep_s: float) -> waves.Components:
    """The sea's components the engine resolves, or TwinError naming why it cannot."""
    t_min = shortest_period(hull, timestep_s)
    waves.check_sea(sea, t_min if sea.regular else None, "the twin resolves (time step and wave grid)")
    if not sea.regular and sea.tp_s < t_min:
        raise TwinError(f"sea: a peak period of {sea.tp_s:g} s is shorter than the {t_min:.2f} s the twin "
                        "resolves (time step and wave grid)")
    return waves.components(sea, omega_max=2 * math.pi / t_min)


def strip_depth_m(hull: HullModel) -> float:
    """The strips' mean depth below the waterline (m): where the hull meets the waves' orbits."""
    return float(np.mean([s.mean_depth for s in hull.strips if s.beam > 0]))


def known_sea_drift(vessel: Vessel, sea: waves.Sea) -> tuple[float, float]:
    """The steady drift (north, east, m/s) a 3-DOF twin takes as a known flow for a sea it is not
    simulated in (environment.Environment.wave_drift_ned): the Stokes drift [Stokes-1847] of the
    components the 6-DOF engine would resolve on this hull, at its strips' mean depth. A free 6-DOF
    hull drifts at about this speed in long waves and faster in short ones (twin.verify.sea.free_drift;
    docs/results/sea_verification.md), where its own pressure and diffraction loads add to it."""
    hull = hull_model(vessel)
    comps = sea_components(hull, sea, _spec(vessel, False).option.timestep)
    n, e = waves.stokes_drift(comps, strip_depth_m(hull))
    return float(n), float(e)


KNOWN_SPEEDS_M_S = (0.0, 1.0, 2.0, 3.0)  # the mean-load table's speeds: run over ground, read through the flow
KNOWN_SETTLE_S = 6.0  # the heave, roll and pitch settle into the waves before the mean is taken
KNOWN_RUN_S = 30.0  # each run's averaging time: two antithetic runs in an irregular sea, one in a regular
_KNOWN_SAMPLE_EVERY = 5  # steps between the samples of the mean
_MEAN_LOADS: dict[str, np.ndarray] = {}


def mean_sea_load(vessel: Vessel, sea: waves.Sea, speeds_m_s=KNOWN_SPEEDS_M_S, run_s: float = KNOWN_RUN_S
                  ) -> np.ndarray:
    """The mean load of `sea` on the vessel's 6-DOF hull by the waves' heading off the bow (every
    45°) and its speed (the runs' over ground, read through the known flow: docs/method/sea-state.md):
    the block of physics.seakeeping.pack_known_load.

    Each entry is a run of the 6-DOF hull driven at that speed and heading without thrust, free in
    heave, roll and pitch: the mean over the run of the forces that accelerate its surge, sway and
    yaw in the waves (the sea's load, and damping, added-mass Coriolis and propellers seeing the
    orbital velocity), after KNOWN_SETTLE_S, less those of the 3-DOF twin moving through the known
    flow (`known_sea_drift`): the flow and this load together give the 3-DOF twin the mean forces of
    the 6-DOF hull. An irregular sea is run twice, the second time with every component's phase
    turned by π, so that the first-order load, which changes sign, cancels from the mean and the
    second-order load, which does not, stays; a regular wave once, over whole periods of encounter. The hull is taken as port-starboard
    symmetric (the shipped hulls are): the waves from port are those from starboard mirrored."""
    vessel = without_known_sea(vessel)
    key = json.dumps([vessel.to_dict(), sea.to_dict(), list(speeds_m_s), run_s], sort_keys=True, default=str)
    if key not in _MEAN_LOADS:
        _MEAN_LOADS[key] = _mean_sea_load(vessel, sea, tuple(float(u) for u in speeds_m_s), run_s)
    return _MEAN_LOADS[key].copy()


def _mean_sea_load(vessel: Vessel, sea: waves.Sea, speeds: tuple[float, ...], run_s: float) -> np.ndarray:
    flow_n, flow_e = known_sea_drift(vessel, sea)
    six = compile_six(compile_vessel(vessel), sea)
    model = six.model
    data = mujoco.MjData(model)
    qa, da = (list(a) for a in joint_addresses(model))
    p = native._params_view(model).copy()
    inertia = np.linalg.inv(p[native._O_MINV:native._O_MINV + 9].reshape(3, 3))  # M_RB + M_A
    view = sea_view(model)
    layout = sk.sea_layout(*(int(view[i]) for i in (sk._NV, sk._NF, sk._NC, sk._NS, sk._ND)))
    phases = view[layout["comps"]].reshape(-1, 6)[:, 5].copy()
    h = model.opt.timestep
    settle = int(round(KNOWN_SETTLE_S / h))
    half = sk.KNOWN_HEADINGS // 2
    table = np.zeros((sk.KNOWN_HEADINGS, len(speeds), 3))
    frm = math.radians(sea.dir_deg)
    with native.installed_native():
        for j in range(half + 1):
            psi = frm - j * 2.0 * math.pi / sk.KNOWN_HEADINGS
            c, s = math.cos(psi), math.sin(psi)
            flow = (c * flow_n + s * flow_e, -s * flow_n + c * flow_e)
            for k, speed in enumerate(speeds):
                steps = settle + int(round(_averaging_s(sea, j * 2.0 * math.pi / sk.KNOWN_HEADINGS, speed, run_s) / h))
                samples = []
                for turn in ((0.0,) if sea.regular else (0.0, math.pi)):
                    view[layout["comps"]].reshape(-1, 6)[:, 5] = phases + turn
                    view_now = view.copy()
                    mujoco.mj_resetData(model, data)
                    data.qpos[:] = six.initial_qpos((0.0, 0.0, psi))
                    vn, ve = speed * c, speed * s
                    for i in range(steps):
                        data.qvel[da[0]], data.qvel[da[1]], data.qvel[da[3]] = vn, ve, 0.0
                        mujoco.mj_step(model, data)
                        data.qpos[qa[0]], data.qpos[qa[1]], data.qpos[qa[3]] = vn * data.time, ve * data.time, psi
                        data.qvel[da[0]], data.qvel[da[1]], data.qvel[da[3]] = vn, ve, 0.0
                        if i >= settle and i % _KNOWN_SAMPLE_EVERY == 0:
                            samples.append(_added_load(view_now, p, inertia, data, da, psi, speed, flow))
                table[j, k] = np.mean(samples, axis=0)
    view[layout["comps"]].reshape(-1, 6)[:, 5] = phases
    for j in range(1, half):  # from port: the mirror of from starboard
        table[sk.KNOWN_HEADINGS - j] = table[j] * np.array([1.0, -1.0, -1.0])
    return sk.pack_known_load(frm, speeds, table)


def _averaging_s(sea: waves.Sea, off_bow_rad: float, speed: float, run_s: float) -> float:
    """How long to average a run: `run_s` in an irregular sea; in a regular wave whole periods of
    encounter, at least three and six seconds, at most `run_s` (following waves nearly at the hull's
    speed are met too seldom for more)."""
    if not sea.regular:
        return run_s
    omega = 2.0 * math.pi / sea.tp_s
    met = abs(omega + omega * omega / waves.G * speed * math.cos(off_bow_rad))
    period = 2.0 * math.pi / max(met, 1e-9)
    whole = max(3, math.ceil(6.0 / period)) * period
    return whole if whole <= run_s else run_s


def _added_load(sea_packed: np.ndarray, p: np.ndarray, inertia: np.ndarray, data, da, psi: float, speed: float,
                flow: tuple[float, float]) -> np.ndarray:
    """What the waves add to the force accelerating surge, sway and yaw of a hull at heading ψ and
    `speed` over ground (body frame) beyond the 3-DOF twin's in the steady `flow` (body frame, m/s):
    the sea's load and the 3-DOF forces with the orbital velocity, less those through the flow."""
    load, water = np.zeros(len(data.qvel)), np.zeros(2)
    sk.sea_load(sea_packed, data.time, data.qpos, data.qvel, load, water)
    c, s = math.cos(psi), math.sin(psi)
    uw, vw = c * water[0] + s * water[1], -s * water[0] + c * water[1]
    sx, sy, sn = c * load[da[0]] + s * load[da[1]], -s * load[da[0]] + c * load[da[1]], load[da[3]]
    wet = native.hydro_force_body(p, psi, speed, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, uw, vw,
                                  sx, sy, sn)
    calm = native.hydro_force_body(p, psi, speed, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                                   flow[0], flow[1])
    return inertia @ (np.array(wet[3:]) - np.array(calm[3:]))


def with_known_sea(vessel: Vessel, sea: waves.Sea | None) -> Vessel:
    """The 3-DOF twin of a recording made in `sea`: its steady drift (`known_sea_drift`) a known flow
    and its mean load (`mean_sea_load`) a known force (unchanged without a sea)."""
    if sea is None:
        return vessel
    env = replace(vessel.environment, wave_drift_ned=known_sea_drift(vessel, sea),
                  wave_load=tuple(float(x) for x in mean_sea_load(vessel, sea)))
    return vessel.with_environment(env)


def without_known_sea(vessel: Vessel) -> Vessel:
    """The twin without a recording's sea: what identification and diagnosis write."""
    return vessel.with_environment(replace(vessel.environment, wave_drift_ned=(0.0, 0.0), wave_load=()))


def check_sea_for(vessel: Vessel, sea: waves.Sea) -> None:
    """TwinError (one line) unless the vessel can run in `sea`: hull meshes, and a sea its time step
    and wave grid resolve. What a command checks before any work."""
    spec = _spec(vessel, False)
    sea_components(hull_model(vessel), sea, spec.option.timestep)


@dataclass
class SixModel:
    """A compiled 6-DOF model and what it was built from."""

    model: mujoco.MjModel
    hull: HullModel
    components: waves.Components | None
    grid: Grid | None
    sea: waves.Sea | None

    def initial_qpos(self, eta0=None) -> np.ndarray:
        """qpos at rest on the equilibrium (heave, trim, heel) at η0."""
        eta0 = np.zeros(3) if eta0 is None else np.asarray(eta0, float)
        qpos, _ = joint_addresses(self.model)
        q = self.model.qpos0.copy()
        z, th, ph = self.hull.equilibrium
        for adr, val in zip(qpos, (eta0[0], eta0[1], z, eta0[2], th, ph)):
            q[adr] = val
        return q


def compile_six(compiled: CompiledVessel, sea: waves.Sea | None = None, terms: Terms | None = None,
                sea_terms: SeaTerms | None = None, wind_inputs: bool | None = None,
                slots: int | None = None) -> SixModel:
    """The vessel's 6-DOF model with the native callback's parameters (3-DOF horizontal model first,
    the packed sea second), in calm water without `sea`. `slots`: room for that many wave components
    (the unused ones of zero height), so that another draw of the sea fits in a copy (`reseeded`)."""
    vessel = compiled.vessel
    if any(vessel.environment.wave_drift_ned) or vessel.environment.wave_load:
        raise TwinError(f"'{vessel.name}' carries a sea's drift as a known flow of the 3-DOF twin; the 6-DOF twin "
                        "takes the sea itself (--sea)")
    hull = hull_model(vessel)
    sea_terms = sea_terms or SeaTerms()
    wind_inputs = compiled.wind_inputs if wind_inputs is None else wind_inputs
    rad = hull.radiation
    spec = _spec(vessel, wind_inputs, (rad.A33, rad.A55, rad.A44))
    h = spec.option.timestep
    comps = None if sea is None else sea_components(hull, sea, h)
    others = [(n.name, list(n.data), n.size) for n in spec.numerics]
    for n in list(spec.numerics):
        spec.delete(n)
    spec.add_numeric(name=native.PARAMS_NAME, data=np.zeros(native.NPARAM), size=native.NPARAM)
    packed = _pack(hull, comps, sea_terms, (0,) * 6, (0,) * 6, compiled, h, slots)
    spec.add_numeric(name=SEA_NAME, data=np.zeros(len(packed)), size=len(packed))
    for name, data, size in others:
        spec.add_numeric(name=name, data=data, size=size)
    model = spec.compile()
    native.set_params(model, compiled.hydro(terms))
    qpos, dof = joint_addresses(model)
    packed = _pack(hull, comps, sea_terms, qpos, dof, compiled, h, slots)
    adr = int(model.numeric_adr[1])
    model.numeric_data[adr:adr + len(packed)] = packed
    grid = None if comps is None else wave_grid(hull, comps)
    return SixModel(model, hull, comps, grid, sea)


def reseeded(six: SixModel, compiled: CompiledVessel, sea: waves.Sea, sea_terms: SeaTerms | None = None
             ) -> mujoco.MjModel:
    """A copy of six.model in `sea` (typically six.sea drawn from another seed), with the horizontal
    added mass of `compiled` in its diffraction load; six compiled with room for the components
    (`compile_six(..., slots=...)`). The native parameters stay six.model's (set them per copy)."""
    model = copy.copy(six.model)
    h = model.opt.timestep
    comps = sea_components(six.hull, sea, h)
    qpos, dof = joint_addresses(model)
    view = sea_view(model)
    slots = int(view[sk._NC])
    if len(comps) > slots:
        raise TwinError(f"a sea of {len(comps)} components does not fit a model made for {slots}")
    packed = _pack(six.hull, comps, sea_terms or SeaTerms(), qpos, dof, compiled, h, slots)
    if len(packed) != len(view):
        raise TwinError("the sea does not fit this model's packed sea")
    view[:] = packed
    return model


def _pack(hull: HullModel, comps, sea_terms: SeaTerms, qpos, dof, compiled: CompiledVessel, h: float,
          slots: int | None = None) -> np.ndarray:
    verts, faces, off = [], [], 0
    for v, f in hull.meshes:
        verts.append(v)
        faces.append(f + off)
        off += len(v)
    verts, faces = np.vstack(verts), np.vstack(faces)
    # the deepest pressure level: half as deep again as the keel at rest (the body origin floats
    # equilibrium[0] below the surface, the keel z_keel_m below the origin)
    zh = max(hull.z_keel_m + hull.equilibrium[0], 0.02) * 1.5
    strip_depth = strip_depth_m(hull)
    dxs = np.array([s.dx for s in hull.strips])
    # the sway share follows each section's area B·T (its share of the displaced water); a flat plate's
    # sway added mass would follow T², which moves the load's centre 6-7 mm on the shipped hulls
    a22 = np.array([s.beam * s.draft for s in hull.strips]) * dxs
    rows = np.column_stack([[s.x for s in hull.strips], [s.y for s in hull.strips], hull.radiation.a33 * dxs,
                            hull.radiation.b33 * dxs, dxs / dxs.sum(), a22 / max(a22.sum(), 1e-12)])
    am = compiled.vessel.added_mass
    if comps is None:
        grid = {"nx": 0, "ny": 0, "gx0": 0.0, "gy0": 0.0, "dx": 1.0, "dy": 1.0, "zh": zh, "i0": 0, "j0": 0}
        packed_c, weights, drift_c = np.zeros((0, 6)), np.zeros((7, 0)), np.zeros(0)
    else:
        grid = wave_grid(hull, comps).to_pack(zh)
        packed_c = comps.pack()
        weights = waves.field_weights(comps, (0.0, zh / 2, zh), strip_depth)
        drift_c = 0.5 * hull.rho * waves.G * sk.reflection_squared(comps.k_rad_m, hull.draft_m)
        if slots is not None and slots > len(comps):  # zero-height components: they add nothing
            pad = slots - len(comps)
            packed_c = np.vstack([packed_c, np.zeros((pad, 6))])
            weights = np.hstack([weights, np.zeros((7, pad))])
            drift_c = np.concatenate([drift_c, np.zeros(pad)])
    switches = (sea_terms.waves, sea_terms.diffraction, sea_terms.damping, sea_terms.drift)
    return sk.pack_sea(verts, faces, packed_c, weights, drift_c, rows, hull.drift, grid, switches, qpos, dof,
                       hull.rho, (am.Xudot, am.Yvdot), thrust_arms=level_thrust_arms(compiled),
                       rest_down_m=hull.equilibrium[0])


def level_thrust_arms(compiled: CompiledVessel) -> np.ndarray:
    """(actuator, a_x, a_y, a_N) per thruster: the 3-DOF model's generalised force on north, east and
    yaw per newton of each site-driven actuator, at heading 0 (seakeeping.level_thrust)."""
    model = compiled.model
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    _, dof = joint_addresses3(model)
    rows = []
    for i in range(model.nu):
        if model.actuator_trntype[i] != mujoco.mjtTrn.mjTRN_SITE:
            continue
        site = int(model.actuator_trnid[i, 0])
        jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, jacp, jacr, site)
        rot = data.site_xmat[site].reshape(3, 3)
        gear = model.actuator_gear[i]
        q = jacp.T @ (rot @ gear[:3]) + jacr.T @ (rot @ gear[3:])
        rows.append((float(i), *(float(q[d]) for d in dof)))
    return np.array(rows).reshape(-1, 4)


def joint_addresses3(model: mujoco.MjModel) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """qpos and dof addresses of the 3-DOF model's north, east and yaw joints."""
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) for name in JOINTS]
    return tuple(int(model.jnt_qposadr[j]) for j in ids), tuple(int(model.jnt_dofadr[j]) for j in ids)


def sea_view(model: mujoco.MjModel) -> np.ndarray:
    """The model's packed sea (a writable view of its second numeric)."""
    adr, size = int(model.numeric_adr[1]), int(model.numeric_size[1])
    return model.numeric_data[adr:adr + size]


def set_sea_terms(model: mujoco.MjModel, sea_terms: SeaTerms) -> None:
    p = sea_view(model)
    p[sk._FK], p[sk._DIFF], p[sk._DAMP], p[sk._DRIFT] = (float(sea_terms.waves), float(sea_terms.diffraction),
                                                       float(sea_terms.damping), float(sea_terms.drift))


def potential_energy(hull: HullModel, qpos6: np.ndarray) -> float:
    """Hydrostatic potential ρ g ∫_V z dV of the displaced water (J), z down, in calm water: with the
    gravity potential −m g z_G it is the energy the pressure and gravity forces conserve."""
    x, y, z, psi, theta, phi = qpos6
    R = sk.rotation(psi, theta, phi)
    total = 0.0
    for v, f in hull.meshes:
        w = v @ R.T + np.array([0.0, 0.0, z])
        vol, c = submerged_volume(w, f, 0.0)
        total += vol * c[2]
    return hull.rho * waves.G * total


def free_run(six: SixModel, duration_s: float, offset=(0.0, 0.0, 0.0), qvel0=None, sample_every: int = 1,
             thrust=(0.0, 0.0), eta0=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step the 6-DOF model from its rest at η0 (north m, east m, heading rad) displaced by `offset`
    (down m, pitch rad, roll rad) under a constant thrust command: (times, qpos rows, qvel rows)
    every `sample_every` steps, in ORDER."""
    model = six.model
    data = mujoco.MjData(model)
    qpos, dof = joint_addresses(model)
    data.qpos[:] = six.initial_qpos(eta0)
    for adr, d in zip((qpos[2], qpos[4], qpos[5]), offset):
        data.qpos[adr] += d
    if qvel0 is not None:
        data.qvel[list(dof)] = qvel0
    data.ctrl[:2] = thrust
    n = int(round(duration_s / model.opt.timestep))
    rows = n // sample_every + 1
    t, q, v = np.empty(rows), np.empty((rows, 6)), np.empty((rows, 6))
    with native.installed_native():
        for i in range(rows):
            t[i] = data.time
            q[i] = data.qpos[list(qpos)]
            v[i] = data.qvel[list(dof)]
            if i < rows - 1:
                mujoco.mj_step(model, data, sample_every)
    return t, q, v
