"""Build the MuJoCo model of a vessel from its MJCF and vessel file.

The vessel file's mass case, thrust range, thruster gains and lag are applied
to the MJCF through mjSpec, so the MJCF never repeats a parameter of the JSON.
The rigid-body inertia the callbacks and the analytic model use is read back
from the compiled model, so the engine's mass distribution is the only one.

A propeller-and-rudder ship's actuators (`propeller`, `rudder`) exert no force: they carry the
inputs n (rps) and δ (rad) as controls 0 and 1 to the hydrodynamic callback, which applies the
MMG forces; the propeller's and rudder's positions in those forces are their MJCF sites.

A measured, time-varying wind enters as two more controls (`wind_inputs`): actuators
`wind_north`, `wind_east` without force whose controls are the air's velocity over ground
(NED, m/s, where the air goes), held over each step like the thrust commands; the callback
reads them in place of the environment's constant wind.
"""
from __future__ import annotations

import math
import re
from pathlib import Path
from xml.etree import ElementTree
from dataclasses import dataclass

import mujoco
import numpy as np

from ..errors import TwinError
from ..physics import fujiwara, mmg
from ..physics.added_mass import RigidBody, is_symmetric_positive_definite
from ..physics.hydrostatics import RHO_FRESH_KG_M3
from ..physics.hydrodynamics import HydroModel, Terms
from ..vessel import MODEL_DIR, Vessel

ASSETS_DIR = MODEL_DIR.parent / "assets"  # the hull meshes shipped with the package
SHIPPED_MESHDIR = "../assets"  # the shipped MJCFs' meshdir, relative to twin/model

JOINTS = ("north", "east", "yaw")
THRUSTERS = ("thruster_left", "thruster_right")
PROPELLER_RUDDER = ("propeller", "rudder")
WIND_ACTUATORS = ("wind_north", "wind_east")


def actuator_names(vessel: Vessel) -> tuple[str, str]:
    """The two input actuators (and their sites) of the vessel's kind of thrusters."""
    return PROPELLER_RUDDER if vessel.thrusters.kind == "propeller_rudder" else THRUSTERS


@dataclass(frozen=True)
class Geometry:
    """What the compiled MJCF says about the vessel, in the body frame (m, kg)."""

    rigid: RigidBody
    thruster_pos_m: np.ndarray  # (2, 3): left, right thrusters, or the propeller and the rudder
    gnss_pos_m: np.ndarray  # (3,)
    imu_pos_m: np.ndarray  # (3,)
    length_m: float = 0.0  # length overall, the geoms' fore-and-aft extent

    @property
    def thruster_y_m(self) -> tuple[float, float]:
        return float(self.thruster_pos_m[0, 1]), float(self.thruster_pos_m[1, 1])


@dataclass
class CompiledVessel:
    """A vessel with its MuJoCo model (compiled from its MJCF and vessel file: `compile_vessel`) and
    the geometry read from that model (rigid-body mass, CG, yaw inertia, site positions)."""

    vessel: Vessel
    model: mujoco.MjModel
    geometry: Geometry

    def hydro(self, terms: Terms | None = None) -> HydroModel:
        """The hydrodynamic model the callbacks evaluate (M_RB, M_A, damping, thrusters), with the
        terms switched on or off by `terms` (default: every term)."""
        return hydro_model(self.vessel, self.geometry, terms)

    @property
    def wind_inputs(self) -> bool:
        """Whether the model takes the wind as controls 2 and 3 (`compile_vessel(..., wind_inputs=True)`)."""
        return wind_control(self.model) >= 0


# attributes that name things or hold text (a body called "nan" is a name, not a number)
NAMING = {"name", "file", "class", "childclass", "model", "mesh", "material", "texture", "hfield", "joint", "joint1",
          "joint2", "jointinparent", "site", "refsite", "cranksite", "slidersite", "body", "body1", "body2",
          "geom", "geom1", "geom2", "tendon", "tendon1", "tendon2", "actuator", "target", "objname", "refname",
          "objtype", "reftype", "plugin", "instance", "meshdir", "texturedir", "assetdir", "content_type",
          "prefix", "type", "integrator", "data", "key", "value"}


