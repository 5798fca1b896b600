"""A twin-thruster vessel's hull and propulsor coefficients from first principles on its own
geometry: the hull meshes floating the vessel's mass, the thruster sites, and the `design` block
of its vessel file (top speed, form factor, cross-flow drag coefficient, duct and propeller
diameters). Each coefficient comes with the method that gave it (physics/priors.py).

`twin params --vessel NAME --first-principles` prints the table; the shipped BlueBoat file holds
these values as its prior (tests/test_priors.py checks that they agree), and identification
moves them only as far as the recordings support.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..engine.mjcf import compile_vessel
from ..errors import TwinError
from ..physics.added_mass import half_body_added_mass
from ..physics.hydrostatics import (RHO_FRESH_KG_M3, clip_triangle, submerged_volume, waterline_for_mass,
                                    waterplane_extent)
from ..physics.priors import (SpeedDerivatives, cross_flow_drag, lateral_profile, propulsor_at_rest,
                              propulsor_lateral, resistance_curve, slender_hull_derivatives, twin_hull_yaw,
                              without_added_mass_coriolis)
from ..physics.thrusters import T200_MAP_VOLTAGE_V, advance_loss, t200_voltage_gain
from ..vessel import Vessel
from .validate import load_meshes


@dataclass(frozen=True)
class Estimate:
    """One coefficient: value in its unit, and how it was obtained."""

    name: str
    value: float
    unit: str
    method: str


@dataclass(frozen=True)
class Hull:
    """One hull at its flotation draft: waterline length, breadth, draft (m), block coefficient,
    wetted area (m²), lateral position y (m) and its lateral profile (x m, T(x) m); x_m (m) the
    centre of its displaced volume."""

    length_m: float
    beam_m: float
    draft_m: float
    block_coefficient: float
    wetted_m2: float
    y_m: float
    profile: tuple[np.ndarray, np.ndarray]
    x_m: float = 0.0


@dataclass
class FirstPrinciples:
    """The estimate: the hulls it was made on and each coefficient (`values()` for a vessel file)."""

    vessel: str
    hulls: list[Hull]
    estimates: list[Estimate]

    def values(self) -> dict[str, float]:
        return {e.name: e.value for e in self.estimates}

    def table(self) -> str:
        width = max(len(e.name) for e in self.estimates)
        lines = [f"{'coefficient':{width}s} {'value':>10s}  {'unit':10s} method", "-" * 100]
        lines += [f"{e.name:{width}s} {e.value:10.4g}  {e.unit:10s} {e.method}" for e in self.estimates]
        return "\n".join(lines)

    def applied(self, vessel: Vessel) -> Vessel:
        """`vessel` with these added-mass and damping values and thruster gains (the map kept), each
        source saying so."""
        values = self.values()
        picked = {section: {k: v for k, v in values.items() if k in fields_of}
                  for section, fields_of in (("added_mass", vessel.added_mass.__dataclass_fields__),
                                             ("damping", vessel.damping.__dataclass_fields__))}
        thrusters = replace(vessel.thrusters, **{k: values[k] for k in ("gain_left", "gain_right") if k in values})
        sources, before = dict(vessel.sources), ""
        for e in self.estimates:  # "the same ..." in the table reads on from the row above; a file's source stands alone
            same, rest = e.method.startswith("the same"), e.method[len("the same"):]
            before = (before + (rest if rest.startswith(",") else "")) if same else e.method
            sources[e.name] = f"twin params --first-principles: {before}"
        return replace(vessel, added_mass=replace(vessel.added_mass, **picked["added_mass"]),
                       damping=replace(vessel.damping, **picked["damping"]), thrusters=thrusters, sources=sources)


def _wetted_area_m2(vertices: np.ndarray, faces: np.ndarray, z_waterline_m: float) -> float:
    """Area of the mesh below the waterline (body z down), triangles clipped at the waterplane."""
    tris = vertices[faces]
    depth = tris[:, :, 2] - z_waterline_m
    total = 0.0
    for tri, d in zip(tris, depth):
        for piece in clip_triangle(tri, d):
            total += 0.5 * np.linalg.norm(np.cross(piece[1] - piece[0], piece[2] - piece[0]))
    return float(total)


def hulls(vessel: Vessel) -> list[Hull]:
    """Each hull mesh of the vessel at the waterline that floats its mass."""
    compiled = compile_vessel(vessel)  # first: it says what is wrong with a vessel file in its own words
    meshes = load_meshes(vessel)
    if not meshes:
        raise TwinError(f"vessel '{vessel.name}' has no hull meshes: a first-principles estimate needs them")
    placed = [(np.asarray(m["mesh"].vertices), np.asarray(m["mesh"].faces)) for m in meshes]
    z_w = waterline_for_mass(placed, compiled.geometry.rigid.mass_kg, RHO_FRESH_KG_M3)["waterline_z_m"]
    out = []
    for v, f in placed:
        volume, centre = submerged_volume(v, f, z_w)
        length, beam = waterplane_extent(v, f, z_w)
        draft = float(v[:, 2].max() - z_w)
        x, t = lateral_profile(v, f, z_w)
        out.append(Hull(length, beam, draft, volume / (length * beam * draft), _wetted_area_m2(v, f, z_w),
                        float(np.mean(v[:, 1])), (x, t), float(centre[0])))
    return out


def first_principles(vessel: Vessel) -> FirstPrinciples:
    """The estimate of the module docstring for a twin-thruster vessel with hull meshes and a design block."""
    d = vessel.design
    if d is None:
        raise TwinError(f"vessel '{vessel.name}' has no design block (top speed, form factor, cross-flow drag "
                        "coefficient, thruster diameters): a first-principles estimate needs it")
    if vessel.thrusters.kind != "t200":
        raise TwinError(f"vessel '{vessel.name}': the first-principles estimate is for PWM thrusters")
    hs = hulls(vessel)
    rho = RHO_FRESH_KG_M3
    g = compile_vessel(vessel).geometry
    t = vessel.thrusters
    gain = t200_voltage_gain(d.battery_v) if d.battery_v else float(np.mean(t.gains()))
    full = float(t.bounds()[1] * gain)
    loss = float(advance_loss(t.advance_loss, full, d.top_speed_m_s))  # ≤ 0: the thrust lost at top speed
    at_top = full + loss
    thrust_top = 2.0 * at_top
    wetted = sum(h.wetted_m2 for h in hs)
    length = float(np.mean([h.length_m for h in hs]))
    curve = resistance_curve(wetted, length, d.form_factor, d.top_speed_m_s, thrust_top, rho)
    gain_text = (f"T200 maximum thrust by supply voltage, {d.battery_v:g} V against the map's {T200_MAP_VOLTAGE_V:g} V: "
                 "a power law through the published 12, 16 and 20 V figures [BlueRobotics-T200]" if d.battery_v
                 else "the vessel file's own")
    est = [Estimate("gain_left", gain, "×", gain_text), Estimate("gain_right", gain, "×", "the same"),
           Estimate("Xu", curve.xu, "N s/m", f"ITTC-1957 friction × (1 + k) {d.form_factor:g} on {wetted:.3f} m² "
                    f"wetted, residuary C_R {curve.residuary_cr:.4f} holding {d.top_speed_m_s:g} m/s at "
                    f"{thrust_top:.1f} N ({d.top_speed_source or 'stated top speed'}; full thrust less the file's advance loss "
                    f"{t.advance_loss:g}: {abs(2 * loss):.1f} N less); least squares to "
                    "Xu·u + Xuu·u|u| [ITTC-1957]"),
           Estimate("Xuu", curve.xuu, "N s2/m2", "the same curve")]
    lift = SpeedDerivatives(0.0, 0.0, 0.0, 0.0)
    yvv = nrr = 0.0
    for h in hs:
        lift = lift + slender_hull_derivatives(h.length_m, h.beam_m, h.draft_m, h.block_coefficient, rho)
        a, b = cross_flow_drag(*h.profile, d.cross_flow_cd, rho)
        yvv, nrr = yvv + a, nrr + b
    # the estimate's own added mass, which a file it writes carries, not the file's it started from
    inertia = _added_mass(hs, rho)
    am = {e.name: e.value for e in inertia}
    hull_lift = without_added_mass_coriolis(lift, am["Xudot"], am["Yvdot"])
    props = SpeedDerivatives(0.0, 0.0, 0.0, 0.0)
    for x_t in g.thruster_pos_m[:, 0]:
        props = props + propulsor_lateral(float(x_t), d.duct_diameter_m, d.propeller_diameter_m, rho)
    rest = np.zeros(4)  # Yv, Yr, Nv, Nr of the thrusters working at half their full forward thrust
    for x_t in g.thruster_pos_m[:, 0]:
        rest += np.array(propulsor_at_rest(float(x_t), d.propeller_diameter_m, 0.5 * full, rho))
    s = float(np.mean([abs(h.y_m) for h in hs])) if len(hs) == 2 else 0.0
    dnr, dnur = twin_hull_yaw(s, curve.xu, curve.xuu)
    total = hull_lift + props
    hull_text = ", ".join(f"L {h.length_m:.3f} B {h.beam_m:.3f} T {h.draft_m:.3f} m C_B {h.block_coefficient:.2f}"
                          for h in hs[:1])
    est += [
        Estimate("Yuv", total.Yuv, "N s2/m2", f"slender hulls [Clarke-1983] ({len(hs)} × {hull_text}) "
                 f"{hull_lift.Yuv:.2f} + thrusters' lateral momentum and duct lift {props.Yuv:.2f}"),
        Estimate("Yur", total.Yur, "N s2/m", f"hulls {hull_lift.Yur:.2f} (C_A's X_u̇ u r taken out) + thrusters "
                 f"{props.Yur:.2f}"),
        Estimate("Nuv", total.Nuv, "N s2/m", f"hulls {hull_lift.Nuv:.2f} (C_A's Munk moment taken out) + thrusters "
                 f"{props.Nuv:.2f}"),
        Estimate("Nur", total.Nur + dnur, "N m s2/m", f"hulls {hull_lift.Nur:.2f} + thrusters {props.Nur:.2f}"
                 + (f" + the two hulls' resistance at u ∓ r·s, s {s:.3f} m: {dnur:.2f}" if len(hs) == 2 else
                    " (one hull: no resistance at u ∓ r·s)")),
        Estimate("Nr", rest[3] + dnr, "N m s", f"the thrusters' own flow at half thrust ({0.5 * full:.1f} N each) "
                 f"turning lateral momentum [Glauert-1935]: {rest[3]:.2f}"
                 + (f", + the two hulls' resistance at u ∓ r·s (its linear part) {dnr:.2f}" if len(hs) == 2 else "")),
        Estimate("Yv", rest[0], "N s/m", "the thrusters' own flow at half thrust; the hulls' sway damping at rest "
                 "is quadratic (Yvv) and their lift grows with the speed (Yuv)"),
        Estimate("Yvv", yvv, "N s2/m2", f"cross-flow drag, C_D {d.cross_flow_cd:g} on the hulls' lateral profiles "
                 "[Hoerner-1965; Fossen-2021]"),
        Estimate("Nrr", nrr, "N m s2", f"cross-flow drag, C_D {d.cross_flow_cd:g}, ∫T|x|³dx"),
        Estimate("Yr", rest[1], "N s", "the thrusters' own flow at half thrust, at their x (the hulls' cross-flow "
                 "is symmetric about the centre)"),
        Estimate("Nv", rest[2], "N s", "the same"),
    ]
    est += inertia
    return FirstPrinciples(vessel.name, hs, est)


def _added_mass(hs: list[Hull], rho: float) -> list[Estimate]:
    """Xu̇, Yv̇, Nṙ: each hull the lower half of an ellipsoid of its waterline half-length and
    half-breadth and its draft, half the added mass of the whole ellipsoid [Yellowfish-TR eq. 21]
    (physics.added_mass.half_body_added_mass), the hulls summed about the origin by the
    parallel-axis theorem for added mass (physics.added_mass.catamaran_added_mass_consistent)."""
    xu = yv = nr = 0.0
    for h in hs:
        e = half_body_added_mass(h.length_m / 2, h.beam_m / 2, h.draft_m, rho)
        xu, yv = xu + e["Xudot"], yv + e["Yvdot"]
        nr += e["Nrdot"] + e["Xudot"] * h.y_m ** 2 + e["Yvdot"] * h.x_m ** 2
    h = hs[0]
    text = (f"{len(hs)} half-ellipsoid{'s' if len(hs) > 1 else ''} of semi-axes {h.length_m / 2:.3f}, "
            f"{h.beam_m / 2:.3f}, {h.draft_m:.3f} m (half waterline length and breadth, draft): half the whole "
            "ellipsoid's added mass [Yellowfish-TR eq. 21], the free surface a rigid wall [Newman-1977 ch. 4]")
    return [Estimate("Xudot", xu, "kg", text), Estimate("Yvdot", yv, "kg", "the same"),
            Estimate("Nrdot", nr, "kg m2", "the same, each hull's added mass carried about the origin "
                     "(parallel axes)")]
