"""Regenerate docs/iso/: IS-O in the twin ([Relay-ISO Table I], in the layout of its Table II) for yaw and surge,
the I-PD controller of eqs. 9-11 tuned from it, and its heading steps and point move against the
model function. A propeller-and-rudder ship (--vessel esso_osaka) is identified in yaw with the
rudder as the relay at several propeller speeds and steered by the rudder; its files are
docs/iso/esso_*.

    python scripts/iso_dp.py [--vessel yellowfish | esso_osaka] [--out out/...]
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from twin import vessel as vessel_mod
from twin.engine.mjcf import compile_vessel
from twin.errors import TwinError
from twin.ident.relay import ipd, iso
from twin.files import write_bytes_atomic, write_text_atomic

ROOT = Path(__file__).resolve().parent.parent
TARGET_NE_M = (10.0, 10.0)


def write_sweep(out: Path, result: iso.IsoSweep) -> None:
    stem = out / f"iso_{result.dof}"
    write_text_atomic(stem.with_suffix(".json"), json.dumps(result.to_dict(), indent=2) + "\n")
    write_text_atomic(stem.with_suffix(".md"), f"# IS-O {result.vessel} {result.dof}\n\n{iso.table_markdown(result)}\n")
    write_bytes_atomic(stem.with_suffix(".png"), iso.sweep_png(result))


def sway_message(name: str) -> str:
    try:
        iso.check_dof(name, "sway")
    except TwinError as exc:
        return str(exc)
    return "sway accepted (unexpected for a twin-thruster vessel)"


def dp_runs(cv, yaw: ipd.DofModel, surge: ipd.DofModel) -> dict[str, ipd.DpRun]:
    return {
        "heading45": ipd.heading_step(cv, yaw, 45.0),
        "heading90": ipd.heading_step(cv, yaw, 90.0),
        "heading90_no_antiwindup": ipd.heading_step(cv, yaw, 90.0, anti_windup=False),
        "point": ipd.point_move(cv, yaw, surge, TARGET_NE_M),
    }


def tuning(models: dict[str, ipd.DofModel], limits: dict[str, float]) -> dict:
    out = {}
    for dof, m in models.items():
        g = m.gains
        steps = {"yaw": {"45deg": math.radians(45), "90deg": math.radians(90)},
                 "surge": {f"{math.hypot(*TARGET_NE_M):.2f}m": math.hypot(*TARGET_NE_M)}}[dof]
        out[dof] = {"alpha": m.alpha, "beta": m.beta, "omega_n_rad_s": m.model.omega_n_rad_s,
                    "a3": m.model.a3, "a2": m.model.a2, "a1": m.model.a1, "ki": g.ki, "kp": g.kp, "kd": g.kd,
                    "relay_limit": limits[dof],
                    "model_peak_effort": {k: m.model.peak_effort(m.alpha, m.beta, v) for k, v in steps.items()}}
    return out


def iso_section(r: iso.IsoSweep) -> str:
    s, u = r.spreads(), iso.UNITS[r.dof]
    return (f"## IS-O, {r.dof}\n\n{iso.table_markdown(r)}\n\n"
            f"α = {s['alpha'].mean:.4g} {u['alpha']} against the twin's uncoupled {r.twin.alpha:.4g} "
            f"({r.alpha_error_percent():+.1f} %), CV {s['alpha'].cv_percent:.1f} % ([Relay-ISO]: ~10 %). "
            f"Drag CV {s['beta_lin'].cv_percent:.1f} % (constant-drag model) and {s['beta_quad'].cv_percent:.1f} % "
            f"(linear-drag model, [Relay-ISO]: 12.5 % for its better model): {r.better_drag_model()} fits better "
            f"[Relay-ISO §V-A]. The twin's drag is d₁ν + d₂|ν|ν with d₁ = {r.twin.drag_lin:g}, d₂ = "
            f"{r.twin.drag_quad:g}, so neither one-term model is exact: each β is close to the twin's "
            "describing-function equivalent at the experiment's speed amplitude ν_m (last two columns), "
            "not to either coefficient alone.\n\n"
            f"![IS-O {r.dof}](iso_{r.dof}.png)\n")


def dp_section(runs: dict[str, ipd.DpRun], tune: dict) -> str:
    y, s = tune["yaw"], tune["surge"]
    lines = ["## I-PD tuned from IS-O (eqs. 9-11)", "",
             "| DOF | α | β (constant drag) | ω_n [rad/s] | K_I | K_P | K_D |", "|---|---|---|---|---|---|---|"]
    for dof, t in tune.items():
        lines.append(f"| {dof} | {t['alpha']:.4g} | {t['beta']:.4g} | {t['omega_n_rad_s']:g} | {t['ki']:.4g} | "
                     f"{t['kp']:.4g} | {t['kd']:.4g} |")
    lines += ["", "Binomial model function G_m = 1/(s/ω_n + 1)³. "
              f"Heading ω_n = {y['omega_n_rad_s']:g} rad/s: on the "
              f"IS-O model a 45° step needs {y['model_peak_effort']['45deg']:.1f} N·m of the "
              f"±{y['relay_limit']:.1f} N·m the thrusters give, "
              f"a 90° step {y['model_peak_effort']['90deg']:.1f} N·m, "
              f"so it saturates [Relay-ISO Fig. 9]. The twin's yaw is fast (α/β = {y['alpha'] / y['beta']:.2f} s), "
              "so the paper's 0.2 rad/s "
              "would be needlessly slow; K_D < 0 means the loop cancels part of the hull's own yaw damping, as eq. 11 "
              f"gives whenever ω_n < β/(3α). Surge ω_n = {s['omega_n_rad_s']:g} rad/s: a "
              f"{math.hypot(*TARGET_NE_M):.1f} m move needs at most {list(s['model_peak_effort'].values())[0]:.1f} N "
              f"of ±{s['relay_limit']:.1f} N and peaks near 1 m/s; the heading loop is "
              f"{y['omega_n_rad_s'] / s['omega_n_rad_s']:.1f}× faster.", "",
              "Anti-windup: back-calculation on the delivered (saturated) moment/force, T_t = 1/(3ω_n). "
              "Allocation: inverse of [Yellowfish-TR eq. 26] with yaw priority, clipped to each thruster's bounds. "
              "The controller uses the twin's η and ν as they are (no Kalman filter: the twin is noise-free).", "",
              "Point move: the vessel has no sway thruster, so it turns to the bearing of the target (a heading step) "
              "and, once the heading model function has settled (8/ω_n,ψ), the surge I-PD drives the along-track "
              "distance x* (on the start-to-target line) to the target distance. The cross-track offset y* is not "
              "controlled and is reported.", "",
              "| run | loop | IAE twin / IAE G_m | max \\|twin − G_m\\| | overshoot | saturated [% of time] | "
              "peak command / delivered |", "|---|---|---|---|---|---|---|"]
    for key, dp in runs.items():
        for lp in dp.summary()["loops"]:
            lines.append(f"| {dp.name} | {lp['dof']} | {lp['iae_ratio']:.3f} | {lp['max_deviation_from_model']:.3g} "
                         f"{lp['unit']} | {lp['overshoot']:.3g} {lp['unit']} | {lp['saturated_percent_of_time']:.1f} | "
                         f"{lp['peak_command']:.2f} / "
                         f"{lp['peak_delivered']:.2f} |")
    p = runs["point"].summary()
    lines += ["", f"Point move: final distance to the target {p['final_distance_to_target_m']:.3f} m, largest "
              f"cross-track offset {p['max_cross_track_m']:.3f} m. [Relay-ISO] reports an IAE ratio of about 1.02 "
              "for its 45° step.", ""]
    lines += [f"![{dp.name}](dp_{key}.png)" for key, dp in runs.items()]
    return "\n".join(lines) + "\n"


SHIP_PREFIX = "esso_"


def ship_main(cv, out: Path, vessel_name: str) -> None:
    """IS-O with the rudder relay ([Relay-ISO Table II] for its ship model), the heading I-PD steering the rudder."""
    sweep = iso.ship_sweep(cv)
    stem = out / f"{SHIP_PREFIX}iso_yaw"
    write_text_atomic(stem.with_suffix(".json"), json.dumps(sweep.to_dict(), indent=2) + "\n")
    write_text_atomic(stem.with_suffix(".md"), f"# IS-O {sweep.vessel} yaw, rudder relay\n\n{iso.table_markdown(sweep)}\n")
    write_bytes_atomic(stem.with_suffix(".png"), iso.sweep_png(sweep))
    rps = ipd.SHIP_RPS
    alpha, beta = iso.linear_model(sweep, rps)
    yaw = ipd.DofModel(alpha, beta, ipd.binomial(ipd.SHIP_HEADING_OMEGA_RAD_S))
    u0 = iso.straight_speed(cv, rps)
    allocation = ipd.RudderAllocation.at(cv, u0, rps)
    limit = allocation.moment(allocation.max_rad)
    runs = {"heading45": ipd.ship_heading_step(cv, yaw, 45.0, rps),
            "heading90": ipd.ship_heading_step(cv, yaw, 90.0, rps),
            "heading90_no_antiwindup": ipd.ship_heading_step(cv, yaw, 90.0, rps, anti_windup=False)}
    for key, dp in runs.items():
        write_bytes_atomic(out / f"{SHIP_PREFIX}dp_{key}.png",
                           ipd.response_png(dp, f"{cv.vessel.name}: {dp.name}, I-PD tuned from IS-O"))
    g = yaw.gains
    tune = {"alpha": alpha, "beta": beta, "rps": rps, "u0_m_s": u0, "omega_n_rad_s": yaw.model.omega_n_rad_s,
            "ki": g.ki, "kp": g.kp, "kd": g.kd, "rudder_gain_nm": allocation.gain_nm, "moment_limit_nm": limit,
            "model_peak_effort": {f"{d}deg": yaw.model.peak_effort(alpha, beta, math.radians(d)) for d in (45, 90)}}
    s = sweep.spreads()
    summary = {"vessel": cv.vessel.name, "surge": dof_message(cv, "surge"), "sway": dof_message(cv, "sway"),
               "tuning": tune, "runs": {k: dp.summary() for k, dp in runs.items()},
               "iso": {"alpha_mean": s["alpha"].mean, "alpha_twin_M33": sweep.twin.alpha,
                       "alpha_error_percent": sweep.alpha_error_percent(),
                       "cv_percent": {k: v.cv_percent for k, v in s.items()},
                       "better_drag_model": sweep.better_drag_model()}}
    write_text_atomic(out / f"{SHIP_PREFIX}dp.json", json.dumps(summary, indent=2) + "\n")
    by_rps = {n: iso.linear_model(sweep, n) for n in sorted({r.rps for r in sweep.rows})}
    lines = [f"# IS-O and I-PD heading control of the {cv.vessel.name} twin with its rudder [Relay-ISO]", "",
             f"Regenerate with `python scripts/iso_dp.py --vessel {vessel_name}` (or `twin iso --vessel {vessel_name} "
             f"--dof yaw`, `twin dp --vessel {vessel_name}`). [Relay-ISO §V-A] identifies its tanker model's yaw with the "
             "rudder (Table II: propeller at 60/75/90 %, rudder 10-45°); here the propeller turns at "
             f"{', '.join(f'{n:g}' for n in by_rps)} rps (the Esso turning tests' speeds), the ship starts from its "
             "straight-running speed u₀ in calm water, and the relay puts the rudder at ±δ_c whenever the heading "
             f"error passes ±{math.degrees(iso.SHIP_XA_RAD):g}° (sampled at {iso.SHIP_CONTROL_DT_S * 1e3:.0f} ms, the "
             "tests' 10 Hz; experiments of "
             f"{iso.SHIP_DURATION_S:g} s, the first third left out). Table I's C is the rudder's yaw moment at ±δ_c "
             "in straight running (the paper's allocation N = L₁k_Fδτ₁, here the MMG rudder force), so α and β are "
             "in kg·m² and N·m·s (the paper divides them by its unknown k_F).", "",
             f"Surge: `twin iso --dof surge` → `error: {summary['surge']}`.  ",
             f"Sway: `error: {summary['sway']}`.", "",
             "## IS-O, yaw, rudder relay", "", iso.table_markdown(sweep), "",
             f"α = {s['alpha'].mean:.4g} kg·m² (CV {s['alpha'].cv_percent:.1f} %, [Relay-ISO]: 10 %) against the twin's "
             f"uncoupled M₃₃ = {sweep.twin.alpha:.4g} ({sweep.alpha_error_percent():+.1f} %); β_ν CV "
             f"{s['beta_lin'].cv_percent:.1f} %, β_νν CV {s['beta_quad'].cv_percent:.1f} %: "
             f"{sweep.better_drag_model()} fits better ([Relay-ISO] found the linear-drag model better for its model; "
             "the twin's hull yaw damping is linear in r at a given speed, N'_r r' U² = N'_r r L U). Per propeller "
             "speed: " + "; ".join(f"{n:g} rps: α {a:.4g}, β_ν {b:.4g}" for n, (a, b) in by_rps.items()) + ". "
             "α exceeds M₃₃ and β_ν is below the twin's −∂N/∂r (the last row, at the highest speed) because a ship "
             "cannot yaw without swaying: the rudder's side force and the hull's N'_v (which holds the Munk "
             "moment) make the yaw the relay sees slower and less damped than the uncoupled yaw equation. These "
             "are the effective values the paper's uncoupled model (eq. 6) identifies, and what its I-PD is tuned "
             "with.", "", "![IS-O yaw, rudder](esso_iso_yaw.png)", "",
             "## I-PD heading control with the rudder (eqs. 9-11)", "",
             "| α | β (constant drag) | n [rps] | u₀ [m/s] | ω_n [rad/s] | K_I | K_P | K_D |",
             "|---|---|---|---|---|---|---|---|",
             f"| {alpha:.4g} | {beta:.4g} | {rps:g} | {u0:.3f} | {yaw.model.omega_n_rad_s:g} | {g.ki:.4g} | "
             f"{g.kp:.4g} | {g.kd:.4g} |", "",
             f"The model function G_m = 1/(s/ω_n + 1)³ with ω_n = {yaw.model.omega_n_rad_s:g} rad/s: on the IS-O "
             f"model a 45° step needs {tune['model_peak_effort']['45deg']:.2f} N·m of the {limit:.2f} N·m the rudder "
             f"gives at 35° (A = {allocation.gain_nm:.3f} N·m in N_R = A sin δ cos δ at u₀), a 90° step "
             f"{tune['model_peak_effort']['90deg']:.2f} N·m, so it saturates [Relay-ISO Fig. 9]. [Relay-ISO] used "
             "0.2 rad/s for its 1.2-m tanker; on this ship that would ask more than the rudder's moment for 45°. "
             "The controller allocates the moment to the rudder by inverting N_R at the operating point, the "
             "propeller stays at n; back-calculation anti-windup on the moment of the clipped rudder angle, "
             "T_t = 1/(3ω_n). In the turn the ship slows down (the twin's speed loss), which the constant "
             "operating point of the allocation and the linear model do not know.", "",
             "| run | IAE twin / IAE G_m | max \\|twin − G_m\\| | overshoot | saturated [% of time] | "
             "peak command / delivered [N·m] |", "|---|---|---|---|---|---|"]
    for dp in runs.values():
        lp = dp.summary()["loops"][0]
        lines.append(f"| {dp.name} | {lp['iae_ratio']:.3f} | {lp['max_deviation_from_model']:.3g} deg | "
                     f"{lp['overshoot']:.3g} deg | {lp['saturated_percent_of_time']:.1f} | "
                     f"{lp['peak_command']:.2f} / {lp['peak_delivered']:.2f} |")
    lines += ["", "[Relay-ISO] reports an IAE ratio of about 1.02 for its 45° step."]
    with_aw, without = (runs[k].summary()["loops"][0] for k in ("heading90", "heading90_no_antiwindup"))
    if without["iae_ratio"] < with_aw["iae_ratio"]:
        lines += ["", f"At 90° the run without anti-windup has the lower IAE ({without['iae_ratio']:.3f} against "
                  f"{with_aw['iae_ratio']:.3f}): its wound-up integral holds the rudder hard over longer "
                  f"({without['saturated_percent_of_time']:.0f} % of the time saturated against "
                  f"{with_aw['saturated_percent_of_time']:.0f} %), which this slow, well-damped yaw turns into a "
                  f"faster approach with only {without['overshoot']:.2f}° of overshoot; the back-calculation's "
                  "T_t = 1/(3ω_n) unwinds more than this loop needs. [Relay-ISO] shows its anti-windup on a 90° step "
                  "(Fig. 9) without a run to compare."]
    lines.append("")
    lines += [f"![{dp.name}]({SHIP_PREFIX}dp_{key}.png)" for key, dp in runs.items()]
    write_text_atomic(out / f"{SHIP_PREFIX}summary.md", "\n".join(lines) + "\n")
    print(f"wrote {out}: " + ", ".join(sorted(p.name for p in out.iterdir() if p.name.startswith(SHIP_PREFIX))))


def dof_message(cv, dof: str) -> str:
    try:
        iso.check_dof(cv.vessel.name, dof, cv.vessel.thrusters.kind)
    except TwinError as exc:
        return str(exc)
    return f"{dof} accepted"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vessel", default="yellowfish")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "iso")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    cv = compile_vessel(vessel_mod.load(args.vessel))
    if iso.is_ship(cv):
        ship_main(cv, args.out, args.vessel)
        return
    sweeps = {dof: iso.sweep(cv, dof) for dof in ("yaw", "surge")}
    for result in sweeps.values():
        write_sweep(args.out, result)
    omegas = {"yaw": ipd.HEADING_OMEGA_RAD_S, "surge": ipd.SURGE_OMEGA_RAD_S}
    models = {dof: ipd.DofModel(*iso.linear_model(r), ipd.binomial(omegas[dof])) for dof, r in sweeps.items()}
    limits = {dof: iso.relay_limit(cv.geometry.thruster_y_m, cv.vessel.thrusters.bounds(), dof) for dof in sweeps}
    runs = dp_runs(cv, models["yaw"], models["surge"])
    for key, dp in runs.items():
        write_bytes_atomic(args.out / f"dp_{key}.png",
                               ipd.response_png(dp, f"{cv.vessel.name}: {dp.name}, I-PD tuned from IS-O"))
    tune = tuning(models, limits)
    summary = {"vessel": cv.vessel.name, "sway": sway_message(cv.vessel.name), "tuning": tune,
               "runs": {k: dp.summary() for k, dp in runs.items()},
               "iso": {dof: {"alpha_mean": r.spreads()["alpha"].mean, "alpha_twin": r.twin.alpha,
                             "alpha_error_percent": r.alpha_error_percent(),
                             "cv_percent": {k: v.cv_percent for k, v in r.spreads().items()},
                             "better_drag_model": r.better_drag_model()} for dof, r in sweeps.items()}}
    write_text_atomic(args.out / "dp.json", json.dumps(summary, indent=2) + "\n")
    md = [f"# IS-O identification and I-PD dynamic positioning of the {cv.vessel.name} twin [Relay-ISO]", "",
          f"Regenerate with `python scripts/iso_dp.py --vessel {args.vessel}`. Relay experiments at "
          f"{iso.CONTROL_DT_S * 1e3:.0f} ms, hysteresis {math.degrees(iso.DEFAULT_XA['yaw']):g}° (yaw) and "
          f"{iso.DEFAULT_XA['surge']:g} m (surge); Table I is applied with the switching level the sampled relay "
          "actually saw (xa_eff); σ is the sample standard deviation.", "",
          f"Sway: `twin iso --dof sway` → `error: {summary['sway']}` (exit 2).", "",
          iso_section(sweeps["yaw"]), iso_section(sweeps["surge"]), dp_section(runs, tune)]
    write_text_atomic(args.out / "summary.md", "\n".join(md))
    print(f"wrote {args.out}: " + ", ".join(sorted(p.name for p in args.out.iterdir() if not p.name.startswith("."))))


if __name__ == "__main__":
    main()