def _check_numbers(path: Path, seen: frozenset = frozenset()) -> None:
    """Refuse an MJCF attribute whose numbers hold NaN or infinity (in the file or the files it
    includes): MuJoCo reads it with a warning and then derives the value another way (a geom's NaN
    mass from its volume), so the vessel would run with numbers nobody wrote."""
    path = Path(path)
    try:
        root = ElementTree.parse(path).getroot()
    except (OSError, ElementTree.ParseError):
        return  # MuJoCo's own reader says what is wrong with the file
    for element in root.iter():
        if element.tag == "include" and element.get("file") and path.resolve() not in seen:
            _check_numbers(path.parent / element.get("file"), seen | {path.resolve()})
        if element.tag in ("text", "numeric", "tuple", "custom"):
            continue  # a user's own data, not MuJoCo's numbers
        for key, value in element.attrib.items():
            if key in NAMING or not value.split():
                continue
            try:
                numbers = [float(x) for x in value.split()]
            except ValueError:
                continue  # a word: not a number MuJoCo would read as one
            if not all(math.isfinite(x) for x in numbers):
                raise TwinError(f"{path.name}: <{element.tag}> {key}=\"{value}\" is not a finite number")


def _spec(vessel: Vessel) -> mujoco.MjSpec:
    _check_numbers(vessel.mjcf)
    try:
        spec = mujoco.MjSpec.from_file(str(vessel.mjcf))
    except Exception as exc:  # MuJoCo raises ValueError with the parser message
        raise TwinError(f"{vessel.mjcf.name}{mujoco_message(exc, 'malformed MJCF')}") from None
    _shipped_meshes(spec, Path(vessel.mjcf).parent)
    return spec


def _shipped_meshes(spec: mujoco.MjSpec, folder: Path) -> None:
    """A shipped MJCF copied elsewhere still finds its hull meshes: when a mesh file is missing from
    the MJCF's own mesh folder (meshdir, relative to the MJCF) and the package ships one of that
    name, the package's folder is used. Only for the shipped MJCFs' own meshdir (../assets): a
    meshdir of the user's that names no folder is said, not replaced by the package's meshes."""
    if (spec.meshdir or "").rstrip("/") != SHIPPED_MESHDIR:
        return
    own = folder / (spec.meshdir or "")
    files = [m.file for m in spec.meshes if m.file]
    if files and not all((own / f).is_file() for f in files) and all((ASSETS_DIR / f).is_file() for f in files):
        spec.meshdir = str(ASSETS_DIR)


def mujoco_message(exc: Exception, what: str) -> str:
    """MuJoCo's multi-line parser or compiler message on one line: ', line N: WHAT (reason)'.

    tinyxml2 says 'XML parse error 14:' then 'Error=XML_ERROR_MISMATCHED_ELEMENT ... Line number=2:
    XMLElement name=body'; the schema and compiler say 'XML Error: reason' or 'Error: reason' then
    "Element 'geom', line 5" or "Element name 'hull', id 1, line 5"."""
    text = str(exc).strip() or type(exc).__name__
    line = re.search(r"[Ll]ine(?: number)?[ =](\d+)", text)
    element = re.search(r"Element (?:name )?'([^']+)'", text)
    xml = re.search(r"Error=(XML_\w+).*?Line number=\d+:?\s*(.*)", text)
    if xml:
        reason = xml.group(1) + (f": {xml.group(2).strip()}" if xml.group(2).strip() else "")
    else:
        reason = re.sub(r"^(XML )?Error:\s*", "", text.splitlines()[0].strip())
    where = (f", line {line.group(1)}" if line else "") + (f", element '{element.group(1)}'" if element else "")
    return f"{where}: {what} ({reason})"


def _file_of(vessel: Vessel) -> str:
    """'NAME.json: ' of the vessel file a vessel was read from, '' for one built in code."""
    return f"{Path(vessel.path).name}: " if vessel.path is not None else ""


def _apply_case(vessel: Vessel, spec: mujoco.MjSpec) -> None:
    if vessel.case == "nominal":
        return
    case = vessel.cases[vessel.case]  # its names checked (_check_case_names)
    for name, mass in case.geom_mass_kg.items():
        spec.geom(name).mass = mass
    for name, x in case.body_x_m.items():
        spec.body(name).pos[0] = x


