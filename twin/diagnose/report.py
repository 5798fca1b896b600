"""What a diagnosis shows, answer first: what is missing and how sure, what it changes, what the
recording cannot settle and what to record next; then the evidence (effects, fit before and after
on held-out data, where the misfit was, what is left). As text (the terminal), an HTML page with
plots, and a rerun recording with the real run, the twin before and the twin after on one timeline.

The twin's curves are its 10-s free runs from measured states, window after window (each
window restarts from the measurement, so the curves jump at window starts): exactly what
the diagnosis judged.
"""
from __future__ import annotations

import base64
import html
import io
import math
from pathlib import Path

import numpy as np
from scipy.stats import norm

from ..run import Run
from ..files import write_text_atomic
from ..replay import stitched_runs
from ..engine.mjcf import compile_vessel
from ..outputs import write
from .doctor import Diagnosis
from .search import BLOCK_WINDOWS, REL_EXCESS, Z_MIN, Z_PREFER
from .separate import settling
from .verdict import FOLLOWS_R, MIN_UNANIMOUS_BLOCKS, MODEL_FORM_SIGMA, TIMING_EFFECTS, at_edge, family, \
    more_recording_factor, promising

WORSE_R2 = 0.01  # a held-out R² this much lower after the amendment is said as worse

DOF_UNITS = {"u": "m/s", "v": "m/s", "r": "°/s"}  # the one unit system of the report: r in degrees per second
DOF_SCALE = {"u": 1.0, "v": 1.0, "r": 180.0 / np.pi}  # from the diagnosis's SI values to DOF_UNITS


def excess_share(share: float) -> str:
    """A candidate's share of the held-out misfit above the noise, as the report says it. Beyond 100 %
    the candidate fits the held-out blocks closer than the noise estimated for the recording allows:
    that estimate is high there (or the twin was already within it), and a percentage would mislead."""
    if share >= 1.0:  # a JSON file's shares stop at 1 (search.excess_shown)
        return "all of the held-out misfit above the noise (or more: the recording's noise estimate is high)"
    return f"{100 * share:.0f} % of the held-out misfit above the noise"


def z_text(z: float, bar: float = 3.0) -> str:
    """A blocks' z as the report says it: one decimal, two where one would round it onto the bar it is
    judged against (2.98 is not 3.0: z 3 is needed)."""
    one = f"{z:.1f}"
    return f"{z:.2f}" if z != bar and float(one) == bar else one


def given_text(effects, e) -> str:
    """One answer for given_evidence: whether the recordings prove the effects as given, how sure, what
    they change."""
    what = " + ".join(str(x) for x in effects) or "nothing"
    if e.affected == 0:
        return (f"{what} changes no window's prediction on these recordings: nothing to judge (a per-log effect "
                "names its log by file name)")
    blocks = f"z {e.z:.2f} over {e.blocks_for + e.blocks_against} blocks ({e.blocks_for} for, {e.blocks_against} against)"
    share = (f"removes {excess_share(e.rel_excess)}" if e.rel_excess >= 0
             else f"adds {-100 * e.rel_excess:.1f} % to the held-out misfit above the noise" if e.rel_excess >= -1
             else "adds more than all of the held-out misfit above the noise to it")
    # said as what the effect does to the misfit: lowers (a gain) or raises it, each velocity alike
    def moved(rel: float) -> str:
        return f"{'lowers' if rel >= 0 else 'raises'} it {100 * abs(rel):.1f} %"

    change = (f"held-out misfit: {moved(e.rel)} ({share}; "
              + ", ".join(f"{k}: {moved(v)}" for k, v in e.dof_rel.items()) + ")")
    if e.earns_its_place():
        return f"{what} earns its place as given: {blocks}; {change}"
    if e.z <= -Z_MIN:  # the blocks' vote, mirrored: as sure as a finding, the other way
        return f"{what} is contradicted by these recordings: {blocks}; {change}"
    if e.blocks_for == 0 and e.blocks_against >= 2:  # as far as these blocks can say, the data oppose it
        fewest = math.ceil(math.log2(1.0 / norm.sf(Z_MIN)))  # all of n blocks one way: p = 2^−n (exact test)
        return (f"{what} does not earn its place as given ({blocks}; {change}): every block votes against it, as "
                f"far against as {e.blocks_against} blocks can be (calling it contradicted takes z ≤ −{Z_MIN:g}, "
                f"{fewest} blocks or more)")
    return (f"{what} does not earn its place as given ({blocks}; {change}): these recordings cannot prove it at "
            "these values (the rule: z ≥ 3 and 5 % of the misfit above the noise)")


