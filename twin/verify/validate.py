"""`twin validate`: the vessel's inertia, added mass, thrust bounds and
hydrostatics, number by number, from the report's hand formulas, the report's
printed tables, the compiled MuJoCo model, the hull meshes (trimesh) and an
independent computation (MuJoCo's own ellipsoid fluid model, a closed form,
Archimedes on the meshes).

Every difference over 5 % carries a sentence naming the assumption behind it
and the value the twin uses. Printed values that cannot be reproduced from
their own table's inputs are reported as such; inputs are never adjusted.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from ..engine.mjcf import CompiledVessel, actuator_names, compile_vessel, edited_spec
from ..errors import TwinError
from ..physics import added_mass as am
from ..physics.hydrostatics import (RHO_FRESH_KG_M3, equilibrium, submerged_volume, waterline_for_mass,
                                    waterplane_extent)
from ..physics.thrusters import force_torque_bounds
from ..references import YELLOWFISH_TR, CYBERSHIP_I
from ..vessel import Vessel

FLAG_THRESHOLD = 0.05
COLUMNS = ("analytic", "table", "engine", "mesh", "independent")


@dataclass
class Quantity:
    name: str
    unit: str
    analytic: float | None = None
    table: float | None = None
    engine: float | None = None
    mesh: float | None = None
    independent: float | None = None
    reference: str = "table"
    explanation: str = ""
    diff_scale: float | None = None  # what rel_diff is relative to when the value may be near 0 (a coordinate)

    @property
    def rel_diff(self) -> float | None:
        """Largest relative difference of any column from the reference column."""
        ref = getattr(self, self.reference)
        if ref is None:
            ref = next((getattr(self, c) for c in COLUMNS if getattr(self, c) is not None), None)
        others = [getattr(self, c) for c in COLUMNS if getattr(self, c) is not None]
        if ref is None or len(others) < 2:
            return None
        scale = self.diff_scale or (abs(ref) if abs(ref) > 1e-12 else max(abs(x) for x in others))
        return max(abs(x - ref) for x in others) / scale if scale > 0 else 0.0

    @property
    def flag(self) -> bool:
        return self.rel_diff is not None and self.rel_diff > FLAG_THRESHOLD

    def to_dict(self) -> dict:
        d = {k: (float(v) if isinstance(v, (np.floating, np.integer)) else v) for k, v in asdict(self).items()}
        d.pop("reference")
        d["reference_column"] = self.reference
        d["rel_diff"] = None if self.rel_diff is None else float(self.rel_diff)
        d["flag"] = bool(self.flag)
        if not self.flag:
            d["explanation"] = d["explanation"] if self.rel_diff is None else ""
        elif not d["explanation"]:
            d["explanation"] = "no known cause: this difference is not explained by the validation; investigate"
        return d


@dataclass
class Validation:
    vessel: str
    case: str
    quantities: list[Quantity]
    drawing: dict = field(default_factory=dict)  # positions for the top-view figure

    def flagged(self) -> list[Quantity]:
        return [q for q in self.quantities if q.flag]

    def __repr__(self) -> str:
        flagged = ", ".join(q.name for q in self.flagged()) or "none"
        return f"Validation({self.vessel} {self.case}: {len(self.quantities)} quantities, flagged: {flagged})"


# ---------------------------------------------------------------- engine and mesh readers


def _body_id(model: mujoco.MjModel, name: str) -> int:
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if bid < 0:
        raise TwinError(f"model has no body '{name}'")
    return bid


def _inertia_in_vessel_frame(model: mujoco.MjModel, data: mujoco.MjData, bid: int) -> np.ndarray:
    """One body's inertia tensor about its centre of mass, in vessel-frame axes (kg·m², at q = 0)."""
    R = _vessel_rotation(model, data).T @ data.ximat[bid].reshape(3, 3)
    return R @ np.diag(model.body_inertia[bid]) @ R.T