def _apply_propeller_rudder(vessel: Vessel, spec: mujoco.MjSpec) -> None:
    """The propeller's and rudder's actuators carry n and δ: no gain, no bias, no range, no dynamics."""
    for name in PROPELLER_RUDDER:
        act = spec.actuator(name)
        if act is None:
            raise TwinError(f"{vessel.mjcf.name}: no actuator '{name}' (a propeller-and-rudder ship needs "
                            "actuators 'propeller' and 'rudder')")
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        act.gaintype, act.biastype = mujoco.mjtGain.mjGAIN_FIXED, mujoco.mjtBias.mjBIAS_NONE
        act.gainprm[0] = 0.0
        act.dyntype = mujoco.mjtDyn.mjDYN_NONE


def add_wind_inputs(spec: mujoco.MjSpec) -> None:
    """Two force-free actuators after the vessel's own whose controls carry the wind (module docstring)."""
    for name in WIND_ACTUATORS:
        act = spec.add_actuator()
        act.name = name
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.target = JOINTS[0]
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        act.gaintype, act.biastype = mujoco.mjtGain.mjGAIN_FIXED, mujoco.mjtBias.mjBIAS_NONE
        act.gainprm[0] = 0.0


def wind_control(model: mujoco.MjModel) -> int:
    """Index of the wind's first control (wind_north; wind_east follows), −1 without wind inputs."""
    first = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, WIND_ACTUATORS[0])
    second = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, WIND_ACTUATORS[1])
    return first if first >= 0 and second == first + 1 else -1


def _apply_thrusters(vessel: Vessel, spec: mujoco.MjSpec) -> None:
    t = vessel.thrusters
    if t.kind == "propeller_rudder":
        _apply_propeller_rudder(vessel, spec)
        return
    t_min, t_max = t.bounds()
    for name, gain in zip(THRUSTERS, t.gains()):
        act = spec.actuator(name)
        if act is None:
            raise TwinError(f"{vessel.mjcf.name}: no actuator '{name}' (a {t.kind} vessel has two thrusters, actuators "
                            f"'{THRUSTERS[0]}' and '{THRUSTERS[1]}'; a one-propeller ship is a propeller_rudder "
                            "vessel: docs/reference/vessel-file.md)")
        if t.bounded:  # an unbounded thruster (no bound in its source) is not limited
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrlrange = [t_min, t_max]
        else:
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        act.gainprm[0] = gain  # the advance loss is the hydrodynamic callback's (physics/hydrodynamics.py)
        if t.lag_s > 0:
            # MuJoCo integrates the first-order thrust lag [Morel-2024 eq. 15] as actuator state.
            # "filter", not "filterexact": under RK4 the latter lags by about half a step
            act.dyntype = mujoco.mjtDyn.mjDYN_FILTER
            act.dynprm[0] = t.lag_s


def _apply_cg_offset(vessel: Vessel, spec: mujoco.MjSpec) -> None:
    """Move every mass of the vessel body by cg_offset_m (x, y); its sites stay where they are."""
    dx, dy = vessel.cg_offset_m
    if dx == 0.0 and dy == 0.0:
        return
    hull = next((j.parent for j in spec.joints if j.name == JOINTS[0]), None)
    if hull is None:
        raise TwinError(f"{vessel.mjcf.name}: missing planar joint '{JOINTS[0]}'")
    for item in [*hull.bodies, *hull.geoms]:
        item.pos[0] += dx
        item.pos[1] += dy


def edited_spec(vessel: Vessel, wind_inputs: bool = False) -> mujoco.MjSpec:
    """The vessel's MJCF with the vessel file's mass case, CG offset and thruster settings applied
    (and the wind's two controls when `wind_inputs`)."""
    spec = _spec(vessel)
    _check_case_names(vessel, spec)
    _apply_case(vessel, spec)
    _apply_cg_offset(vessel, spec)
    _apply_thrusters(vessel, spec)
    if wind_inputs:
        add_wind_inputs(spec)
    return spec


