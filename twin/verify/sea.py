"""Checks of the 6-DOF hull (engine/sixdof.py) against closed forms and published figures, each a
function returning numbers: tests/test_sea.py asserts them, scripts/sea_verification.py writes them
on a result page (docs/results/sea_verification.md).

- rest: the engine left free from the design waterline settles where `twin validate` floats the
  full meshes (heave, trim);
- natural periods of free heave, roll and pitch decay against T = 2π √((M + A)/C) from the
  waterplane and the metacentric heights, with the added mass the engine uses;
- energy of an undamped roll decay (kinetic + gravity + hydrostatic potential);
- calm water: the 6-DOF horizontal track against the 3-DOF twin's over the crosscheck zig-zag;
- a floating box (barge) in regular waves: heave RAO against the closed-form linear strip solution
  of the same model (Froude-Krylov on the bottom with the Smith factor, relative-motion
  diffraction and damping [Journee-Massie-2001]), roll RAO's long-wave limit (the hull follows the
  wave slope) and resonance at the natural period;
- mean drift on the barge against the short-wave asymptote of a wall-sided body [Faltinsen-1990]
  and the reflection of a fixed barrier [Ursell-1947];
- a free hull in waves drifts along them at about the Stokes drift of the water it floats in
  [Stokes-1847], not along its own heading.
"""
from __future__ import annotations

import math
import statistics
import time
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import trimesh

from .. import drive
from ..engine import native, sixdof
from ..engine.mjcf import compile_vessel
from ..engine.sim import simulate
from ..errors import TwinError
from ..physics import seakeeping as sk
from ..physics import waves
from ..physics.hydrodynamics import Terms
from ..vessel import Vessel, load
from .validate import validate

BARGE = {"length_m": 2.0, "beam_m": 1.0, "depth_m": 0.5, "mass_kg": 500.0}  # a 0.25 m draft in fresh water

_BARGE_XML = """<mujoco model="barge">
  <compiler meshdir="{meshdir}" angle="radian"/>
  <option timestep="0.01" integrator="RK4" gravity="0 0 9.81"><flag contact="disable" constraint="disable"/></option>
  <asset><mesh name="box" file="barge.stl" inertia="exact"/></asset>
  <default><geom contype="0" conaffinity="0"/><site size="0.02"/></default>
  <worldbody>
    <body name="vessel">
      <joint name="north" type="slide" axis="1 0 0"/>
      <joint name="east" type="slide" axis="0 1 0"/>
      <joint name="yaw" type="hinge" axis="0 0 1"/>
      <body name="box"><geom name="box" type="mesh" mesh="box" mass="{mass}"/></body>
      <site name="imu" pos="0 0 0"/>
      <site name="gnss" pos="0 0 -0.5"/>
      <site name="thruster_left" pos="-0.9 -0.3 0.1"/>
      <site name="thruster_right" pos="-0.9 0.3 0.1"/>
    </body>
  </worldbody>
  <actuator>
    <general name="thruster_left" site="thruster_left" gear="1 0 0 0 0 0"/>
    <general name="thruster_right" site="thruster_right" gear="1 0 0 0 0 0"/>
  </actuator>
</mujoco>
"""


def barge(folder: Path) -> Vessel:
    """A uniform box barge (BARGE) written into `folder`: CyberShip I's horizontal model on a box hull
    whose centre is the body origin, floating level at half its depth."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    b = BARGE
    box = trimesh.creation.box((b["length_m"], b["beam_m"], b["depth_m"]))
    box.export(folder / "barge.stl")
    (folder / "barge.xml").write_text(_BARGE_XML.format(meshdir=folder.resolve(), mass=b["mass_kg"]))
    base = load("cybership1")
    return replace(base, name="barge", mjcf=folder / "barge.xml", path=None, cases={}, case="nominal")


# ---------------------------------------------------------------- rest and natural periods


def rest(vessel: Vessel, settle_s: float = 20.0) -> dict:
    """The engine's heave and trim after settling from the design waterline (level, z = 0), against
    `twin validate`'s floating-free values from the full meshes."""
    quantities = {q.name: q.mesh for q in validate(vessel).quantities}
    cv = compile_vessel(vessel)
    six = sixdof.compile_six(cv, terms=Terms().only())
    eq = six.hull.equilibrium
    t, q, _ = sixdof.free_run(six, settle_s, offset=(-eq[0], -eq[1], -eq[2]), sample_every=50)
    return {"engine_down_mm": 1e3 * q[-1, 2], "engine_trim_deg": math.degrees(q[-1, 4]),
            "engine_heel_deg": math.degrees(q[-1, 5]),
            "validate_down_mm": quantities["CO below the surface, free"],
            "validate_trim_deg": quantities["trim, free (bow down −)"],
            "validate_heel_deg": quantities["heel, free"]}