def _vessel_rotation(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    return data.xmat[_body_id(model, "vessel")].reshape(3, 3)


def _in_vessel_frame(model: mujoco.MjModel, data: mujoco.MjData, point: np.ndarray) -> np.ndarray:
    vid = _body_id(model, "vessel")
    return data.xmat[vid].reshape(3, 3).T @ (point - data.xpos[vid])


def _at_rest(model: mujoco.MjModel) -> mujoco.MjData:
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return data


def _check_geometry(compiled: CompiledVessel) -> None:
    model = compiled.model
    vessel_body = _body_id(model, "vessel")
    owned = [g for g in range(model.ngeom) if _root_child(model, model.geom_bodyid[g], vessel_body)]
    if not owned:
        raise TwinError(f"vessel '{compiled.vessel.name}': body 'vessel' has no geometry (no geoms)")


def _root_child(model, bid: int, root: int) -> bool:
    while bid > 0:
        if bid == root:
            return True
        bid = model.body_parentid[bid]
    return False


def load_meshes(vessel: Vessel) -> list[dict]:
    """Each mesh geom of the vessel as the engine compiles it (mass case and CG offset applied): name, body,
    geom id, file, mass (kg), whether the geom is its body's only mass, and the trimesh mesh in the vessel
    frame (m), placed by the compiled model's own kinematics."""
    import trimesh  # late: 0.11 s, only where hull meshes are read (`twin params` loads this module too)

    spec = edited_spec(vessel)
    model = spec.compile()  # compile_vessel has compiled this spec already: no error here
    data = _at_rest(model)
    meshdir = vessel.mjcf.parent / (spec.meshdir or "")
    out = []
    for geom in spec.geoms:
        if geom.type != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        spec_mesh = spec.mesh(geom.meshname)
        path = (meshdir / spec_mesh.file).resolve()
        name = geom.name or f"mesh {path.stem}"
        mesh = trimesh.load(path, force="mesh")
        if not mesh.is_watertight:
            raise TwinError(f"mesh '{path.name}' of geom '{name}' is not watertight: "
                            "its volume and inertia are undefined")
        mesh.apply_transform(_file_to_vessel(model, data, geom.id))
        mass = float(geom.mass) if np.isfinite(geom.mass) else float(geom.density * mesh.volume)
        bid = int(model.geom_bodyid[geom.id])
        out.append({"name": name, "body": model.body(bid).name, "gid": geom.id, "file": path, "mass": mass,
                    "alone": model.body_geomnum[bid] == 1 and not geom.parent.explicitinertial,
                    "mujoco_volume_m3": _mujoco_mesh_volume(spec_mesh, path), "mesh": mesh})
    return out


def _file_to_vessel(model: mujoco.MjModel, data: mujoco.MjData, gid: int) -> np.ndarray:
    """4×4 transform of a mesh file's vertices into the vessel frame. MuJoCo moved the geom frame to the
    mesh's centroid and principal axes (mesh_pos, mesh_quat, in file coordinates), so undo that."""
    mid = model.geom_dataid[gid]
    R_mesh = np.zeros(9)
    mujoco.mju_quat2Mat(R_mesh, model.mesh_quat[mid])
    R_file = data.geom_xmat[gid].reshape(3, 3) @ R_mesh.reshape(3, 3).T
    p_file = data.geom_xpos[gid] - R_file @ model.mesh_pos[mid]
    T = np.eye(4)
    T[:3, :3] = _vessel_rotation(model, data).T @ R_file @ np.diag(model.mesh_scale[mid])
    T[:3, 3] = _in_vessel_frame(model, data, p_file)
    return T


def _mujoco_mesh_volume(spec_mesh, path: Path) -> float:
    """MuJoCo's volume of a mesh (m³): the mass it gives the mesh at unit density, in its own inertia mode."""
    probe = mujoco.MjSpec()
    mesh = probe.add_mesh()
    mesh.name, mesh.file, mesh.scale, mesh.inertia = "hull", str(path), spec_mesh.scale, spec_mesh.inertia
    probe.worldbody.add_body().add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="hull", density=1.0)
    return float(probe.compile().body_mass[1])


def _mujoco_ellipsoid(a: float, b: float, c: float) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's virtual-mass and virtual-inertia coefficients for an ellipsoid (per unit density)."""
    xml = (f'<mujoco><worldbody><body><freejoint/><geom type="ellipsoid" size="{a} {b} {c}" '
           f'fluidshape="ellipsoid" mass="1"/></body></worldbody></mujoco>')
    fluid = mujoco.MjModel.from_xml_string(xml).geom_fluid[0]
    return fluid[6:9].copy(), fluid[9:12].copy()


def _engine_bounds(compiled: CompiledVessel) -> dict[str, float]:
    """Fu and τr extremes from the compiled actuators (ctrl range, gain, site moment arm)."""
    model, data = compiled.model, mujoco.MjData(compiled.model)
    out = {"Fu": [], "tau": []}
    for left in model.actuator_ctrlrange[0]:
        for right in model.actuator_ctrlrange[1]:
            data.ctrl[:2] = (left, right)
            mujoco.mj_forward(model, data)
            out["Fu"].append(data.qfrc_actuator[0])
            out["tau"].append(data.qfrc_actuator[2])
    return {"Fu_min_n": min(out["Fu"]), "Fu_max_n": max(out["Fu"]), "tau_r_max_nm": max(out["tau"])}


# ---------------------------------------------------------------- [Yellowfish-TR]: the Yellowfish