def make_lean(spec: mujoco.MjSpec, rigid: RigidBody) -> mujoco.MjSpec:
    """The spec with the vessel's parts (meshes, geoms, welded bodies) replaced by one inertial of
    the same planar M_RB (`rigid`, about CO), in place; sites, joints and actuators kept.

    On three planar joints only the mass, the CG's (x, y) and the yaw inertia move the hull, so
    the dynamics are those of the full model up to round-off, at a sixth less time per step
    (kinematics of five bodies and seven geoms, four times per RK4 step). A vessel whose sites
    or joints sit in its welded bodies is left whole."""
    hull = next((j.parent for j in spec.joints if j.name == JOINTS[0]), None)
    if hull is None:
        return spec
    parts = hull.find_all(mujoco.mjtObj.mjOBJ_BODY)  # every body welded below the hull
    if any(b.sites or b.joints or b.cameras for b in parts):
        return spec
    for b in hull.bodies:
        spec.delete(b)
    for g in list(hull.geoms):
        spec.delete(g)
    for mesh in list(spec.meshes):
        spec.delete(mesh)
    m, xg, yg = rigid.mass_kg, rigid.xg_m, rigid.yg_m
    izz = rigid.Iz_kgm2 - m * (xg * xg + yg * yg)  # about the CG (parallel axes)
    hull.explicitinertial = True
    hull.mass = m
    hull.ipos = [xg, yg, 0.0]
    hull.iquat = [1.0, 0.0, 0.0, 0.0]
    hull.inertia = [izz, izz, izz]  # only the yaw axis turns; equal axes keep MuJoCo's inertia checks happy
    return spec


def compile_vessel(vessel: Vessel, wind_inputs: bool = False) -> CompiledVessel:
    """The vessel's MuJoCo model, its geometry and checks; `wind_inputs`: with the wind as controls."""
    spec = edited_spec(vessel, wind_inputs)
    _check_masses(vessel, spec)
    try:
        model = spec.compile()
    except Exception as exc:
        if "mass and inertia" in str(exc):
            body = re.search(r"Element name '([^']+)'", str(exc))
            raise TwinError(f"{vessel.mjcf.name}: zero mass or inertia in body {body.group(1) if body else '?'} "
                            "(every moving body needs a positive mass and inertia)") from None
        raise TwinError(f"{vessel.mjcf.name}{mujoco_message(exc, 'cannot compile')}") from None
    for j in JOINTS:
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) < 0:
            raise TwinError(f"{vessel.mjcf.name}: missing planar joint '{j}' (north, east, yaw)")
    if model.nv != 3:
        raise TwinError(f"{vessel.mjcf.name}: expected 3 degrees of freedom (north, east, yaw), got {model.nv}")
    _check_joints(vessel, model)
    _check_gears(vessel, model)
    if not 0 < model.opt.timestep < 1:  # MuJoCo takes 0 (and a step of a second misses every lag)
        raise TwinError(f"{vessel.mjcf.name}: option timestep must lie between 0 and 1 s, got {model.opt.timestep:g}")
    geometry = read_geometry(model, vessel)
    _check_floats(vessel, model, geometry.rigid.mass_kg)
    _check_fits_its_box(vessel, model, geometry.rigid.mass_kg)
    _check_sites(vessel, model, geometry)
    _check_sides(vessel, geometry)
    _check_added_mass_scale(vessel, geometry)
    compiled = CompiledVessel(vessel, model, geometry)
    M = compiled.hydro().M
    if not is_symmetric_positive_definite(M):
        raise TwinError(f"vessel '{vessel.name}': M = M_RB + M_A is not symmetric positive-definite")
    return compiled


# a vessel heavier than this many times what its hull meshes displace fully submerged has its masses
# in another unit (grams for kilograms), not a hull that floats low; a mesh that is no closed hull
# (a mast, a deck) makes the displacement only larger
SINKS_AT = 10.0


def mesh_volume_m3(model: mujoco.MjModel) -> float:
    """The volume (m³) of the model's mesh geoms: what its hulls displace fully submerged (0 without
    meshes)."""
    volume_m3 = 0.0
    for gid in np.flatnonzero(model.geom_type == mujoco.mjtGeom.mjGEOM_MESH):
        mid = model.geom_dataid[gid]
        v0, nv = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
        f0, nf = model.mesh_faceadr[mid], model.mesh_facenum[mid]
        tri = model.mesh_vert[v0:v0 + nv][model.mesh_face[f0:f0 + nf]]
        volume_m3 += abs(float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum())) / 6.0
    return volume_m3