def crossing_period(t: np.ndarray, x: np.ndarray) -> float:
    """Mean period from the up-crossings of x about its final mean (linear interpolation)."""
    x = x - np.mean(x[len(x) // 2:])
    up = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    times = t[up] - x[up] * (t[up + 1] - t[up]) / (x[up + 1] - x[up])
    return float(np.mean(np.diff(times))) if len(times) > 2 else float("nan")


def natural_periods(vessel: Vessel, cycles: float = 6.0) -> dict:
    """Free decay in heave, roll and pitch, undamped (sea loads off but hydrostatics; no horizontal
    hydrodynamics), each mode started along its own shape (sk.coupled_modes: a pure heave or pitch
    displacement of a hull whose two periods are close rings in both and beats), its period from
    the up-crossings of its own coordinate, against the closed form."""
    cv = compile_vessel(vessel)
    six = sixdof.compile_six(cv, terms=Terms().only(), sea_terms=sixdof.SeaTerms(False, False, False, False))
    hull = six.hull
    closed = hull.periods
    modes = sk.coupled_modes(hull.waterplane, hull.restoring, hull.mass_kg, hull.cg_m, hull.inertia_cg,
                             hull.radiation, hull.rho)
    out = {}
    for mode, amplitude, col in (("heave", 0.004, 0), ("pitch", math.radians(0.5), 1),
                                 ("roll", math.radians(1.0), 2)):
        shape = modes[mode][1]
        t, q, _ = sixdof.free_run(six, cycles * closed[mode], offset=tuple(amplitude / shape[col] * shape))
        measured = crossing_period(t, q[:, (2, 4, 5)[col]])
        out[mode] = {"engine_s": measured, "closed_form_s": closed[mode],
                     "uncoupled_s": closed[f"{mode}_uncoupled"], "error": measured / closed[mode] - 1.0}
    return out


def roll_energy(vessel: Vessel, duration_s: float = 10.0, roll_deg: float = 3.0) -> dict:
    """Undamped roll decay: kinetic + gravity + hydrostatic potential energy at the start and its
    largest departure (J), relative to the roll's initial potential energy above the rest."""
    cv = compile_vessel(vessel)
    six = sixdof.compile_six(cv, terms=Terms().only(), sea_terms=sixdof.SeaTerms(False, False, False, False))
    model = six.model
    t, q, v = sixdof.free_run(six, duration_s, offset=(0.0, 0.0, math.radians(roll_deg)), sample_every=5)
    qpos, dof = sixdof.joint_addresses(model)
    data = mujoco.MjData(model)
    energy = []
    rest_e = None
    for row_q, row_v in zip(q, v):
        data.qpos[list(qpos)] = row_q
        data.qvel[list(dof)] = row_v
        mujoco.mj_forward(model, data)
        mujoco.mj_energyPos(model, data)
        mujoco.mj_energyVel(model, data)
        gravity = -six.hull.mass_kg * waves.G * data.subtree_com[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY,
                                                                                  "vessel")][2]
        energy.append(float(data.energy[1] + gravity + sixdof.potential_energy(six.hull, row_q)))
    data.qpos[:] = six.initial_qpos()
    mujoco.mj_forward(model, data)
    rest_e = -six.hull.mass_kg * waves.G * data.subtree_com[1][2] + sixdof.potential_energy(
        six.hull, data.qpos[list(qpos)])
    energy = np.array(energy)
    scale = energy[0] - rest_e
    return {"initial_J": float(energy[0] - rest_e), "largest_change_J": float(np.max(np.abs(energy - energy[0]))),
            "relative": float(np.max(np.abs(energy - energy[0])) / scale), "roll_amplitude_end_deg":
            float(np.rad2deg(np.max(np.abs(q[-len(q) // 5:, 5] - six.hull.equilibrium[2]))))}


def calm_water(vessel: Vessel, duration_s: float = 120.0) -> dict:
    """The 6-DOF horizontal track against the 3-DOF twin's over the crosscheck zig-zag, and how far
    the hull heaves, rolls and pitches in it."""
    cv = compile_vessel(vessel)
    r3 = simulate(cv, drive.get("zigzag"), duration_s)
    r6 = simulate(cv, drive.get("zigzag"), duration_s, six_dof=True)
    six = r6.meta["six_dof"]
    return {"position_err_m": float(np.max(np.hypot(*(r6.eta[:, :2] - r3.eta[:, :2]).T))),
            "heading_err_deg": float(np.rad2deg(np.max(np.abs(r6.eta[:, 2] - r3.eta[:, 2])))),
            "trim_deg": math.degrees(sixdof.hull_model(vessel).equilibrium[1]),
            "heel_deg": math.degrees(sixdof.hull_model(vessel).equilibrium[2]),
            "roll_max_deg": float(np.rad2deg(np.max(np.abs(six["roll_rad"])))),
            "pitch_range_deg": float(np.rad2deg(np.ptp(six["pitch_rad"]))),
            "heave_range_mm": float(1e3 * np.ptp(six["down_m"]))}


# ---------------------------------------------------------------- the barge in regular waves


def heave_rao_closed_form(hull: sixdof.HullModel, period_s: float) -> float:
    """|z|/a of the box in head seas, linear: (C33 − ω²(m + A33) − iωB33) ẑ = F̂ with
    F̂/a = L sinc(kL/2) [−ρ g B e^{−kT} + (A33/L) ω² e^{−kT_m} + iω (B33/L) e^{−kT_m}]
    (Froude-Krylov on the bottom, relative-motion diffraction and damping, T_m = T for a box)."""
    b = BARGE
    L, B = b["length_m"], b["beam_m"]
    T = float(np.mean([s.draft for s in hull.strips]))
    w = 2 * math.pi / period_s
    k = w * w / waves.G
    a33 = hull.radiation.A33
    b33 = float(np.sum(hull.radiation.b33 * [s.dx for s in hull.strips]))
    sinc = math.sin(k * L / 2) / (k * L / 2)
    force = L * sinc * (-hull.rho * waves.G * B * math.exp(-k * T) + a33 / L * w * w * math.exp(-k * T)
                        + 1j * w * b33 / L * math.exp(-k * T))
    z = force / (hull.restoring["C33"] - w * w * (hull.mass_kg + a33) - 1j * w * b33)
    return abs(z)


def roll_rao_closed_form(hull: sixdof.HullModel, period_s: float) -> float:
    """|φ|/(k a) of the box in beam seas, linear and undamped (no roll damping on a box whose strips
    lie on its centreline): (C44 − ω²(I44 + A44)) φ̂ = M̂ with the Froude-Krylov roll moment of the
    incident pressure ρ g a e^{−kz} e^{iky} on the bottom (y = ±b, z = T) and the sides,
        M̂ = 2i ρ g a L [sin(kb) J − e^{−kT} (sin(kb)/k² − b cos(kb)/k)],  J = (1 − e^{−kT}(1 + kT))/k².
    Its long-wave limit is 1: the box follows the wave slope."""
    b = BARGE
    L, half = b["length_m"], b["beam_m"] / 2
    T = float(np.mean([s.draft for s in hull.strips]))
    w = 2 * math.pi / period_s
    k = w * w / waves.G
    J = (1 - math.exp(-k * T) * (1 + k * T)) / (k * k)
    moment = 2 * hull.rho * waves.G * L * (math.sin(k * half) * J - math.exp(-k * T) * (
        math.sin(k * half) / (k * k) - half * math.cos(k * half) / k))
    return abs(moment / (hull.restoring["C44"] - w * w * (hull.inertia_cg[0] + hull.radiation.A44))) / k


def _amplitude(t: np.ndarray, x: np.ndarray, period_s: float, settle_s: float, free_s: float | None = None) -> float:
    """Amplitude of the first harmonic of x over whole periods after settle_s (least squares; with
    the free oscillation at period free_s fitted beside it, for an undamped mode)."""
    keep = t >= settle_s
    n = int((t[keep][-1] - t[keep][0]) / period_s)
    keep &= t < t[keep][0] + n * period_s
    w = 2 * math.pi / period_s
    cols = [np.cos(w * t[keep]), np.sin(w * t[keep]), np.ones(keep.sum())]
    if free_s is not None:
        cols += [np.cos(2 * math.pi / free_s * t[keep]), np.sin(2 * math.pi / free_s * t[keep])]
    A = np.column_stack(cols)
    c, *_ = np.linalg.lstsq(A, x[keep], rcond=None)
    return float(math.hypot(c[0], c[1]))


def barge_rao(vessel: Vessel, mode: str, periods: list[float], height_m: float = 0.02,
              cycles: int = 14) -> list[dict]:
    """Heave (head seas) or roll (beam seas) response of the barge in regular waves of these periods:
    the engine's amplitude per wave amplitude (per wave slope k·a for roll) and the reference."""
    cv = compile_vessel(vessel)
    out = []
    for period in periods:
        sea = waves.Sea(height_m, period, 180.0 if mode == "heave" else 270.0, regular=True)
        six = sixdof.compile_six(cv, sea=sea, terms=Terms().only("added_mass", "damping"),
                                 sea_terms=sixdof.SeaTerms(drift=False))
        t, q, _ = sixdof.free_run(six, cycles * period)
        a = height_m / 2
        k = (2 * math.pi / period) ** 2 / waves.G
        if mode == "heave":
            rao = _amplitude(t, q[:, 2], period, (cycles - 8) * period) / a
            ref = heave_rao_closed_form(six.hull, period)
        else:
            rao = _amplitude(t, q[:, 5], period, (cycles - 8) * period, six.hull.periods["roll"]) / (k * a)
            ref = roll_rao_closed_form(six.hull, period)
        out.append({"period_s": period, "kL": k * BARGE["length_m"], "engine": rao, "reference": ref})
    return out


def drift(vessel: Vessel, height_m: float = 0.02) -> list[dict]:
    """Mean drift force on the barge at rest in regular waves (beam and head seas, short and
    intermediate waves), from the engine's sea load, per ½ρg a² times the illuminated side's length;
    against the published short-wave asymptote (1) times Ursell's barrier reflection R²(kT)."""
    cv = compile_vessel(vessel)
    out = []
    for heading, period in ((270.0, 0.8), (270.0, 1.2), (270.0, 2.0), (180.0, 0.8)):
        sea = waves.Sea(height_m, period, heading, regular=True)
        six = sixdof.compile_six(cv, sea=sea, terms=Terms().only(),
                                 sea_terms=sixdof.SeaTerms(waves=False, diffraction=False, damping=False, drift=True))
        qpos = six.initial_qpos()
        force = np.zeros(six.model.nv)
        samples = []
        for t in np.linspace(0.0, period, 8, endpoint=False):
            fx, fy, fn = sk.sea_load(sixdof.sea_view(six.model), t, qpos, np.zeros(six.model.nv), force,
                                     np.zeros(2))
            samples.append((fx, fy))
        fx, fy = np.mean(samples, axis=0)
        a = height_m / 2
        k = (2 * math.pi / period) ** 2 / waves.G
        side = BARGE["length_m"] if heading == 270.0 else BARGE["beam_m"]
        along = fy if heading == 270.0 else fx
        unit = 0.5 * six.hull.rho * waves.G * a * a * side
        draft = six.hull.draft_m
        out.append({"heading": "beam" if heading == 270.0 else "head", "period_s": period, "kT": k * draft,
                    "engine": along / unit, "short_wave_asymptote": 1.0,
                    "with_reflection": float(sk.reflection_squared(np.array([k]), draft)[0])})
    return out


DRIFT_SETTLE_TIME_CONSTANTS = 5.0  # a start from rest in the waves has died to e⁻⁵ of itself
DRIFT_MIN_SETTLE_S = 20.0
DRIFT_AVERAGE_S = 300.0


def drift_time_constant_s(vessel: Vessel, speed_m_s: float) -> float:
    """(m − X_u̇)/(−X_u − 2 X_uu |u|) at a drift of speed_m_s: how long the hull takes to settle
    into a drift. At a few mm/s only the linear damping holds it: a hull of light linear surge
    damping (the BlueBoat's X_u −0.44 N s/m at 16 kg: 35 s) keeps the start's velocity for minutes."""
    mass = compile_vessel(vessel).geometry.rigid.mass_kg - vessel.added_mass.Xudot
    slope = -(vessel.damping.Xu + 2.0 * vessel.damping.Xuu * abs(speed_m_s))
    return float(mass / slope) if slope > 0 else float("inf")


def free_drift(vessel: Vessel, sea: waves.Sea, duration_s: float | None = None, settle_s: float | None = None
               ) -> dict:
    """A free hull without thrust in `sea`, from rest heading into the waves: its mean velocity after
    `settle_s` (a line through its track) along and across the waves' mean direction, against the
    Stokes drift at the strips' mean depth (waves.stokes_drift): the known flow a 3-DOF twin given
    this sea moves through (sixdof.known_sea_drift). settle_s defaults to DRIFT_SETTLE_TIME_CONSTANTS
    of the hull's drift time constant at the Stokes drift (at least DRIFT_MIN_SETTLE_S), duration_s
    to that plus DRIFT_AVERAGE_S."""
    cv = compile_vessel(vessel)
    six = sixdof.compile_six(cv, sea)
    depth = sixdof.strip_depth_m(six.hull)
    stokes = waves.stokes_drift(six.components, depth)
    tau = drift_time_constant_s(vessel, float(np.hypot(*stokes)))
    if settle_s is None:
        if not math.isfinite(tau):
            raise TwinError(f"{vessel.name}: no surge damping to settle a drift by (X_u, X_uu)")
        settle_s = max(DRIFT_MIN_SETTLE_S, DRIFT_SETTLE_TIME_CONSTANTS * tau)
    duration_s = settle_s + DRIFT_AVERAGE_S if duration_s is None else duration_s
    toward = math.atan2(stokes[1], stokes[0])
    t, q, _ = sixdof.free_run(six, duration_s, sample_every=10, eta0=(0.0, 0.0, toward + math.pi))
    keep = t >= settle_s
    vn, ve = (float(np.polyfit(t[keep], q[keep, i], 1)[0]) for i in (0, 1))
    c, s = math.cos(toward), math.sin(toward)
    x0, x1, _, _ = six.hull.footprint
    return {"sea": sea.text(), "strip_depth_m": depth, "stokes_m_s": float(np.hypot(*stokes)),
            "wavelength_over_length": waves.wavelength_m(sea.tp_s) / (x1 - x0),
            "along_m_s": c * vn + s * ve, "across_m_s": -s * vn + c * ve,
            "heading_end_deg": float(np.rad2deg(q[-1, 3]) % 360.0), "settle_s": float(settle_s),
            "duration_s": float(duration_s), "time_constant_s": tau if math.isfinite(tau) else None,
            "waves_toward_deg": float(np.rad2deg(toward) % 360.0)}


# ---------------------------------------------------------------- speed


def speed_pair(vessel: Vessel, sea_text: str, repeats: int = 5, duration_s: float = 60.0) -> dict:
    """Simulated seconds per wall second of one 3-DOF twin and one 6-DOF twin in the sea, each a run of
    duration_s from rest under the same thrust, on one core, timed in turn (medians over repeats):
    a machine's background load comes and goes, and the pair sees the same."""
    cv = compile_vessel(vessel)
    three = native.with_native_params(cv)
    six = sixdof.compile_six(cv, waves.parse_sea(sea_text))
    nstep = int(round(duration_s / three.opt.timestep))
    d3, d6 = mujoco.MjData(three), mujoco.MjData(six.model)
    w3, w6 = [], []
    with native.installed_native():
        mujoco.mj_step(six.model, d6, 10)  # compile and warm outside the timing
        for _ in range(repeats):
            for model, data, walls, q0 in ((three, d3, w3, None), (six.model, d6, w6, six.initial_qpos())):
                mujoco.mj_resetData(model, data)
                if q0 is not None:
                    data.qpos[:] = q0
                data.ctrl[:2] = (10.0, 8.0)
                t0 = time.perf_counter()
                mujoco.mj_step(model, data, nstep)
                walls.append(time.perf_counter() - t0)
    r3, r6 = duration_s / statistics.median(w3), duration_s / statistics.median(w6)
    return {"vessel": vessel.name, "sea": sea_text, "components": len(six.components),
            "grid_nodes": six.grid.nx * six.grid.ny, "triangles": six.hull.to_dict()["triangles"],
            "three_dof_simsec_per_s": r3, "six_dof_simsec_per_s": r6, "ratio": r6 / r3,
            "three_dof_runs_s": w3, "six_dof_runs_s": w6}