def _yellowfish_tr_inertia(compiled: CompiledVessel, case: str, meshes: list[dict]) -> list[Quantity]:
    S, model = YELLOWFISH_TR, compiled.model
    data = _at_rest(model)
    g = compiled.geometry.rigid
    parts = ("metal_bars_kg", "hulls_kg", "electronics_box_kg", "sensors_kg", "battery_kg")
    m_box_parts = S["metal_bars_kg"][case] + S["electronics_box_kg"][case] + S["sensors_kg"][case] + S["battery_kg"][case]
    m_hull, x_hull, x_box = S["m_hull_kg"][case], S["x_hull_mm"][case], S["x_box_mm"][case]
    m_box, d_g = S["m_box_kg"][case], S["d_g_m"][case]
    xg_eq17 = (2 * x_hull * m_hull + x_box * m_box) / (2 * m_hull + m_box)
    # the analytic column follows the report's own chain, eq. 19 into eq. 18; the table column keeps what it printed
    I_box_eq19 = m_box * (S["a_box_m"] ** 2 + S["b_box_m"] ** 2) / 12.0
    Iz_eq18 = I_box_eq19 + 2 * m_hull * d_g**2
    elec = _body_id(model, "electronics")
    elec_com = _in_vessel_frame(model, data, data.xipos[elec])
    I_elec_com = float(_inertia_in_vessel_frame(model, data, elec)[2, 2])
    I_elec_co = I_elec_com + model.body_mass[elec] * (elec_com[0] ** 2 + elec_com[1] ** 2)

    centroids_mesh = [h["mesh"].center_mass for h in meshes]
    centroids_engine = [_in_vessel_frame(model, data, data.geom_xpos[h["gid"]]) for h in meshes]
    hull_izz_mesh = [_mesh_inertia(h)[2, 2] for h in meshes]
    iz_mesh = I_elec_co + sum(izz + h["mass"] * (c[0] ** 2 + c[1] ** 2)
                              for h, c, izz in zip(meshes, centroids_mesh, hull_izz_mesh)) if meshes else None
    hull_offset_m = _mean([abs(c[1]) for c in centroids_engine])
    return [
        Quantity("m", "kg", analytic=sum(S[p][case] for p in parts), table=S["m_kg"][case], engine=g.mass_kg),
        Quantity("m_box", "kg", analytic=m_box_parts, table=m_box,
                 engine=float(model.body_subtreemass[elec])),
        Quantity("x_hull", "mm", table=x_hull, engine=_mean([1e3 * c[0] for c in centroids_engine]),
                 mesh=_mean([1e3 * c[0] for c in centroids_mesh])),
        Quantity("x_box", "mm", table=x_box, engine=1e3 * float(elec_com[0])),
        Quantity("xg (eq. 17)", "mm", analytic=xg_eq17, table=S["xg_mm"][case], engine=1e3 * g.xg_m),
        Quantity("I_box (eq. 19)", "kg m2", analytic=I_box_eq19, table=S["I_box_kgm2"], engine=I_elec_com,
                 explanation=_i_box_explanation(case, I_box_eq19, I_elec_com)),
        Quantity("d_g (hull axis)", "m", table=d_g, engine=hull_offset_m,
                 explanation="Table V's d_g (0.21/0.30/0.39 m) is not the hull spacing: the hull centres are "
                             "y_m/2 = 0.3375 m from the centreline (Table VI), which the MJCF uses."),
        Quantity("Iz (eq. 18)", "kg m2", analytic=Iz_eq18, table=S["Iz_kgm2"][case], engine=g.Iz_kgm2,
                 mesh=iz_mesh, explanation=_iz_explanation(case, I_box_eq19, Iz_eq18, _mean(hull_izz_mesh),
                                                           hull_offset_m)),
    ]


def _i_box_explanation(case: str, I_box_eq19: float, I_box_engine: float) -> str:
    S = YELLOWFISH_TR
    text = ""
    if abs(I_box_eq19 - S["I_box_kgm2"]) > FLAG_THRESHOLD * S["I_box_kgm2"]:
        text = (f"Table V prints one I_box, {S['I_box_kgm2']} kg m2, for all three cases: eq. 19 with the nominal "
                f"m_box ({S['m_box_kg']['nominal']} kg). With this case's m_box = {S['m_box_kg'][case]} kg, eq. 19 "
                f"gives {I_box_eq19:.3f} kg m2 (analytic column). ")
    if abs(I_box_engine - I_box_eq19) > FLAG_THRESHOLD * I_box_eq19:
        text += ("The engine differs from eq. 19 because eq. 19 spreads all of m_box uniformly over the "
                 "0.50 x 0.52 m box (Assumption 2); the MJCF gives battery, sensors and the 0.8 m metal bars "
                 "their own shapes, and the bars reach past the box. ")
    return text + "The twin uses the engine value."


def _mean(values: list[float]) -> float | None:
    return float(np.mean(values)) if values else None