def _check_floats(vessel: Vessel, model: mujoco.MjModel, mass_kg: float) -> None:
    """Refuse a vessel its hull meshes cannot float, fully submerged (masses in another unit, past
    SINKS_AT times, said so); a vessel without meshes is not judged here."""
    displaced_kg = RHO_FRESH_KG_M3 * mesh_volume_m3(model)
    if displaced_kg > 0 and mass_kg > displaced_kg:
        unit = (f" ({vessel.mjcf.name}'s masses are in kg)" if mass_kg > SINKS_AT * displaced_kg else
                " (every mesh geom counts as hull: docs/reference/vessel-file.md)")
        raise TwinError(f"{_file_of(vessel) or vessel.mjcf.name + ': '}the vessel's {mass_kg:.6g} kg cannot float: its "
                        f"hull meshes displace {displaced_kg:.4g} kg fully submerged{unit}")


def _check_fits_its_box(vessel: Vessel, model: mujoco.MjModel, mass_kg: float) -> None:
    """Refuse masses in another unit by the box around the vessel's geoms: a floating vessel displaces
    less water than that box holds, and SINKS_AT times as much leaves room for geoms drawn smaller than
    the hull (a marker box beside an <inertial>) while grams for kilograms stay far beyond it."""
    extent_m = _extent_m(model)
    box_kg = RHO_FRESH_KG_M3 * float(np.prod(extent_m))
    if box_kg > 0 and mass_kg > SINKS_AT * box_kg:
        raise TwinError(f"{vessel.mjcf.name}: the vessel's {mass_kg:.6g} kg cannot float: the box around its geoms "
                        f"({' x '.join(f'{x:.3g}' for x in extent_m)} m) holds {box_kg:.4g} kg of water (the MJCF's "
                        "masses are in kg and its lengths in m)")


