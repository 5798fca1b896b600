#!/usr/bin/env python3
"""The 6-DOF hull's checks (twin.verify.sea) and its speed, written to docs/results/sea_verification.md
with the raw figures in docs/results/data/sea_verification.json.

    python scripts/sea_verification.py [--out docs/results] [--repeats 5]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import twin.vessel as vessel_mod
from twin.engine import sixdof
from twin.files import json_default, write_text_atomic
from twin.physics import waves
from twin.verify import sea as checks
from twin.viz.pages import ResultPage, ResultTable

SEA = "0.3,2.5,30,4"
# long swell at 1 % steepness (λ 56 m and 100 m) beside the waves of 25 m and 39 m
FREE_DRIFT_SEAS = ("regular,0.25,4,30", "regular,0.39,5,30", "regular,0.562,6,30", "regular,0.999,8,30",
                   "regular,0.15,2,30", SEA)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("docs/results"))
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    raw: dict = {}
    yf, bb = vessel_mod.load("yellowfish"), vessel_mod.load("blueboat")
    barge = checks.barge(Path(tempfile.mkdtemp(prefix="twin-barge-")))

    raw["rest"] = {n: checks.rest(v) for n, v in (("yellowfish", yf), ("blueboat", bb))}
    raw["natural_periods"] = {n: checks.natural_periods(v) for n, v in (("yellowfish", yf), ("blueboat", bb),
                                                                        ("barge", barge))}
    raw["roll_energy"] = {n: checks.roll_energy(v) for n, v in (("yellowfish", yf), ("barge", barge))}
    raw["calm_water"] = {n: checks.calm_water(v) for n, v in (("yellowfish", yf), ("blueboat", bb))}
    raw["heave_rao"] = checks.barge_rao(barge, "heave", [8.0, 4.0, 2.5, 2.0, 1.73, 1.5, 1.2])
    raw["roll_rao"] = checks.barge_rao(barge, "roll", [8.0, 4.0, 3.0, 2.2, 1.45], cycles=24)
    raw["drift"] = checks.drift(barge)
    raw["free_drift"] = [{"vessel": n, **checks.free_drift(v, waves.parse_sea(text, 1))}
                         for n, v in (("yellowfish", yf), ("blueboat", bb)) for text in FREE_DRIFT_SEAS]
    raw["speed"] = checks.speed_pair(yf, SEA, args.repeats)
    raw["hulls"] = {n: sixdof.hull_model(v).to_dict() for n, v in (("yellowfish", yf), ("blueboat", bb),
                                                                   ("barge", barge))}

    tables = [
        ResultTable("Rest: the engine settled from the design waterline against twin validate's full meshes",
                    ["vessel", "CO down, engine mm", "validate mm", "trim engine °", "validate °"],
                    [[n, r["engine_down_mm"], r["validate_down_mm"], r["engine_trim_deg"], r["validate_trim_deg"]]
                     for n, r in raw["rest"].items()], digits=4),
        ResultTable("Natural periods: free decay against the closed forms with the added mass used (s)",
                    ["hull", "mode", "engine", "closed form", "error %", "uncoupled closed form"],
                    [[h, m, r["engine_s"], r["closed_form_s"], 100 * r["error"], r["uncoupled_s"]]
                     for h, modes in raw["natural_periods"].items() for m, r in modes.items()], digits=4),
        ResultTable("Undamped roll decay (3°, 10 s): energy", ["hull", "roll energy J", "largest change J", "relative"],
                    [[n, r["initial_J"], r["largest_change_J"], r["relative"]] for n, r in raw["roll_energy"].items()]),
        ResultTable("Calm water: the 6-DOF horizontal track against the 3-DOF twin's, 120-s zig-zag",
                    ["vessel", "trim at rest °", "position error m", "heading error °", "roll max °",
                     "pitch range °", "heave range mm"],
                    [[n, r["trim_deg"], r["position_err_m"], r["heading_err_deg"], r["roll_max_deg"],
                      r["pitch_range_deg"], r["heave_range_mm"]] for n, r in raw["calm_water"].items()]),
        ResultTable("Barge heave RAO in head seas, |z|/a: engine against the linear strip solution",
                    ["period s", "kL", "engine", "reference", "error %"],
                    [[r["period_s"], r["kL"], r["engine"], r["reference"], 100 * (r["engine"] / r["reference"] - 1)]
                     for r in raw["heave_rao"]], digits=4),
        ResultTable("Barge roll RAO in beam seas, |φ|/(ka): engine against the linear Froude-Krylov solution",
                    ["period s", "kL", "engine", "reference", "error %"],
                    [[r["period_s"], r["kL"], r["engine"], r["reference"], 100 * (r["engine"] / r["reference"] - 1)]
                     for r in raw["roll_rao"]], digits=4),
        ResultTable("Mean drift on the barge per ½ρga² × the lit side's length",
                    ["waves", "period s", "kT", "engine", "short-wave asymptote", "× Ursell R²"],
                    [[r["heading"], r["period_s"], r["kT"], r["engine"], r["short_wave_asymptote"],
                      r["with_reflection"]] for r in raw["drift"]], digits=4),
        ResultTable("Free drift: each hull without thrust, from rest heading into the waves, its mean velocity "
                    f"over {checks.DRIFT_AVERAGE_S:.0f} s after it has settled for "
                    f"{checks.DRIFT_SETTLE_TIME_CONSTANTS:g} of its drift time constants (m − X_u̇)/(−X_u − 2 X_uu |u|) "
                    f"(at least {checks.DRIFT_MIN_SETTLE_S:g} s), against the Stokes drift at its strips' mean depth "
                    "[Stokes-1847]",
                    ["vessel", "sea", "λ / hull length", "time constant s", "settled s", "Stokes m/s",
                     "along the waves m/s", "across m/s", "heading at the end °"],
                    [[r["vessel"], r["sea"], r["wavelength_over_length"], r["time_constant_s"], r["settle_s"],
                      r["stokes_m_s"], r["along_m_s"], r["across_m_s"], r["heading_end_deg"]]
                     for r in raw["free_drift"]], digits=3),
        ResultTable(f"Speed on one core: the Yellowfish, sea {SEA} (JONSWAP Hs, Tp, from, cos-power), 60-s runs",
                    ["twin", "simulated s per wall s"],
                    [["3-DOF (timed in turn with the next)", raw["speed"]["three_dof_simsec_per_s"]],
                     ["6-DOF in the sea", raw["speed"]["six_dof_simsec_per_s"]]], digits=4),
    ]
    s = raw["speed"]
    long_waves = [r for r in raw["free_drift"] if r["wavelength_over_length"] >= 10.0]
    page = ResultPage(
        name="sea_verification", title="The 6-DOF hull in waves: verification and speed",
        ran="python scripts/sea_verification.py",
        data="the Yellowfish and the BlueBoat as shipped (their hull meshes float them level at their nominal "
             "mass), and a 2 × 1 × 0.5 m box barge of 500 kg floating at 0.25 m (twin.verify.sea.barge)",
        summary=("The engine floats each hull where twin validate floats its full meshes (within "
                 f"{max(abs(r['engine_down_mm'] - r['validate_down_mm']) for r in raw['rest'].values()):.2f} mm and "
                 f"{max(abs(r['engine_trim_deg'] - r['validate_trim_deg']) for r in raw['rest'].values()):.3f}°). "
                 "Free heave, roll and pitch decays, each started along its mode, keep the closed-form periods; an "
                 "undamped roll keeps its energy; in calm water the 6-DOF horizontal track ends within "
                 f"{max(r['position_err_m'] for r in raw['calm_water'].values()) * 100:.1f} cm of the 3-DOF "
                 "twin's. The barge's heave follows the linear strip solution of the same model, its roll the "
                 "linear Froude-Krylov solution, and its mean drift the short-wave asymptote for a wall-sided hull "
                 "[Faltinsen-1990] times the reflection of a fixed barrier of its draft [Ursell-1947]. In long waves "
                 "a free hull drifts within "
                 f"{max(abs(r['along_m_s'] - r['stokes_m_s']) for r in long_waves):.4f} m/s of their Stokes drift, "
                 f"at {min(r['along_m_s'] / r['stokes_m_s'] for r in long_waves):.2f} to "
                 f"{max(r['along_m_s'] / r['stokes_m_s'] for r in long_waves):.2f} times it"
                 + "".join(f"; the {r['vessel']} at {r['along_m_s']:+.4f} m/s for {r['stokes_m_s']:+.4f}, against the "
                           "waves" for r in long_waves if r["along_m_s"] < 0)
                 + "; in short waves up to "
                 f"{max(r['along_m_s'] / r['stokes_m_s'] for r in raw['free_drift']):.1f} times it. The 6-DOF "
                 f"twin in an irregular short-crested sea ran {s['six_dof_simsec_per_s']:.0f}× real time on one "
                 f"core, paired with the 3-DOF twin at {s['three_dof_simsec_per_s']:.0f}× in the same run."),
        tables=tables,
        notes=["The RAO references are computed from the same added mass, damping and Smith factor the engine "
               "uses (closed forms, twin.verify.sea): they check the time-domain pressure integration, the wave "
               "grid and the strip loads, not the strip theory itself.",
               "The drift check evaluates the engine's own drift load (Ursell-Maruo reflection on the short-wave "
               "waterline integral) on the barge's mesh: it checks the waterline, the heading table and Newman's "
               "sums against the published asymptote and Ursell's closed form, not against a measured drift.",
               "A hull of light linear surge damping keeps the velocity of its start for minutes (the BlueBoat's "
               "X_u of −0.44 N s/m at 16 kg with its added mass: a drift time constant of about 35 s): each drift is "
               "averaged only once the start has died to e⁻⁵ of itself.",
               "The engine takes the strips' heave and pitch radiation damping at the hull's heave natural "
               "frequency whatever the wave's period (a frequency-dependent radiation, the memory of the hull's own "
               "waves, is not modelled); it holds a drifting hull head to the waves.",
               "The incident pressure decays with the depth below the local surface (Wheeler's stretching "
               "[Wheeler-1970]): zero on the surface under crests and troughs alike.",
               "The free drift has no published figure for these hulls: in long waves a small hull rides the "
               "orbits and goes with the water's Stokes drift, the reference used; in shorter waves its own "
               "pressure and diffraction loads add a drift of their own, which is the engine's and is not checked "
               "against a measurement. The Stokes drift is the flow `--sea` gives identify, evaluate and diagnose "
               "(engine/sixdof.py known_sea_drift), beside the mean load measured on the hull.",
               "Under thrust the hull trims (its thrusters sit below the centre of gravity) and in turns it heels; "
               "the horizontal joints keep the level thrust and the 3-DOF rigid body's inertia (engine/sixdof.py), "
               "so the calm-water difference left is the vertical modes' coupling to the horizontal.",
               "Speed figures are of a shared two-core machine; the ratio of the two twins, timed in turn, is the "
               "steadier figure."],
        raw_file="data/sea_verification.json")
    # the raw figures first (into a folder of their own under --out), so the page never links to none
    write_text_atomic(args.out / "data" / "sea_verification.json",
                      json.dumps(raw, indent=1, default=json_default) + "\n", make_folder=True)
    page.write(args.out)
    print(f"wrote {args.out / 'sea_verification.md'}")
    print(json.dumps(raw["speed"], indent=1, default=json_default))
    return 0


if __name__ == "__main__":
    sys.exit(main())