def _iz_explanation(case: str, I_box_eq19: float, Iz_eq18: float, hull_izz: float | None,
                    hull_offset_m: float | None) -> str:
    S = YELLOWFISH_TR
    if hull_izz is None or hull_offset_m is None:
        text = "eq. 18 counts the hulls as point masses at d_g; this MJCF has no hull meshes to compare with."
    else:
        text = (f"eq. 18 leaves out each hull's own yaw inertia about its centroid (about {hull_izz:.2f} kg m2 "
                f"per 1.28 m hull), uses d_g = {S['d_g_m'][case]:.2f} m instead of the {hull_offset_m:.4g} m hull "
                "offset, and ignores the box group's offset from CO.")
    if abs(I_box_eq19 - S["I_box_kgm2"]) > FLAG_THRESHOLD * S["I_box_kgm2"]:
        text += (f" Table V's Iz = {S['Iz_kgm2'][case]} kg m2 adds its single printed I_box ({S['I_box_kgm2']} kg m2, "
                 f"the nominal one); with this case's own eq. 19 value ({I_box_eq19:.3f} kg m2) eq. 18 gives "
                 f"{Iz_eq18:.3f} kg m2 (analytic column).")
    return text + " The twin uses the engine value (from the MJCF geometry)."


def _mesh_inertia(h: dict) -> np.ndarray:
    """Inertia tensor of a hull mesh about its centroid in vessel-frame axes, uniform density, given mass."""
    return h["mesh"].moment_inertia * h["mass"] / h["mesh"].volume


def _mesh_quantities(compiled: CompiledVessel, meshes: list[dict]) -> list[Quantity]:
    """Each hull mesh's volume, centroid and inertia about its centroid: MuJoCo (engine) against trimesh (mesh)."""
    model = compiled.model
    data = _at_rest(model)
    why = ("MuJoCo and trimesh disagree on this mesh: MuJoCo integrates the closed surface only with "
           'inertia="exact" on the <mesh>; otherwise it uses the convex hull or a legacy approximation.')
    out = []
    for h in meshes:
        n, mesh = h["name"], h["mesh"]
        c_engine = 1e3 * _in_vessel_frame(model, data, data.geom_xpos[h["gid"]])
        length_mm = 1e3 * float(np.max(mesh.extents))  # coordinates near 0 are compared on the hull's length
        out.append(Quantity(f"{n} volume", "L", engine=1e3 * h["mujoco_volume_m3"], mesh=1e3 * mesh.volume,
                            reference="mesh", explanation=why))
        out += [Quantity(f"{n} centroid {axis}", "mm", engine=float(c_engine[i]), mesh=1e3 * float(mesh.center_mass[i]),
                         reference="mesh", diff_scale=length_mm, explanation=why) for i, axis in enumerate("xyz")]
        I_mesh = _mesh_inertia(h)
        if h["alone"]:
            I_engine, note = _inertia_in_vessel_frame(model, data, int(model.geom_bodyid[h["gid"]])), why
        else:
            I_engine, note = None, (f"body '{h['body']}' holds other mass too: the engine has no inertia of "
                                    "this geom alone")
        out += [Quantity(f"{n} I{axis}{axis} (centroid)", "kg m2", mesh=float(I_mesh[i, i]), reference="mesh",
                         engine=None if I_engine is None else float(I_engine[i, i]), explanation=note)
                for i, axis in enumerate("xyz")]
    return out


def _printed_column_match(value: float, computed: dict[str, float]) -> str | None:
    for case, v in computed.items():
        if abs(v - value) <= 0.01 * abs(value):
            return case
    return None