def _extent_m(model: mujoco.MjModel) -> np.ndarray:
    """(3,) the extent (m) along body x, y, z of every geom of the vessel's bodies at q = 0."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    points = []
    for g in np.flatnonzero(model.geom_bodyid > 0):
        centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        corners = centre + half * np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        points.append(data.geom_xpos[g] + corners @ data.geom_xmat[g].reshape(3, 3).T)
    return np.ptp(np.vstack(points), axis=0) if points else np.zeros(3)


# an added mass this many times the rigid body's (or an added inertia as many times its inertia) is a
# unit slip (grams, a yaw term in kg·cm²), not a hull: a floating hull's is of the order of its own
ADDED_MASS_AT_MOST = 50.0


def _check_added_mass_scale(vessel: Vessel, geometry: Geometry) -> None:
    """Refuse an added mass or inertia in another unit (ADDED_MASS_AT_MOST times the rigid body's)."""
    rigid, a = geometry.rigid, vessel.added_mass
    for name, value, own, unit in (("Xudot", a.Xudot, rigid.mass_kg, "kg"), ("Yvdot", a.Yvdot, rigid.mass_kg, "kg"),
                                   ("Nrdot", a.Nrdot, rigid.Iz_kgm2, "kg·m²")):
        if own > 0 and abs(value) > ADDED_MASS_AT_MOST * own:
            where = vessel.path.name if vessel.path is not None else f"vessel '{vessel.name}'"
            raise TwinError(f"{where}: added_mass.{name} {value:g} {unit} is {abs(value) / own:.0f} "
                            f"times the rigid body's {own:.4g} {unit}: a hull's added mass is of the order of its "
                            f"own (the vessel file's added mass is in {unit})")


SIDES_APART_M = 0.01  # two thrusters closer athwartships than this give no moment to turn by: one site written twice


def _check_sides(vessel: Vessel, geometry: Geometry) -> None:
    """Refuse a left thruster to starboard of the right one: body y points to starboard (FRD), and a
    site written in a forward-left-up frame mirrors the boat, so every differential thrust turns the
    twin the other way from the vessel."""
    if vessel.thrusters.kind == "propeller_rudder" or len(geometry.thruster_pos_m) != 2:
        return
    left, right = (float(p[1]) for p in geometry.thruster_pos_m)
    if abs(left - right) < SIDES_APART_M:
        names = actuator_names(vessel)
        raise TwinError(f"{vessel.mjcf.name}: sites '{names[0]}' and '{names[1]}' both at y = {left:+.3g} m: a "
                        "twin-thruster vessel turns by the difference of their thrusts, which needs them apart "
                        "(the left one at the smaller y: body y points to starboard)")
    if left > right:
        names = actuator_names(vessel)
        raise TwinError(f"{vessel.mjcf.name}: site '{names[0]}' at y = {left:+.3g} m lies to starboard of "
                        f"'{names[1]}' at y = {right:+.3g} m: body y points to starboard (x forward, y to starboard, "
                        "z down), so the left thruster's y is the smaller; swap the two sites' y")


def _check_sites(vessel: Vessel, model: mujoco.MjModel, geometry: Geometry) -> None:
    """Refuse a thruster or sensor site far outside the vessel (its position in mm for m): the twin
    would run with a lever arm of hundreds of metres and diverge, or say nothing."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    # the hull's own reach from the origin (its geoms; MuJoCo's stat.extent counts the sites too)
    hull_m = float(np.max(np.linalg.norm(data.geom_xpos[:, :2], axis=1) + model.geom_rbound)) if model.ngeom else 1.0
    named = list(zip(actuator_names(vessel), geometry.thruster_pos_m)) + [("gnss", geometry.gnss_pos_m),
                                                                          ("imu", geometry.imu_pos_m)]
    for name, pos in named:
        if float(np.linalg.norm(np.asarray(pos)[:2])) > 2.0 * hull_m + 1.0:
            raise TwinError(f"{vessel.mjcf.name}: site '{name}' at ({', '.join(f'{x:g}' for x in pos)}) m lies "
                            f"far beyond the hull, which reaches {hull_m:.3g} m from the origin (positions are in m)")
    antenna = np.asarray(geometry.gnss_pos_m)[:2] + np.asarray(vessel.sensors.antenna_offset_m, float)
    if float(np.linalg.norm(antenna)) > 2.0 * hull_m + 1.0:
        raise TwinError(f"{_file_of(vessel)}sensors.antenna_offset_m {list(vessel.sensors.antenna_offset_m)} puts the "
                        f"GNSS antenna at ({antenna[0]:g}, {antenna[1]:g}) m, far beyond the hull, which reaches "
                        f"{hull_m:.3g} m from the origin (the offset is in m)")


# what each planar joint must be, in this order: the twin reads qpos/qvel as (north, east, ψ)
_JOINT_FORM = {"north": (mujoco.mjtJoint.mjJNT_SLIDE, (1.0, 0.0, 0.0)),
               "east": (mujoco.mjtJoint.mjJNT_SLIDE, (0.0, 1.0, 0.0)),
               "yaw": (mujoco.mjtJoint.mjJNT_HINGE, (0.0, 0.0, 1.0))}


def _check_joints(vessel: Vessel, model: mujoco.MjModel) -> None:
    """The planar joints in order north, east, yaw: slides along world x (north) and y (east) and a hinge
    about z (down, FRD), each axis as given (a reversed or swapped one mirrors the boat)."""
    for k, name in enumerate(JOINTS):
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        kind, axis = _JOINT_FORM[name]
        if model.jnt_dofadr[j] != k:
            raise TwinError(f"{vessel.mjcf.name}: joint '{name}' is degree of freedom {model.jnt_dofadr[j] + 1}; the "
                            f"planar joints go in the order {', '.join(JOINTS)}")
        if model.jnt_type[j] != kind or not np.allclose(model.jnt_axis[j], axis, atol=1e-9):
            raise TwinError(f"{vessel.mjcf.name}: joint '{name}' must be {_joint_text(kind, axis)}, got "
                            f"{_joint_text(model.jnt_type[j], model.jnt_axis[j])}")


def _joint_text(kind, axis) -> str:
    """'a slide with axis="1 0 0"': a joint as its MJCF says it."""
    word = {mujoco.mjtJoint.mjJNT_SLIDE: "a slide", mujoco.mjtJoint.mjJNT_HINGE: "a hinge"}.get(int(kind),
                                                                                             "a joint of another kind")
    return f"{word} with axis=\"{' '.join(f'{a:g}' for a in axis)}\""


def _check_gears(vessel: Vessel, model: mujoco.MjModel) -> None:
    """A thruster pushes along body x, ahead for a positive thrust: gear="1 0 0 0 0 0" on a site whose
    x axis is the hull's. A gear or a site turned off body x (toe-in, a tilt) would steer the boat with its
    forward thrust, while the allocation, the force bounds and the analytic 3-DOF model push along x;
    a site above the hulls' top would push from the air."""
    if vessel.thrusters.kind == "propeller_rudder":
        return
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    top_m = _hull_top_m(model, data)
    for name in THRUSTERS:
        a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        gear = model.actuator_gear[a]
        if not np.allclose(gear, (1.0, 0, 0, 0, 0, 0), atol=1e-9):
            raise TwinError(f"{vessel.mjcf.name}: actuator '{name}' has gear=\"{' '.join(f'{g:g}' for g in gear)}\"; a "
                            "thruster pushes along body x, gear=\"1 0 0 0 0 0\" (its thrust map gives the sign)")
        if model.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_SITE:
            raise TwinError(f"{vessel.mjcf.name}: actuator '{name}' acts on a joint or body; a thruster acts at its "
                            f"site (site=\"{name}\")")
        site = int(model.actuator_trnid[a, 0])
        site_name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, site)
        # the thrust acts along the site's x axis; at q = 0 the world frame is the body frame
        thrust_axis = data.site_xmat[site].reshape(3, 3)[:, 0]
        if not np.allclose(thrust_axis, (1.0, 0.0, 0.0), atol=1e-6):
            angle_deg = np.degrees(np.arccos(np.clip(thrust_axis[0], -1.0, 1.0)))
            raise TwinError(f"{vessel.mjcf.name}: site '{site_name}' of actuator '{name}' pushes {angle_deg:.3g}° off "
                            "body x (its euler, quat, axisangle, xyaxes or zaxis, or its body's, turns it); a thruster "
                            "pushes along body x: give the site no yaw or pitch")
        z_m = float(data.site_xpos[site, 2])
        if top_m is not None and z_m < top_m:
            raise TwinError(f"{vessel.mjcf.name}: site '{site_name}' at z = {z_m:+.3g} m lies above the hulls' top "
                            f"(z = {top_m:+.3g} m; body z points down): a thruster in the air gives no thrust")