def as_json(d) -> dict:
    """A diagnosis as the JSON `twin diagnose --json` writes: its figures (doctor.Diagnosis.to_dict)
    and the answer as the report words it (`answer`)."""
    return {**Diagnosis.to_dict(d), "answer": answer(d)}


def _shown(dof: str, value):
    """A residual, noise or error of `dof` in the report's unit (None stays None)."""
    return None if value is None else value * DOF_SCALE.get(dof, 1.0)


def runs(d) -> dict[str, Run]:
    """Real, twin before and twin after on the windows' samples, in time order."""
    rp = d.replay
    before, after = rp["before"], rp["after"]
    return stitched_runs(rp["windows"], {"recorded": (rp["preps"], before.meas_eta, before.meas_nu),
                                         "twin before": (rp["preps"], before.pred_eta, before.pred_nu),
                                         "twin after": (rp["amended_preps"], after.pred_eta, after.pred_nu)})


def write_rrd(d, path: Path) -> None:
    write(runs(d), Path(path), geometry=compile_vessel(d.prior).geometry, vessel_name=d.prior.name,
          mjcf=d.prior.mjcf, view=True)


def _png(fig) -> str:
    import matplotlib.pyplot as plt  # late: matplotlib (0.25 s) only for the HTML report's figures

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode()


# what to record next, by the family of effects a recording could not tell apart or name
NEXT = {
    "drift": "straight runs under way on opposite headings, and a few minutes drifting with the thrusters off: "
             "a current or wind pushes the same way whatever the heading, a compass error turns with the boat",
    "compass": "straight runs on four or more headings, each at a low and at a high throttle (a compass the "
               "motors' currents disturb turns its error with the throttle; a fixed error does not), or "
               "ArduPilot's compassmot calibration",
    "timing": "steps of the sticks from rest and back to neutral (the thrust's timing shows at steps), and the "
              "PWM logged on the same clock as GNSS and heading; with the gyro (IMU) logged, `twin info` reads "
              "how late the heading is against it",
    "thrust": "straight runs at several fixed throttles ahead and astern, and spins in place both ways "
              "(a weak thruster turns the boat better one way than the other), the same runs on a full and "
              "on a tired pack with the battery voltage logged (a thrust that follows the pack, not the clock)",
    "turning": "spins in place both ways and turns at a steady speed both ways",
    "drag": "coast-downs from full speed with the thrusters at neutral, and runs at several steady speeds",
    "inertia": "zig-zags and sharp throttle steps",
}
# the same for a propeller-and-rudder ship, where the advice above speaks of what it has not
NEXT_SHIP = {
    "drift": "straight runs under way on opposite headings, and a few minutes drifting with the propeller "
             "stopped: a current or wind pushes the same way whatever the heading, a compass error turns with "
             "the ship",
    "timing": "steps of the propeller speed and of the rudder from steady running (the answer's timing shows at "
              "steps), and the inputs logged on the same clock as GNSS and heading; with the gyro logged, "
              "`twin info` reads how late the heading is against it",
    "thrust": "straight runs at several fixed propeller speeds ahead and astern, and turns both ways at one "
              "rudder angle",
    "turning": "turns both ways at several rudder angles, and zig-zags",
    "drag": "coast-downs from full speed with the propeller stopped, and runs at several steady propeller speeds",
}
# what to record where the kinematics could not tell an effect (neither named nor shown absent: too few
# spins or steps, or too loose a reading); the timing effects take the "timing" family's advice
ANTENNA_NEXT = ("spins in place both ways, four or more each, each turning 30° or more within 3 s at under "
                "0.5 m/s over ground with the hull held on the spot (ease the thruster ahead where it creeps): "
                "only there do the fixes swing round the hull's middle whatever the twin's form")