def _yellowfish_tr_added_mass(compiled: CompiledVessel, case: str) -> list[Quantity]:
    S, rho = YELLOWFISH_TR, YELLOWFISH_TR["rho_water_kg_m3"]
    per_case = {c: am.ellipsoid_added_mass(S["a_m"][c], S["b_m"][c], S["c_m"][c], rho) for c in S["a_m"]}
    e = per_case[case]
    a, b, c = S["a_m"][case], S["b_m"][case], S["c_m"][case]
    vm, vi = _mujoco_ellipsoid(a, b, c)
    volume = 4 / 3 * np.pi * a * b * c
    closed = am.ellipsoid_lamb_coefficients_closed_form(a, b, c)
    printed = am.catamaran_added_mass_as_printed(e, S["m_hull_kg"][case], S["y_m_m"])
    mj_single = {"Xudot": -rho * vm[0], "Yvdot": -rho * vm[1], "Nrdot": -rho * vi[2]}
    consistent = am.catamaran_added_mass_consistent(mj_single, S["y_m_m"], S["x_hull_mm"][case] / 1e3)
    used = compiled.vessel.added_mass
    out = []
    for key, name, col in (("alpha0", "alpha0 (eq. 22)", 0), ("beta0", "beta0 (eq. 22)", 1)):
        kappa = vm[col] / volume
        q = Quantity(name, "-", analytic=e[key], table=S[key][case], independent=2 * kappa / (1 + kappa))
        if abs(closed[col] - e[key]) > 1e-9:
            q.explanation = "quadrature and closed form disagree: numerical problem"
        match = _printed_column_match(S[key][case], {k: v[key] for k, v in per_case.items()})
        if match is not None and match != case:
            q.explanation = (f"Table VI's printed {key} for the {case} case cannot be reproduced from the "
                             f"table's own semi-axes (eq. 22 gives {e[key]:.4f}); it equals the value of the "
                             f"{match} case's semi-axes, so the printed columns appear shifted. Xu_dot and "
                             "Yv_dot use eq. 22 with this case's own a, b, c.")
        elif not q.explanation:
            q.explanation = (f"Table VI's printed {key} cannot be reproduced from the table's own semi-axes "
                             f"(eq. 22 gives {e[key]:.4f}).")
        out.append(q)
    for key, name, unit in (("Xudot", "Xu_dot (2 hulls)", "kg"), ("Yvdot", "Yv_dot (2 hulls)", "kg")):
        table = S[f"{key}_kg"]
        computed = {k: 2 * v[key] for k, v in per_case.items()}
        q = Quantity(name, unit, analytic=printed[key], table=table[case], engine=getattr(used, key),
                     independent=consistent[key])
        q.explanation = (_swap_note(name.split()[0], unit, table, computed, case)
                         or f"Table VI's {case} value cannot be reproduced from its own semi-axes. ")
        q.explanation += (f"With this case's own semi-axes eq. 21 gives {printed[key]:.2f} {unit} (analytic column); "
                          f"inputs are not adjusted. The twin uses {getattr(used, key):.2f} {unit} (model file, the "
                          "same for every mass case).")
        out.append(q)
    out.append(Quantity("Nr_dot one ellipsoid (eq. 21)", "kg m2", analytic=e["Nrdot"],
                        independent=mj_single["Nrdot"], reference="analytic"))
    eq25 = {k: am.catamaran_added_mass_as_printed(v, S["m_hull_kg"][k], S["y_m_m"])["Nrdot"] for k, v in per_case.items()}
    out.append(Quantity(
        "Nr_dot (2 hulls, eq. 25)", "kg m2", analytic=printed["Nrdot"], table=S["Nrdot_kgm2"][case],
        engine=used.Nrdot, independent=consistent["Nrdot"],
        explanation="eq. 25 adds the hull's rigid mass times y_m^2 (8.06 kg x 0.675^2 = 3.67 kg m2): rigid "
                    "inertia already in Iz, at the full hull spacing instead of y_m/2. Two ellipsoids each "
                    "carrying their own added mass at (x_hull, +-y_m/2), whose centres move in surge when "
                    f"the vessel yaws, give {consistent['Nrdot']:.2f} kg m2 (independent column, from "
                    f"MuJoCo's ellipsoid coefficients). The twin uses {used.Nrdot:.2f} kg m2."
                    + (" " + _swap_note("Nr_dot", "kg m2", S["Nrdot_kgm2"], eq25, case, "eq. 25")).rstrip()))
    return out


def _swapped(printed: dict[str, float], computed: dict[str, float], tol: float = 0.10) -> bool:
    """Table VI's min and max columns each near the other case's value and not near their own."""
    def near(p, c):
        return abs(p - c) <= tol * abs(p)

    return (near(printed["min"], computed["max"]) and near(printed["max"], computed["min"])
            and not near(printed["min"], computed["min"]) and not near(printed["max"], computed["max"]))


def _swap_note(what: str, unit: str, printed: dict[str, float], computed: dict[str, float], case: str,
               formula: str = "eq. 21") -> str:
    """For the min and max cases, a plain sentence when Table VI's min and max columns look swapped."""
    if case == "nominal" or not _swapped(printed, computed):
        return ""
    other = "max" if case == "min" else "min"
    return (f"Table VI's min and max columns for {what} appear swapped: the printed {case} value, "
            f"{printed[case]:g} {unit}, is near {formula} with the {other} case's semi-axes ({computed[other]:.2f} "
            f"{unit}), and the printed {other} value, {printed[other]:g} {unit}, near {formula} with the {case} "
            f"case's semi-axes ({computed[case]:.2f} {unit}). ")