def _hull_top_m(model: mujoco.MjModel, data: mujoco.MjData) -> float | None:
    """The highest point (smallest z, body FRD at q = 0) of the vessel's mesh geoms; None without meshes."""
    tops = []
    for g in np.flatnonzero(model.geom_type == mujoco.mjtGeom.mjGEOM_MESH):
        mid = model.geom_dataid[g]
        v0, nv = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
        verts = model.mesh_vert[v0:v0 + nv] @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
        tops.append(float(verts[:, 2].min()))
    return min(tops) if tops else None


def _check_case_names(vessel: Vessel, spec: mujoco.MjSpec) -> None:
    """Every mass case names geoms and bodies the MJCF has, checked whichever case is loaded (a typo
    would otherwise wait for the day that case is used), before any case is applied."""
    geoms, bodies = {g.name for g in spec.geoms}, {b.name for b in spec.bodies}
    for case, mass_case in vessel.cases.items():
        for name in mass_case.geom_mass_kg:
            if name not in geoms:
                raise TwinError(f"{_file_of(vessel)}cases.{case}.geom_mass_kg names geom '{name}', which "
                                f"{vessel.mjcf.name} does not have")
        for name in mass_case.body_x_m:
            if name not in bodies:
                raise TwinError(f"{_file_of(vessel)}cases.{case}.body_x_m names body '{name}', which "
                                f"{vessel.mjcf.name} does not have")