ANTENNA_NEXT_SHIP = ("the antenna's place from the ship's drawings, put in the vessel file (sensors.antenna_offset_m): "
                     "the kinematics read it only from turns on the spot, which a propeller-and-rudder ship does not make")


def _block_text(d) -> str:
    """' of N s': a block's length, BLOCK_WINDOWS windows of the diagnosis's own window length."""
    block_s = BLOCK_WINDOWS * float(d.windows.get("length_s") or 0.0)
    return f" of {block_s:.0f} s" if block_s > 0 else ""


def answer(d) -> dict:
    """What the diagnosis concludes, in the order a user needs it: {"missing": [...], "form": [...],
    "changes": str, "unsettled": [...], "next": [...]} (lines of plain text)."""
    out = {"missing": [], "form": [], "changes": "", "unsettled": [], "next": []}
    families = set()
    block = _block_text(d)
    for e in d.effects:
        params = ", ".join(f"{k} {v:.3g}" + (f" [{e['ci'][k][0]:.3g}, {e['ci'][k][1]:.3g}]" if k in e["ci"] else "")
                           for k, v in e["parameters"].items())
        ev = e.get("evidence", {})
        if e.get("kind") == "kinematic":
            out["missing"].append(f"{e['name']} ({params}): told from the kinematics, before any fit ({ev.get('why', '')}; "
                                  f"{ev.get('basis', '')})")
            continue
        # a rival the recording cannot tell from it is said on the same line: named alone, the effect would
        # read as settled, and UNSETTLED below as a contradiction of it
        rivals = [r["name"] for r in e["rivals"] if not r["separable"]]
        out["missing"].append(
            f"{e['name']} ({params}): removes {excess_share(e.get('excess_gain', 0))}, z {z_text(e['z'], Z_MIN)} over "
            f"{ev.get('blocks_for', 0) + ev.get('blocks_against', 0)} blocks{block} "
            f"({ev.get('blocks_for', 0)} for, {ev.get('blocks_against', 0)} against)"
            + (f"; or {' or '.join(rivals)} in its place (UNSETTLED)" if rivals else ""))
        for r in e["rivals"]:
            if not r["separable"] and r["z"] <= -Z_PREFER:
                # kept all the same: the rival the blocks lean to did not earn its place by itself
                out["unsettled"].append(f"{e['name']} or {r['name']}: the blocks prefer {r['name']} (z "
                                        f"{-r['z']:.1f} between the two), but it does not earn its place by itself: "
                                        f"{e['name']} may stand in for it")
                families |= {family(d, r["name"]), family(d, e["name"])}  # what settles either
            elif not r["separable"]:
                out["unsettled"].append(f"{e['name']} or {r['name']}: this recording cannot tell them apart "
                                        f"(blocks z {z_text(r['z'], Z_MIN)})")
                families |= {family(d, r["name"]), family(d, e["name"])}
    window_s = float(d.windows.get("length_s") or 10.0)
    settle = [_settling(e["name"], rival, seps, window_s) for e in d.effects
              for rival, seps in (e.get("separations") or {}).items() if seps]
    blocks = int(d.windows.get("blocks", (d.windows.get("windows") or 0) // BLOCK_WINDOWS))
    if not d.effects and blocks < MIN_UNANIMOUS_BLOCKS:
        block_s = BLOCK_WINDOWS * float(d.windows.get("length_s") or 0.0)
        out["missing"].append(
            f"nothing can be named from the dynamics with {blocks} blocks of {block_s:.0f} s: the held-out test "
            f"(z ≥ {Z_MIN:g}) needs {MIN_UNANIMOUS_BLOCKS} blocks or more in which an effect changes the prediction, "
            f"even with every one for it; at least {(MIN_UNANIMOUS_BLOCKS - blocks) * block_s / 60:.1f} min more of "
            "recording with inputs (only what the kinematics tell can be named here)")
    elif not d.effects:
        out["missing"].append(f"no effect of the library earns its place (z ≥ {Z_MIN:g} over the held-out blocks and "
                              f"≥ {100 * REL_EXCESS:.0f} % of the misfit above the noise removed)")
    for u in d.unexplained:
        if u.get("dimension") == "all" and (u.get("rms_over_noise") or 0) > MODEL_FORM_SIGMA:
            follows = ", ".join(f"{c['signal']} ({c['r']:+.2f})" for c in u.get("correlates_with", []))
            where = _worst_bin(d, u["dof"])
            # a residual that follows no logged signal may be a disturbance the log does not record (short waves,
            # gusts) as well as a form error the signals do not show: the proof's chop and its dead zones leave the
            # same lines, and no test on the residual tells them apart, so both are said
            cause = ("the twin's form is off there" if follows else
                     f"it follows none of the logged signals (correlation at most {FOLLOWS_R:g} in size): either the "
                     "twin's form is off in a way they do not show, or a disturbance the log does not record acts "
                     "(short waves, gusts)")
            out["form"].append(f"{u['dof']} is still {u['rms_over_noise']:.0f}× the noise off (RMS "
                               f"{_shown(u['dof'], u['rms']):.3g} {DOF_UNITS[u['dof']]})" + (f", most in {where}" if where else "")
                               + (f", and follows {follows}" if follows else "")
                               + f": {cause}, and " + (f"with {blocks} blocks no effect of the library can be shown "
                                                       "to explain it" if blocks < MIN_UNANIMOUS_BLOCKS else
                                                       "no effect of the library explains it on held-out blocks"))
    for c in at_edge(d):
        edges = ", ".join(f"{k} {np.median([f[k] for f in c['fold_values']]):.3g}" for k in c["at_edge"])
        out["form"].append(f"{c['name']} would remove {excess_share(c['excess_gain'])} (z {z_text(c['z'], Z_MIN)}), "
                           f"but only at the edge of what is physical ({edges}, on every "
                           f"fold): not named; the twin's form is off where {c['name']} acts")
    if d.effects:
        b, a = d.fit_before, d.fit_after
        out["changes"] = "held-out R² " + ", ".join(f"{k} {_num(b[k]['r2'])} → {_num(a[k]['r2'])}" for k in "uvr")
        worse = [k for k in "uvr" if isinstance(b[k]["r2"], float) and isinstance(a[k]["r2"], float)
                 and a[k]["r2"] < b[k]["r2"] - WORSE_R2]
        if worse:  # the rule weighs the velocities together (each by its noise): one may pay for the others
            out["changes"] += (f"; {' and '.join(worse)} worse with it: what is named gains on the held-out blocks "
                               "as a whole, not in every velocity (check the amended twin there before using it)")
        if any(e.get("kind") == "kinematic" for e in d.effects):
            # a kinematic finding is read into the logs before any fit: the twin is judged with it both ways
            alone = all(e.get("kind") == "kinematic" for e in d.effects)
            out["changes"] += (" (what the kinematics told is read into the logs before any fit, so both sides carry "
                               "it" + ("; nothing of the dynamics was named" if alone else "") + ")")
    for c in promising(d):
        out["unsettled"].append(
            f"{c['name']} may be missing but is not proven: it removes {excess_share(c['excess_gain'])}, "
            f"z {z_text(c['z'], Z_MIN)} "
            f"from the {c['blocks_for'] + c['blocks_against']} blocks in which "
            f"it changes the prediction ({c['blocks_for']} for, {c['blocks_against']} against; z {Z_MIN:g} needs more "
            f"such blocks{_more_to_record(d, c)})")
        families.add(family(d, c["name"]))
    candidates_tried = {c["name"] for r in d.rounds for c in r.get("candidates", [])}
    if not d.effects and out["form"]:
        families |= {family(d, n) for n in candidates_tried}
    ship = d.prior.thrusters.kind == "propeller_rudder"
    untold = [f for f in getattr(d, "kinematic", []) if not (f.told or f.absent)]
    families |= {"timing" for f in untold if f.effect in TIMING_EFFECTS}
    antenna = [f"to tell where the GNSS antenna sits (not told: {f.why}): {ANTENNA_NEXT_SHIP if ship else ANTENNA_NEXT}"
               for f in untold if f.effect == "gnss_lever_arm"]
    advice = NEXT | (NEXT_SHIP if ship else {})
    out["next"] = settle + antenna + [f"to settle {fam} effects: {advice[fam]}" for fam in sorted(families)
                                      if fam in advice]
    return out


# the trials (synth.manoeuvres.TRIALS) as the answer names them
TRIAL_WORDS = {
    "full_ahead_coast": "full ahead from rest for 25 s, then the thrusters at neutral to coast down",
    "throttle_steps": "throttle steps from rest (a quarter, half, three quarters, full, 8 s each), then neutral",
    "spins": "spins on the spot both ways (12 s each, 0.8 of full on each stick)",
    "turns": "turns both ways at 0.6 throttle, 15 s each",
    "astern_stop": "astern at 0.8 for 15 s, then neutral",
}


def _settling(kept: str, rival: str, seps: list[dict], window_s: float) -> str:
    """The trial the two readings' twins part on most (separate.py), as the answer says it; or that
    none of the trials tried parts them."""
    s = settling(seps)
    if s is None:
        best = seps[0]
        tried = [x["trial"] for x in seps if x.get("refitted")] or [x["trial"] for x in seps]
        return (f"to tell {kept} from {rival}: none of the trials tried ({', '.join(tried)}"
                f"{', the rival refitted to each' if best.get('refitted') else ''}) parts their twins by what the twin "
                f"still misses (at best {best['ratio']:.1f}× it, {best['trial']}): on this twin the two may be one "
                "reading, and recording more of any kind may leave them so")
    dof = s["dof"]
    much = (f"about {s['minutes']:.0f} min of it" if s["minutes"] is not None and s["minutes"] >= 1.5
            else "a few repeats of it")
    return (f"to tell {kept} from {rival}: {TRIAL_WORDS[s['trial']]} ({much}); there the two twins' "
            f"{window_s:g}-s free runs differ by {_shown(dof, s['difference']):.2g} {DOF_UNITS[dof]} in {dof}, "
            f"{s['ratio']:.1f}× what the twin still misses (a prediction of the two twins"
            f"{', the rival refitted to the trial' if s.get('refitted') else ''}, in {100 * s['share']:.0f} % of "
            "its windows)")


def _more_to_record(d, c: dict) -> str:
    """`more_recording_factor` as the hint's closing words ("" where it has none)."""
    factor = more_recording_factor(c)
    minutes = (d.windows.get("windows") or 0) * (d.windows.get("length_s") or 0.0) / 60.0
    if factor is None or minutes <= 0:
        return ""
    return (f"; if further blocks voted as these did, a recording of the same kind of driving about "
            f"{factor:.1f}× as long as these {minutes:.0f} min of windows would reach it")


def _worst_bin(d, dof: str) -> str:
    bins = [e for e in d.located if e["dof"] == dof and e.get("z", 0) >= 3.0]
    if not bins:
        return ""
    e = max(bins, key=lambda x: x.get("share_of_residual", 0))
    return bin_words(e["dimension"], e["bin"])


# how a bin of the located table (diagnose/locate.py DIMENSIONS) reads in a sentence
_BIN_WORDS = {"near_zero_pwm": {"yes": "windows with a thruster near zero PWM",
                                "no": "windows with both thrusters away from zero PWM"},
              "region": {"ff": "samples with both thrusters ahead", "fr": "samples with the left thruster ahead, the "
                         "right astern", "rf": "samples with the left thruster astern, the right ahead",
                         "rr": "samples with both thrusters astern"},
              "speed": "speed", "yaw_rate": "yaw rate", "heading": "heading",
              "since_step": "time since an input step", "pwm_diff": "PWM difference", "run_third": "part of the run",
              "time_block": "time in the run", "recording": "recording"}


def bin_words(dimension: str, bin_label: str) -> str:
    """A located bin as words: "yaw rate r>10°/s", "windows with a thruster near zero PWM"."""
    words = _BIN_WORDS.get(dimension, dimension)
    if isinstance(words, dict):
        return words.get(bin_label, f"{dimension} {bin_label}")
    return f"{words} {bin_label}"


def format_text(d) -> str:
    """The diagnosis for the terminal, ≤ 100 columns, answer first."""
    a = answer(d)
    lines = [f"diagnosis of {d.prior.name}: {d.windows.get('windows')} windows of {d.windows.get('length_s')} s in "
             f"{d.windows.get('blocks')} blocks, judged in {d.windows.get('folds')} folds; took {d.seconds:.0f} s"]
    lines += [f"MISSING: {x}" for x in a["missing"]]
    lines += [f"TWIN'S FORM: {x}" for x in a["form"]]
    if a["changes"]:
        lines.append(f"CHANGES: {a['changes']}")
    lines += [f"UNSETTLED: {x}" for x in a["unsettled"]]
    lines += [f"RECORD NEXT: {x}" for x in a["next"]]
    noise = d.noise
    lines.append(f"noise estimated from the recording: GNSS {noise.get('gnss_m', float('nan')):.3f} m, heading "
                 f"{noise.get('heading_deg', float('nan')):.2f}° → u {noise.get('u', float('nan')):.3f} m/s, "
                 f"v {noise.get('v', float('nan')):.3f} m/s, r {_shown('r', noise.get('r', float('nan'))):.3f} °/s")
    if noise.get("input_period_s"):
        lines.append(f"replay's own resolution (inputs logged every {noise['input_period_s']:.2g} s, judged with the "
                     f"noise): u {noise.get('replay_u', 0.0):.3f} m/s, v {noise.get('replay_v', 0.0):.3f} m/s, "
                     f"r {_shown('r', noise.get('replay_r', 0.0)):.3f} °/s")
    lines.append(f"{'held-out fit':14s}" + "".join(f"{'R2 ' + k:>9s}{'MAE ' + k:>10s}" for k in "uvr")
                 + "   (MAE: u, v m/s; r °/s)")
    fits = (("before", d.fit_before), ("after", d.fit_after)) if d.effects else (("twin", d.fit_before),)
    for name, fit in fits:
        lines.append(f"{name:14s}" + "".join(f"{_num(fit[k]['r2']):>9s}{_num(_shown(k, fit[k]['mae']), 4):>10s}"
                                             for k in "uvr"))
    growth = ", ".join(f"{k}: {v.get('verdict')}" for k, v in d.growth.items())
    legend = {"dynamics": "grows", "measurement": "there from the start",
              "unsettled": "grows, but too few windows to say it does", "none": "within the noise"}
    said = [w for w in legend if w in {v.get("verdict") for v in d.growth.values()}] or ["dynamics", "measurement"]
    lines.append(f"along the free runs the residual is ({'; '.join(f'{w}: {legend[w]}' for w in said)}): {growth}")
    lines += [f"note: {n}" for n in d.notes]
    return "\n".join(lines)


def _telling(d, most: int) -> list[int]:
    """The windows where the amendment changed the twin most; with nothing amended, those where the
    twin misses the measurement most (in noise units, so that u, v and r weigh alike)."""
    rp = d.replay
    if not d.effects:
        noise = np.array([d.noise.get(k) or 1.0 for k in "uvr"])
        change = np.nanmean(np.abs(rp["before"].pred_nu - rp["before"].meas_nu) / noise, axis=(1, 2))
    else:
        change = np.nanmean(np.abs(rp["after"].pred_nu - rp["before"].pred_nu), axis=(1, 2))
    order = np.argsort(-np.nan_to_num(change))
    return sorted(order[:most].tolist())


def series_png(d, max_windows: int = 8) -> str:
    """u, v, r of the windows the amendment changed most: measured, twin before (red), twin after
    (green, dashed, drawn over it: where they agree the red shows through). With nothing amended:
    measured and twin on the windows where the twin misses most, no "after"."""
    # late: matplotlib (0.25 s) only for the HTML report, not every `twin diagnose` (nor twin.api)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rp = d.replay
    picks = _telling(d, max_windows)
    fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    offset = 0.0
    for i, j in enumerate(picks):
        w = rp["windows"][j]
        n = w.n + 1
        x = offset + np.arange(n) * 0.1
        for k, ax in enumerate(axes):
            scale = DOF_SCALE["uvr"[k]]
            ax.plot(x, scale * rp["before"].meas_nu[j, :n, k], color="k", lw=1.4, label="measured" if i == 0 else None)
            ax.plot(x, scale * rp["before"].pred_nu[j, :n, k], color="tab:red", lw=2.2, alpha=0.7,
                    label=("twin before" if d.effects else "twin") if i == 0 else None)
            if d.effects:
                ax.plot(x, scale * rp["after"].pred_nu[j, :n, k], color="tab:green", lw=1.2, ls="--",
                        label="twin after" if i == 0 else None)
        offset = x[-1] + 1.0
    for ax, dof in zip(axes, "uvr"):
        ax.set_ylabel(f"{dof} ({DOF_UNITS[dof]})")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8, ncol=3)
    axes[-1].set_xlabel("free runs of 10 s from measured states, one after another (s)")
    fig.suptitle(f"{d.prior.name}: the windows the amendment changed most" if d.effects else
                 f"{d.prior.name}: nothing named; the windows where the twin misses most", fontsize=10)
    fig.tight_layout()
    return _png(fig)


def track_png(d, max_windows: int = 8) -> str:
    """The real track and the twin's free runs before and after on the map (north up, east right),
    for the windows the amendment changed most."""
    # late: matplotlib (0.25 s) only for the HTML report, not every `twin diagnose` (nor twin.api)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rp = d.replay
    fig, ax = plt.subplots(figsize=(7, 7))
    for i, j in enumerate(_telling(d, max_windows)):
        n = rp["windows"][j].n + 1
        lines = [(rp["before"].meas_eta, dict(color="k", lw=1.4), "recorded"),
                 (rp["before"].pred_eta, dict(color="tab:red", lw=2.0, alpha=0.7), "twin before" if d.effects else "twin")]
        if d.effects:
            lines.append((rp["after"].pred_eta, dict(color="tab:green", lw=1.2, ls="--"), "twin after"))
        for eta, style, label in lines:
            ax.plot(eta[j, :n, 1], eta[j, :n, 0], label=label if i == 0 else None, **style)
        ax.plot(rp["before"].meas_eta[j, 0, 1], rp["before"].meas_eta[j, 0, 0], "k.", ms=6)
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{d.prior.name}: 10-s free runs from the dots", fontsize=10)
    fig.tight_layout()
    return _png(fig)


def _table(head: list[str], rows: list[list]) -> str:
    th = "".join(f"<th>{html.escape(str(h))}</th>" for h in head)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{th}</tr>{body}</table>"


def _num(x, digits=3) -> str:
    return "-" if x is None else f"{x:.{digits}f}" if isinstance(x, float) else str(x)


def write_html(d, path: Path) -> None:
    a = answer(d)
    eff_rows = []
    for e in d.effects:
        params = "; ".join(f"{k} = {v:.4g} [{e['ci'][k][0]:.4g}, {e['ci'][k][1]:.4g}]" if k in e["ci"] else
                           f"{k} = {v:.4g}" for k, v in e["parameters"].items())
        rivals = "; ".join(f"{r['name']}: {'told apart' if r['separable'] else 'not separable'} (z {r['z']})"
                           for r in e["rivals"]) or "-"
        gain = ", ".join(f"{k} {100 * v:.0f} %" for k, v in e["improvement"].items())
        eff_rows.append([e["name"], params, (f"{100 * e.get('excess_gain', 0):.0f} %" if e.get('excess_gain', 0) <= 1 else "> 100 %") + f" (z {e['z']})", gain, rivals])
    fits = (("before", d.fit_before), ("after", d.fit_after)) if d.effects else (("twin (nothing amended)", d.fit_before),)
    fit_rows = [[name] + [f"{_num(fit[k]['r2'])} / {_num(_shown(k, fit[k]['mae']), 4)}" for k in "uvr"]
                for name, fit in fits]
    loc_rows = [[e["dimension"], e["bin"], e["dof"], e["kind"], e["n"], _num(_shown(e["dof"], e["rms"]), 4),
                 _num(_shown(e["dof"], e["bias"]), 4), DOF_UNITS.get(e["dof"], ""), _num(e.get("rms_over_noise"), 1),
                 _num(e.get("z"), 1)] for e in d.located[:15]]
    grow_rows = [[k, v.get("verdict"), _num(_shown(k, v.get("rms_early")), 4), _num(_shown(k, v.get("rms_late")), 4),
                  DOF_UNITS.get(k, "")] for k, v in d.growth.items()]
    corr_rows = [[k] + [f"{c['signal']} ({c['r']:+.2f})" for c in v[:3]] for k, v in d.correlations.items()]
    unexpl = [[u["dof"], u["dimension"], u["bin"], _num(_shown(u["dof"], u["rms"]), 4), DOF_UNITS.get(u["dof"], ""),
               _num(u.get("rms_over_noise"), 1),
               ", ".join(f"{c['signal']} ({c['r']:+.2f})" for c in u.get("correlates_with", []))]
              for u in d.unexplained]
    noise_rows = [["GNSS position", _num(d.noise.get("gnss_m"), 3), "m"],
                  ["heading", _num(d.noise.get("heading_deg"), 2), "deg"],
                  ["u (from GNSS)", _num(d.noise.get("u"), 3), "m/s"], ["v (from GNSS)", _num(d.noise.get("v"), 3), "m/s"],
                  ["r (from heading)", _num(_shown("r", d.noise.get("r")), 3), "°/s"]]
    lead = ("<ul>" + "".join(f"<li><b>Missing</b>: {html.escape(x)}</li>" for x in a["missing"])
            + "".join(f"<li><b>The twin's form</b>: {html.escape(x)}</li>" for x in a["form"])
            + (f"<li><b>What it changes</b>: {html.escape(a['changes'])}</li>" if a["changes"] else "")
            + "".join(f"<li><b>Unsettled</b>: {html.escape(x)}</li>" for x in a["unsettled"])
            + "".join(f"<li><b>Record next</b>: {html.escape(x)}</li>" for x in a["next"]) + "</ul>")
    parts = [
        f"<h1>twin diagnose: {html.escape(d.prior.name)}</h1>", "<h2>The answer</h2>", lead,
        f"<p>{d.windows.get('windows')} free-run windows of {d.windows.get('length_s')} s in {d.windows.get('blocks')} "
        f"blocks{_block_text(d)}, every block judged once by fits that did not see it ({d.windows.get('folds')} folds); "
        f"{d.seconds:.0f} s.</p>",
        "<h2>Effects named</h2>", _table(["effect", "parameters [95 % CI]", "misfit above noise removed",
                                          "per DOF (held-out)", "rivals"], eff_rows) if eff_rows else
        "<p><b>Nothing named</b>: no effect of the library earns its place, so the twin is not amended. The "
        "residual and where it concentrates are below.</p>",
        "<h2>Held-out fit (R² / MAE; u, v in m/s, r in °/s)</h2>", _table(["twin", "u", "v", "r"], fit_rows),
        f'<img src="data:image/png;base64,{series_png(d)}" alt="free runs before and after">',
        f'<img src="data:image/png;base64,{track_png(d)}" alt="tracks before and after">',
        "<h2>Noise estimated from the recording</h2>", _table(["signal", "σ", "unit"], noise_rows),
        "<h2>Where the residual concentrates</h2>",
        _table(["dimension", "bin", "DOF", "kind", "n", "RMS", "bias", "unit", "RMS/noise", "z"], loc_rows)
        if loc_rows else "<p>no part of the data stands out from the rest (the misfit, if any, is everywhere: "
                         "see what is left)</p>",
        _table(["DOF", "residual along the free run", "RMS early", "RMS late", "unit"], grow_rows),
        _table(["DOF", "follows", "", ""], corr_rows),
        "<h2>What is left after the amendment</h2>" if d.effects else "<h2>What is left unexplained</h2>",
        _table(["DOF", "dimension", "bin", "RMS", "unit", "RMS/noise", "follows"], unexpl) if unexpl else "<p>nothing</p>",
        "".join(f"<p>note: {html.escape(n)}</p>" for n in d.notes),
    ]
    style = ("<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;"
             "margin:8px 0}td,th{border:1px solid #ccc;padding:3px 6px;font-size:13px}img{max-width:100%}</style>")
    title = f"<title>twin diagnose: {html.escape(d.prior.name)}</title>"
    write_text_atomic(Path(path), f"<!doctype html><html><head><meta charset='utf-8'>{title}{style}</head><body>"
                      + "\n".join(parts) + "</body></html>\n")