def _yellowfish_tr_bounds(compiled: CompiledVessel) -> list[Quantity]:
    S = YELLOWFISH_TR
    t = compiled.vessel.thrusters
    analytic = force_torque_bounds(t, (-S["d_thrusters_m"] / 2, S["d_thrusters_m"] / 2))
    engine = _engine_bounds(compiled)
    g = compiled.geometry
    return [
        Quantity("thruster spacing d", "m", table=S["d_thrusters_m"], engine=g.thruster_y_m[1] - g.thruster_y_m[0]),
        Quantity("Fu max (Table VIII)", "N", analytic=analytic["Fu_max_n"], table=S["Fu_max_n"],
                 engine=engine["Fu_max_n"]),
        Quantity("Fu min (Table VIII)", "N", analytic=analytic["Fu_min_n"], table=S["Fu_min_n"],
                 engine=engine["Fu_min_n"]),
        Quantity("tau_r max (Table VIII)", "N m", analytic=analytic["tau_r_max_nm"], table=S["tau_r_max_nm"],
                 engine=engine["tau_r_max_nm"]),
    ]


def _hydrostatics(compiled: CompiledVessel, case: str, meshes: list[dict]) -> tuple[list[Quantity], dict]:
    if not meshes:
        return [], {}
    S = YELLOWFISH_TR if compiled.vessel.name == "yellowfish" else None
    mass = compiled.geometry.rigid.mass_kg
    placed = [(h["mesh"].vertices, h["mesh"].faces) for h in meshes]
    fl = waterline_for_mass(placed, mass, RHO_FRESH_KG_M3)
    # the MJCF's z = 0 is its design waterline: what the meshes displace there says whether it floats the mass
    design_l = 1e3 * sum(submerged_volume(v, f, 0.0)[0] for v, f in placed)
    design_draft_mm = 1e3 * max(float(v[:, 2].max()) for v, _ in placed)
    floats_l = mass / RHO_FRESH_KG_M3 * 1e3
    meshes_say = (f"Below the MJCF's design waterline z = 0 (a {design_draft_mm:.0f} mm draft) the hull meshes "
                  f"displace {design_l:.1f} L; they float {mass:.2f} kg at a {fl['draft_m'] * 1e3:.1f} mm draft.")
    if S is not None:
        ell_l = 1e3 * 2 * (2 / 3) * np.pi * S["a_m"][case] * S["b_m"][case] * S["c_m"][case]
        why = ("the report's semi-axis c is a chosen ellipsoid depth, not a flotation draft: two half-submerged "
               f"ellipsoids of Table VI displace {ell_l:.1f} L, not the {floats_l:.1f} L that float {mass:.2f} kg "
               f"in fresh water. {meshes_say} The hull meshes are an assumed shape with the report's overall "
               "dimensions. The twin keeps the ellipsoid added mass of Table VI's semi-axes until identification.")
    else:
        ell_l = None
        why = (f"{mass:.2f} kg float on {floats_l:.1f} L of fresh water. {meshes_say} The hull lines are assumed, "
               "not published. The 3-DOF twin is planar (no heave, roll or pitch): there the draft enters only "
               "through the parameters the model file's sources derive from it; the 6-DOF hull (--six-dof, --sea) "
               "floats on these meshes.")
    out = [
        Quantity("displaced volume", "L", analytic=floats_l, table=ell_l, mesh=design_l,
                 reference="analytic", explanation=why),
        Quantity("draft at flotation", "mm", table=1e3 * S["c_m"][case] if S else None,
                 mesh=1e3 * fl["draft_m"], reference="mesh", explanation=why),
    ]
    if S is not None:
        out += [
            Quantity("waterline half-length a", "mm", table=1e3 * S["a_m"][case],
                     mesh=0.5e3 * fl["waterline_length_m"], reference="table",
                     explanation="at its flotation draft the assumed hull shape (raked bow, keel rising to the transom) has a "
                                 "shorter waterline than Table VI's 2a; the report does not give the hull lines."),
            Quantity("waterline half-breadth b", "mm", table=1e3 * S["b_m"][case],
                     mesh=0.5e3 * fl["waterline_breadth_m"], reference="table",
                     explanation="Table VI's b for this case is a chosen ellipsoid semi-axis; the hull mesh's "
                                 "waterplane breadth at flotation follows from the 25.5 cm hull [Yellowfish-TR §II-A]."),
        ]
    return out, fl


def _check_propulsors_wet(compiled: CompiledVessel, flotation: dict) -> None:
    """Refuse a thruster, propeller or rudder site above the waterline the hull meshes float the vessel
    at (body z down): it would push from the air. The engine refuses one above the hulls' top at every
    compile; the waterline (a flotation's bisection) is found here."""
    if not flotation:
        return
    z_w = flotation["waterline_z_m"]
    for name, pos in zip(actuator_names(compiled.vessel), compiled.geometry.thruster_pos_m):
        if pos[2] < z_w:
            raise TwinError(f"{compiled.vessel.mjcf.name}: site '{name}' at z = {pos[2]:+.3g} m lies "
                            f"{1e3 * (z_w - pos[2]):.0f} mm above the waterline the hull meshes float "
                            f"{compiled.geometry.rigid.mass_kg:.4g} kg at (z = {z_w:+.3g} m; body z points down): it "
                            "would push from the air")