def _check_masses(vessel: Vessel, spec: mujoco.MjSpec) -> None:
    """Every part must weigh something. MuJoCo accepts a massless geom (or <inertial>) on a body welded
    to a heavier one, so a hull with mass="0" would silently drop out of M_RB and of the validation."""
    for body in spec.bodies[1:]:
        name = body.name or "(unnamed)"
        if body.explicitinertial:
            if not body.mass > 0:
                raise TwinError(f"{vessel.mjcf.name}: {_sign(body.mass)} mass in body {name}: its <inertial> "
                                f"has mass {body.mass:g} kg (every part of the vessel needs a positive mass)")
            continue
        for geom in body.geoms:
            part = f"geom '{geom.name}'" if geom.name else f"its unnamed {_geom_type(geom)} geom"
            if np.isfinite(geom.mass) and not geom.mass > 0:
                raise TwinError(f"{vessel.mjcf.name}: {_sign(geom.mass)} mass in body {name}: {part} has mass "
                                f"{geom.mass:g} kg (every part of the vessel needs a positive mass)")
            if not np.isfinite(geom.mass) and not geom.density > 0:
                raise TwinError(f"{vessel.mjcf.name}: {_sign(geom.density)} mass in body {name}: {part} has "
                                f"density {geom.density:g} kg/m³ (every part of the vessel needs a positive mass)")


def _sign(x: float) -> str:
    return "zero" if x == 0 else "negative" if x < 0 else "undefined"


def _geom_type(geom) -> str:
    return str(geom.type).rsplit("mjGEOM_", 1)[-1].lower()


def _site(model: mujoco.MjModel, data: mujoco.MjData, name: str, vessel: Vessel) -> np.ndarray:
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid < 0:
        raise TwinError(f"{vessel.mjcf.name}: missing site '{name}'")
    return data.site_xpos[sid].copy()  # at q = 0 the world frame is the body frame


def read_geometry(model: mujoco.MjModel, vessel: Vessel) -> Geometry:
    """Rigid M_RB about CO and the site positions, from the model at q = 0."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    M = np.zeros((3, 3))
    mujoco.mj_fullM(model, data, M)
    m = M[0, 0]
    if not m > 0:
        raise TwinError(f"{vessel.mjcf.name}: the vessel has no mass")
    rigid = RigidBody(mass_kg=float(m), xg_m=float(M[1, 2] / m), yg_m=float(-M[0, 2] / m), Iz_kgm2=float(M[2, 2]))
    thrusters = np.array([_site(model, data, n, vessel) for n in actuator_names(vessel)])
    return Geometry(rigid, thrusters, _site(model, data, "gnss", vessel), _site(model, data, "imu", vessel),
                    _length_m(model, data))


def _length_m(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """The hull's length overall (m): the fore-and-aft extent of every geom of the vessel's bodies (each
    geom's bounding box turned into the body frame, which at q = 0 is the world frame)."""
    ends = []
    for g in np.flatnonzero(model.geom_bodyid > 0):
        centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        corners = centre + half * np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        x = data.geom_xpos[g, 0] + corners @ data.geom_xmat[g].reshape(3, 3)[0]
        ends += [float(x.min()), float(x.max())]
    return max(ends) - min(ends) if ends else 0.0


def hydro_model(vessel: Vessel, geometry: Geometry, terms: Terms | None = None) -> HydroModel:
    """The force functions' numbers: the vessel file's, with M_RB and (for a propeller-and-rudder
    ship) the propeller's and rudder's positions from the compiled MJCF."""
    mmg_params = None
    if vessel.mmg is not None:
        n_bounds, delta_bounds = vessel.thrusters.channel_bounds()
        mmg_params = mmg.pack(vessel.mmg, float(geometry.thruster_pos_m[0, 0]), float(geometry.thruster_pos_m[1, 0]),
                              n_bounds, delta_bounds[1])
    return HydroModel(
        M_RB=geometry.rigid.matrix(),
        M_A=vessel.added_mass.matrix(),
        damping=vessel.damping,
        wind_load=vessel.wind_load,
        environment=vessel.environment,
        terms=terms or Terms(),
        mmg=mmg_params,
        wind_regression=None if vessel.wind_regression is None else fujiwara.pack(vessel.wind_regression),
        munk_moment=vessel.mmg is None,  # an MMG hull's N'_v holds the Munk moment (eq. 4)
        advance_loss=vessel.thrusters.advance_loss if vessel.mmg is None else 0.0,
        thruster_y_m=geometry.thruster_y_m,
    )