def _floating_free(compiled: CompiledVessel, meshes: list[dict]) -> list[Quantity]:
    """Where the hull meshes float the vessel free in heave, trim and heel (centre of buoyancy under
    the centre of gravity): the rest of the 6-DOF twin (engine/sixdof.py), from the full meshes."""
    if not meshes:
        return []
    model = compiled.model
    data = _at_rest(model)
    mujoco.mj_comPos(model, data)
    cg = _in_vessel_frame(model, data, data.subtree_com[_body_id(model, "vessel")])
    rho = RHO_FRESH_KG_M3 if compiled.vessel.mmg is None else compiled.vessel.mmg.rho_kg_m3
    placed = [(h["mesh"].vertices, h["mesh"].faces) for h in meshes]
    try:
        z, trim, heel = equilibrium(placed, compiled.geometry.rigid.mass_kg, cg, rho)
    except (TwinError, ValueError, np.linalg.LinAlgError):  # meshes that cannot float it: the draft row says so
        return []
    if not all(np.isfinite([z, trim, heel])):
        return []
    why = ("the rest of the 6-DOF hull: buoyancy equal to the weight, the centre of buoyancy under the centre of "
           f"gravity (z_G = {1e3 * cg[2]:.0f} mm); the 3-DOF twin assumes a level hull")
    return [Quantity("CO below the surface, free", "mm", mesh=1e3 * z, reference="mesh", explanation=why),
            Quantity("trim, free (bow down −)", "deg", mesh=float(np.rad2deg(trim)), reference="mesh", explanation=why),
            Quantity("heel, free", "deg", mesh=float(np.rad2deg(heel)), reference="mesh", explanation=why)]


# ---------------------------------------------------------------- [Bertoni-2024]: CyberShip I


def _cybership_bertoni(compiled: CompiledVessel) -> list[Quantity]:
    hydro = compiled.hydro()
    M, D = hydro.M, hydro.damping.linear_matrix()
    g = compiled.geometry
    out = [Quantity(f"M{i + 1}{j + 1}", "kg" if (i, j) != (2, 2) else "kg m2", table=CYBERSHIP_I["M"][i][j],
                    engine=float(M[i, j])) for i, j in ((0, 0), (1, 1), (1, 2), (2, 2))]
    out += [Quantity(f"D{i + 1}{i + 1}", "SI", table=CYBERSHIP_I["D"][i][i], engine=float(D[i, i])) for i in range(3)]
    out.append(Quantity("thruster spacing d", "m", table=CYBERSHIP_I["d_thrusters_m"],
                        engine=g.thruster_y_m[1] - g.thruster_y_m[0]))
    out.append(Quantity("rigid mass m", "kg", engine=g.rigid.mass_kg, reference="engine",
                        explanation="[Bertoni-2024] gives only the total M; the rigid/added split is an assumption "
                                    "of model/cybership1.json"))
    return out


def _ship_particulars(compiled: CompiledVessel, meshes: list[dict]) -> list[Quantity]:
    """A ship with an MMG description: its published particulars (the vessel file's mmg block) against
    the hull mesh at the design waterline z = 0 (scripts/make_hull_meshes.py builds it from them)."""
    m = compiled.vessel.mmg
    if m is None or not meshes:
        return []
    placed = [(h["mesh"].vertices, h["mesh"].faces) for h in meshes]
    volume_m3 = sum(submerged_volume(v, f, 0.0)[0] for v, f in placed)
    length_m, breadth_m = waterplane_extent(*placed[0], 0.0)
    draft_m = max(float(v[:, 2].max()) for v, _ in placed)
    box_m3 = m.lpp_m * m.breadth_m * m.draft_m
    mass_why = (f"the particulars' displacement L·B·d·C_b = {box_m3 * m.block_coefficient * 1e3:.1f} L floats "
                f"{box_m3 * m.block_coefficient * m.rho_kg_m3:.1f} kg of {m.rho_kg_m3:g} kg/m³ water against the "
                f"published mass {compiled.geometry.rigid.mass_kg:g} kg: the particulars are rounded")
    return [
        Quantity("L_pp (waterline length)", "m", table=m.lpp_m, mesh=length_m),
        Quantity("breadth B", "m", table=m.breadth_m, mesh=breadth_m),
        Quantity("draft d", "m", table=m.draft_m, mesh=draft_m),
        Quantity("block coefficient C_b", "-", table=m.block_coefficient, mesh=volume_m3 / box_m3),
        Quantity("displacement at the draft", "L", analytic=compiled.geometry.rigid.mass_kg / m.rho_kg_m3 * 1e3,
                 table=box_m3 * m.block_coefficient * 1e3, mesh=volume_m3 * 1e3, explanation=mass_why),
    ]


def _generic(compiled: CompiledVessel) -> list[Quantity]:
    r = compiled.geometry.rigid
    return [Quantity("m", "kg", engine=r.mass_kg, reference="engine"),
            Quantity("xg", "mm", engine=1e3 * r.xg_m, reference="engine"),
            Quantity("Iz about CO", "kg m2", engine=r.Iz_kgm2, reference="engine")] + _thruster_bounds(compiled)


def _thruster_bounds(compiled: CompiledVessel) -> list[Quantity]:
    """A twin-thruster vessel's spacing and force and moment bounds: the allocation's hand formula
    [Yellowfish-TR eq. 27] on its own sites against the engine's actuators (none where a thrust has no
    bound, or for a propeller and rudder)."""
    t, g = compiled.vessel.thrusters, compiled.geometry
    if t.kind == "propeller_rudder" or not t.bounded:
        return []
    analytic = force_torque_bounds(t, g.thruster_y_m)
    engine = _engine_bounds(compiled)
    return [Quantity("thruster spacing d", "m", engine=g.thruster_y_m[1] - g.thruster_y_m[0], reference="engine"),
            Quantity("Fu max", "N", analytic=analytic["Fu_max_n"], engine=engine["Fu_max_n"], reference="analytic"),
            Quantity("Fu min", "N", analytic=analytic["Fu_min_n"], engine=engine["Fu_min_n"], reference="analytic"),
            Quantity("tau_r max", "N m", analytic=analytic["tau_r_max_nm"], engine=engine["tau_r_max_nm"], reference="analytic")]


# ---------------------------------------------------------------- entry point


def validate(vessel: Vessel) -> Validation:
    """Every quantity side by side for one vessel and mass case."""
    compiled = compile_vessel(vessel)
    _check_geometry(compiled)
    meshes = load_meshes(vessel)
    case = vessel.case
    if vessel.name == "yellowfish":
        qs = _yellowfish_tr_inertia(compiled, case, meshes) + _yellowfish_tr_added_mass(compiled, case)
        qs += _yellowfish_tr_bounds(compiled)
    elif vessel.name == "cybership1":
        qs = _cybership_bertoni(compiled)
    else:
        qs = _generic(compiled) + _ship_particulars(compiled, meshes)
    qs += _mesh_quantities(compiled, meshes)
    hydro_qs, flotation = _hydrostatics(compiled, case, meshes)
    _check_propulsors_wet(compiled, flotation)
    qs += hydro_qs + _floating_free(compiled, meshes)
    g = compiled.geometry
    drawing = {
        "hulls": [{"outline_xy": _outline(h), "name": h["name"]} for h in meshes],
        "co": [0.0, 0.0],
        "cg_engine": [g.rigid.xg_m, g.rigid.yg_m],
        "cg_analytic": [YELLOWFISH_TR["xg_mm"][case] / 1e3, 0.0] if vessel.name == "yellowfish" else None,
        "thrusters": g.thruster_pos_m[:, :2].tolist(),
        "gnss": g.gnss_pos_m[:2].tolist(),
        "imu": g.imu_pos_m[:2].tolist(),
        "flotation": flotation,
    }
    return Validation(vessel.name, case, qs, drawing)


def _outline(h: dict) -> list[list[float]]:
    """Top-view outline of a hull mesh: its maximum breadth at each station (m)."""
    v = h["mesh"].vertices
    xs = np.linspace(v[:, 0].min(), v[:, 0].max(), 40)
    bins = np.clip(np.digitize(v[:, 0], xs) - 1, 0, len(xs) - 1)
    yc = float(h["mesh"].center_mass[1])
    half = np.array([np.abs(v[bins == i, 1] - yc).max() if np.any(bins == i) else 0.0 for i in range(len(xs))])
    upper = np.column_stack([xs, yc + half])
    lower = np.column_stack([xs[::-1], yc - half[::-1]])
    return np.vstack([upper, lower, upper[:1]]).tolist()


def format_table(name: str, case: str, rows: list[dict]) -> str:
    """The quantities (Quantity.to_dict rows) as a plain-text table that fits 100 columns."""
    def cell(x):
        return f"{'-':>9s}" if x is None else f"{x:9.4g}"

    head = f"{'quantity':30s} {'unit':5s} {'analytic':>9s} {'table':>9s} {'engine':>9s} {'mesh':>9s} " \
           f"{'indep.':>9s} {'diff':>7s}"
    lines = [f"validate {name} ({case})", head, "-" * len(head)]
    for r in rows:
        rel = f"{'-':>7s}" if r["rel_diff"] is None else f"{100 * r['rel_diff']:6.1f}%"
        lines.append(f"{r['name'][:30]:30s} {r['unit'][:5]:5s} " + " ".join(cell(r[c]) for c in (
            "analytic", "table", "engine", "mesh", "independent")) + f" {rel}" + (" !" if r["flag"] else ""))
    return "\n".join(lines)
