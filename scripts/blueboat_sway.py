"""The BlueBoat's sway beyond its fitted runs: what the identified twin misses in v, and what the
figure of merit does with where the antenna is taken to be.

    python scripts/blueboat_sway.py [--out docs/results]

The twin is `twin identify` with its defaults on the five least active of the ten shared runs
[BlueBoat-SI] (twin.fit.extrapolation.by_activity), judged on the five most active in 10-s free
runs from measured states every 2 s, as on the extrapolation page. Eight looks:

1. Where the antenna is taken to be. The recordings' sway at the hull's reference point is the
   antenna's less x·r (prepare): moving the antenna along the hull by Δx adds −Δx·r to the
   measured sway, a part the twin's own r predicts. R² and MAE of the same twin, its antenna moved
   (nothing refitted), tell a better twin from a yardstick that changed.
2. What the sway residual follows: the measured less the predicted v of every free-run sample,
   regressed on u·r by speed band; and, on the prepared runs, the lag at which the measured v and
   u·r, r or the differential thrust (the twin's map of the logged PWM) correlate best (negative: v
   leads).
3. An added-mass coupling Y_ṙ = N_v̇ (zero in the shipped prior; physics/added_mass.py), set by
   hand on the identified twin: what it gives in v and costs in r.
4. Each log's compass offset fitted to that log's own sway through the twin (in-sample, one
   number per log) against the offset its straight running gives: whether the compass
   calibration is what v misses.
5. The antenna where the spins of all ten runs put it (fit/kinematic.py lever_arm, no dynamics),
   `twin identify` refitted on the fitted runs with it there, judged as above: whether a twin
   identified with another reading of the antenna predicts the sway better.
6. The sway equation alone (fit/sway_alone.py), driven by the measured u, r, ṙ and the twin's map of
   the logged PWM, in forms of growing reach, fitted on the fitted runs and on the judged runs
   themselves: how much of the measured sway any sway equation of that form predicts over 10 s when
   surge and yaw are known, not predicted.
7. The sway residual against the speed times the thrusts, u·ΔT and u·ΣT (ΔT left less right, ΣT
   their sum: the form a heading error a·ΔT + b·ΣT takes in the measured v, which it lowers by u
   times the error, as the motors' currents would give it at a magnetometer). The two
   coefficients by least squares on the fitted runs' free-run residuals, added to the twin's v on
   the judged runs; and fitted on each judged run alone (in-sample). Then the heading itself at
   every step of the differential thrust from a steady one: a heading error that follows the
   motors' current jumps with the step, where a hull's heading leaves its rate smoothly. The form
   was chosen looking at these judged runs: a check, not a proof.
8. The heading against the runs' own yaw-rate column (the dataset's `yaw_rate`, which the reader
   leaves out as the author's estimate: smoothed, and its integral drifts from the heading by
   degrees a minute as a gyro's does). Every run's heading replaced by the column's integral at
   periods shorter than τ and the compass's at longer ones (a zero-phase low-pass of their
   difference), `twin identify` refitted on the fitted runs and judged as above: a compass error
   that follows the motors' currents would leave with it. Then the sensors' timing: the
   identified twin with its GNSS fixes or its heading stamped late or early, nothing refitted and
   with `twin identify` run again on the fitted runs read with that latency.

The recordings are read in place; without them the script says so and exits 0.
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.signal import butter, filtfilt

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.vessel import Vessel  # noqa: E402
from twin.effects import apply_effects  # noqa: E402
from twin.fit.evaluate import TwinPredictor, evaluate, horizon_windows  # noqa: E402
from twin.fit import sway_alone  # noqa: E402
from twin.fit.extrapolation import by_activity  # noqa: E402
from twin.fit.kinematic import lever_arm  # noqa: E402
from twin.fit.windows import ModelCache, measured  # noqa: E402
from twin.ident.identify import calibrate, identify, prepared, read  # noqa: E402
from twin.physics.sensors import log_name  # noqa: E402
from twin.prepare import heading_lag_behind_gyro  # noqa: E402
from twin.recording import Recording, Stream  # noqa: E402
from twin.viz.pages import ResultPage, ResultTable  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "blueboat"
HORIZON_S, STRIDE_S = 10.0, 2.0
ANTENNA_DX_M = (0.15, 0.0, -0.1, -0.2, -0.3)
COUPLING_KG_M = (-2.0, 0.0, 2.0, 4.0)
SPEED_BANDS_M_S = ((-3.0, 0.0), (0.0, 0.3), (0.3, 0.8), (0.8, 1.5), (1.5, 3.0))
LAGS_S = np.round(np.arange(-1.5, 1.51, 0.1), 1)
COMPASS_ITERATIONS = 3
PIVOT_TURNING_RAD_S = 0.08
STEP_N = 15.0  # a step of the differential thrust (N) between two grid samples
STEADY_N, STEADY_S = 3.0, 1.0  # ... from a differential steady within STEADY_N over STEADY_S before it
STEP_SAMPLES = 5  # the heading read over this many grid samples after a step
FUSION_TAUS_S = (2.0, 5.0, 10.0, 30.0)  # the heading from the yaw-rate column below these periods
LATENCIES_S = (-0.4, -0.3, -0.15, 0.15, 0.3, 0.4)
SWAY_FORMS = (("v", "|v|v", "ur", "r"), ("v", "|v|v", "|u|v", "ur", "r"), ("v", "|v|v", "ur", "r", "rdot"),
              ("v", "|v|v", "ur", "r", "dT"), sway_alone.TERMS)


def scores(seen, recordings) -> tuple[dict, float]:
    """(10-s free-run {dof: (R², MAE)} on `recordings` as `seen` (a vessel with its logs' compass
    calibrations) sees them, the measured v's spread)."""
    preps = prepared(recordings, seen)
    got = evaluate(seen, preps, stride_s=STRIDE_S, horizons={"10s": HORIZON_S})["10s"]
    spread = float(np.std(np.concatenate([p.v[np.isfinite(p.v)] for p in preps])))
    return {d: (got[d]["r2"], got[d]["mae"]) for d in "uvr"}, spread


def free_run_samples(seen, recordings) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(measured (n, 3), predicted (n, 3), recording index (n,)) of every sample of the 10-s free runs."""
    m, p, rec, _ = free_run_thrust(seen, recordings)
    return m, p, rec


def free_run_thrust(seen, recordings) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """free_run_samples and the twin's thrust map of the logged PWM at each sample ((n, 2) N, left and
    right, gains applied)."""
    preps = prepared(recordings, seen)
    th = seen.thrusters
    windows = horizon_windows(preps, HORIZON_S, STRIDE_S)
    predictor = TwinPredictor(seen, ModelCache(), None)
    pred = np.full((len(windows), max(w.n for w in windows) + 1, 3), np.nan)
    groups: dict[tuple[int, int], list[int]] = {}  # one batch per recording and length
    for j, w in enumerate(windows):
        groups.setdefault((w.rec, w.n), []).append(j)
    for (rec, n), rows in groups.items():
        got = predictor.predict_windows(preps[rec], np.array([windows[j].start for j in rows]), n)
        pred[rows, : n + 1] = got[:, : n + 1]
    _, meas = measured(preps, windows)
    thrust = np.full(meas.shape[:2] + (2,), np.nan)
    for j, w in enumerate(windows):
        pwm = preps[w.rec].pwm[w.start: w.start + w.n + 1]
        thrust[j, : w.n + 1] = th.thrust_from_pwm(pwm) * np.array([th.gain_left, th.gain_right])
    rec = np.broadcast_to(np.array([w.rec for w in windows])[:, None], meas.shape[:2])[:, 1:].ravel()
    p, m, t = pred[:, 1:].reshape(-1, 3), meas[:, 1:].reshape(-1, 3), thrust[:, 1:].reshape(-1, 2)
    ok = np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(m), axis=1) & np.all(np.isfinite(t), axis=1)
    return m[ok], p[ok], rec[ok], t[ok]


def _r2(measured_v: np.ndarray, predicted_v: np.ndarray) -> float:
    return float(1.0 - np.sum((measured_v - predicted_v) ** 2) / np.sum((measured_v - measured_v.mean()) ** 2))


def _speed_thrust(m: np.ndarray, thrust: np.ndarray) -> np.ndarray:
    """(n, 2): u·ΔT and u·ΣT (m/s N)."""
    return np.column_stack([m[:, 0] * (thrust[:, 0] - thrust[:, 1]), m[:, 0] * (thrust[:, 0] + thrust[:, 1])])


def sway_with_speed_thrust(on_fitted, fitted, on_judged, judged) -> tuple[list[list], dict]:
    """Rows (the coefficients as a heading error in ° per 10 N of ΔT and of ΣT, R² v before and
    after) of u·ΔT and u·ΣT fitted on the fitted runs' free-run sway residual and judged on the
    judged runs, then fitted on each judged run alone; and the raw figures."""
    mf, pf, _, tf = free_run_thrust(on_fitted, fitted)
    mj, pj, rj, tj = free_run_thrust(on_judged, judged)
    xf, xj = _speed_thrust(mf, tf), _speed_thrust(mj, tj)
    coef = np.linalg.lstsq(xf, mf[:, 1] - pf[:, 1], rcond=None)[0]
    deg_10n = lambda c: [float(-np.degrees(x) * 10.0) for x in c]  # v lowered by u·δ: δ = −coefficient·T
    rows = [["fitted runs → judged runs", *deg_10n(coef), _r2(mj[:, 1], pj[:, 1]), _r2(mj[:, 1], pj[:, 1] + xj @ coef)]]
    raw = {"fitted_on_fitted_deg_per_10n": deg_10n(coef), "judged_runs": []}
    for k, rec in enumerate(judged):
        s = rj == k
        own = np.linalg.lstsq(xj[s], mj[s, 1] - pj[s, 1], rcond=None)[0]
        rows.append([f"{log_name(rec.source)} alone", *deg_10n(own), _r2(mj[s, 1], pj[s, 1]),
                     _r2(mj[s, 1], pj[s, 1] + xj[s] @ own)])
        raw["judged_runs"].append({"log": log_name(rec.source), "deg_per_10n": deg_10n(own),
                                   "spread_u_dT": float(np.std(xj[s, 0]))})
    raw["r2_v_judged"] = rows[0][3:]
    return rows, raw


def heading_at_steps(seen, recordings) -> np.ndarray:
    """(steps, STEP_SAMPLES): the heading after each step of the differential thrust ΔT (the twin's
    map of the logged PWM) of at least STEP_N from a ΔT steady within STEADY_N over STEADY_S: its
    change from the sample before the step less that sample's rate carried on, in ° per 10 N of the
    step (signed with it), at each grid sample from the step's own."""
    th = seen.thrusters
    changes = []
    for p in prepared(recordings, seen):
        d_thrust = (th.thrust_from_pwm(p.pwm) * np.array([th.gain_left, th.gain_right])) @ np.array([1.0, -1.0])
        before = int(round(STEADY_S / p.settings.grid_dt))
        k = np.arange(STEP_SAMPLES)
        for seg in p.segments:
            for i in range(seg.start + before + 1, seg.stop - STEP_SAMPLES):
                step = d_thrust[i] - d_thrust[i - 1]
                if abs(step) < STEP_N or np.ptp(d_thrust[i - before: i]) > STEADY_N:
                    continue
                rate = (p.psi[i - 1] - p.psi[i - 6]) / 5.0  # rad per sample, over the half second before
                changes.append(np.degrees(p.psi[i + k] - p.psi[i - 1] - rate * (k + 1)) * 10.0 / step)
    return np.array(changes).reshape(-1, STEP_SAMPLES)


def sway_residual(seen, recordings) -> list[list]:
    """Per speed band: window samples, the correlation of the sway residual with u·r and its slope (s)."""
    m, p, _ = free_run_samples(seen, recordings)
    residual, u, ur = (m[:, 1] - p[:, 1]), m[:, 0], m[:, 0] * m[:, 2]
    rows = []
    for lo, hi in SPEED_BANDS_M_S:
        k = (u >= lo) & (u < hi)
        if k.sum() >= 50:
            rows.append([f"{lo:g} to {hi:g}".replace("-", "−"), int(k.sum()), float(np.corrcoef(ur[k], residual[k])[0, 1]),
                         float(np.polyfit(ur[k], residual[k], 1)[0])])
    rows.append(["all", int(len(u)), float(np.corrcoef(ur, residual)[0, 1]), float(np.polyfit(ur, residual, 1)[0])])
    return rows


def pivot_points(seen, recordings) -> list[list]:
    """Per speed band of the free-run samples turning faster than PIVOT_TURNING_RAD_S: where along the
    hull the sway vanishes (x = −v/r by least squares through the origin, m from the reference point,
    negative aft), measured and as the twin predicts it, with the correlation of the measured v and r."""
    m, p, _ = free_run_samples(seen, recordings)
    rows = []
    for lo, hi in SPEED_BANDS_M_S:
        k = (m[:, 0] >= lo) & (m[:, 0] < hi) & (np.abs(m[:, 2]) > PIVOT_TURNING_RAD_S)
        if k.sum() < 50:
            continue
        measured_x = -float(np.sum(m[k, 1] * m[k, 2]) / np.sum(m[k, 2] ** 2))
        predicted_x = -float(np.sum(p[k, 1] * p[k, 2]) / np.sum(p[k, 2] ** 2))
        rows.append([f"{lo:g} to {hi:g}".replace("-", "−"), int(k.sum()), float(np.mean(np.abs(m[k, 2]))),
                     measured_x, float(np.corrcoef(m[k, 1], m[k, 2])[0, 1]), predicted_x])
    return rows


def compass_from_sway(seen, recordings) -> Vessel:
    """`seen` with each log's compass offset moved to where the twin's sway puts it: the offset δ that
    takes u·δ (a compass reading δ high lowers the measured v by u·δ) out of the log's sway residual,
    COMPASS_ITERATIONS times (the free runs start from the measured states the offset also moves).
    In-sample, one number per log: an upper mark for what a better compass calibration could give."""
    names = [log_name(r.source) for r in recordings]
    for _ in range(COMPASS_ITERATIONS):
        m, p, rec = free_run_samples(seen, recordings)
        residual, u = m[:, 1] - p[:, 1], m[:, 0]
        table = dict(seen.sensors.heading_bias_by_log_deg)
        for k in np.unique(rec):
            s = rec == k
            slope = float(np.linalg.lstsq(u[s][:, None], residual[s], rcond=None)[0][0])
            table[names[k]] = table.get(names[k], 0.0) - float(np.degrees(slope))  # on top of the common bias
        seen = replace(seen, sensors=replace(seen.sensors, heading_bias_by_log_deg=tuple(sorted(table.items()))))
    return seen


def lead_of_sway(seen, recordings, signal) -> tuple[float, float]:
    """(lag s of the best correlation of the measured v with signal(prep) (u·r, or r), that correlation)
    over the prepared runs' segments; a negative lag: v leads."""
    preps = prepared(recordings, seen)
    best = (0.0, -np.inf)
    for lag_s in LAGS_S:
        xs, ys = [], []
        for p in preps:
            k = int(round(lag_s / p.settings.grid_dt))
            for seg in p.segments:
                v, ur = p.v[seg.start:seg.stop], signal(p)[seg.start:seg.stop]
                if len(v) <= abs(k) + 10:
                    continue
                a, b = (v[k:], ur[:len(ur) - k]) if k >= 0 else (v[:k], ur[-k:])
                ok = np.isfinite(a) & np.isfinite(b)
                xs.append(b[ok])
                ys.append(a[ok])
        c = float(np.corrcoef(np.concatenate(xs), np.concatenate(ys))[0, 1])
        if c > best[1]:
            best = (float(lag_s), c)
    return best


def yaw_rate_column(rec: Recording) -> Stream:
    """The dataset's own `yaw_rate` column (rad/s) on the recording's clock (the reader leaves it out)."""
    with open(rec.source) as fh:
        header = fh.readline().strip().split(",")
    data = np.genfromtxt(rec.source, delimiter=",", skip_header=1,
                         usecols=(header.index("original_timestamp"), header.index("yaw_rate")))
    ok = np.all(np.isfinite(data), axis=1)
    return Stream(data[ok, 0] * 1e-3 - rec.origin_s, {"yaw_rate_rads": data[ok, 1]})


def heading_on_rate(rec: Recording, tau_s: float) -> tuple[Recording, float]:
    """`rec` with its heading the yaw-rate column's integral at periods under tau_s and the compass's
    above (look 8), and the RMS change of the heading (°)."""
    rate = yaw_rate_column(rec)
    t = rec.heading.t
    psi = np.unwrap(rec.heading["psi_rad"])
    r = np.interp(t, rate.t, rate["yaw_rate_rads"])
    turned = np.r_[0.0, np.cumsum(0.5 * (r[1:] + r[:-1]) * np.diff(t))]
    b, a = butter(2, 1.0 / (2 * np.pi * tau_s) / (0.5 / float(np.median(np.diff(t)))))
    fused = turned + filtfilt(b, a, psi - turned)
    out = replace(rec, heading=Stream(t, {**rec.heading.columns, "psi_rad": np.mod(fused, 2 * np.pi)}))
    return out, float(np.degrees(np.sqrt(np.mean((psi - fused) ** 2))))


def rate_column_checks(recordings: list[Recording]) -> list[list]:
    """Per run: the heading against the column's integral (heading_lag_behind_gyro, the column taken
    for a gyro) and the drift of the integral from the heading (°/min, least squares over the run)."""
    rows = []
    for rec in recordings:
        rate = yaw_rate_column(rec)
        lag = heading_lag_behind_gyro(replace(rec, imu=rate))
        t = rec.heading.t
        r = np.interp(t, rate.t, rate["yaw_rate_rads"])
        turned = np.r_[0.0, np.cumsum(0.5 * (r[1:] + r[:-1]) * np.diff(t))]
        drift = np.polyfit(t, np.degrees(np.unwrap(rec.heading["psi_rad"]) - turned), 1)[0] * 60.0
        rows.append([log_name(rec.source), "not told" if lag.lag_s is None else f"{lag.lag_s:+.2f} ± {lag.sigma_s:.2f}",
                     float(drift)])
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results")
    args = ap.parse_args()
    paths = sorted(DATA.glob("fixed_*.csv"))
    if not paths:
        print(f"the BlueBoat recordings are not in {DATA}: nothing to do")
        return 0
    started = time.time()
    prior = vessel_mod.load("blueboat")
    recordings = read(paths)
    split = by_activity(prepared(recordings, prior))
    by_name = {log_name(r.source): r for r in recordings}
    fitted = [by_name[n] for n in split.fitted]
    judged = [by_name[n] for n in split.judged]
    twin = identify(fitted, prior, sources=[r.source for r in fitted]).vessel
    # each log's compass calibration read once, with the twin's own antenna: a moved antenna then
    # changes the measured sway by x·r alone
    on_judged, _ = calibrate(judged, twin)
    on_fitted, _ = calibrate(fitted, twin)

    antenna_rows, raw_antenna = [], []
    for dx in ANTENNA_DX_M:
        moved = apply_effects(on_judged, [("gnss_lever_arm", {"dx_m": dx, "dy_m": 0.0})]) if dx else on_judged
        got, spread = scores(moved, judged)
        raw_antenna.append({"dx_m": dx, "scores": got, "v_spread_m_s": spread})
        antenna_rows.append([f"{dx:+.2f}", spread, *[x for d in "uvr" for x in got[d]]])
    residual_rows = sway_residual(on_judged, judged)
    pivot_rows = pivot_points(on_judged, judged)
    th = twin.thrusters

    def differential_thrust_n(p):  # the twin's thrust map of the logged PWM, left less right
        thrust = th.thrust_from_pwm(p.pwm) * np.array([th.gain_left, th.gain_right])
        return thrust[:, 0] - thrust[:, 1]
    leads = {f"{runs}, against {name}": lead_of_sway(seen, recs, signal)
             for runs, seen, recs in (("fitted", on_fitted, fitted), ("judged", on_judged, judged))
             for name, signal in (("u·r", lambda p: p.u * p.r), ("r", lambda p: p.r),
                                  ("the differential thrust", differential_thrust_n))}
    coupling_rows, raw_coupling = [], []
    for c in COUPLING_KG_M:
        coupled = replace(on_judged, added_mass=replace(on_judged.added_mass, Yrdot=c, Nvdot=c))
        got, _ = scores(coupled, judged)
        raw_coupling.append({"Yrdot_kg_m": c, "scores": got})
        coupling_rows.append([f"{c:+g}", *[got[d][0] for d in "uvr"]])
    compass_rows, raw_compass = [], []
    for runs, seen, recs in (("judged", on_judged, judged), ("fitted", on_fitted, fitted)):
        kinematic, _ = scores(seen, recs)
        swayed = compass_from_sway(seen, recs)
        got, _ = scores(swayed, recs)
        before, after = dict(seen.sensors.heading_bias_by_log_deg), dict(swayed.sensors.heading_bias_by_log_deg)
        common = seen.sensors.heading_bias_deg  # a log's own bias adds to it (physics.sensors)
        for r in recs:
            name = log_name(r.source)
            compass_rows.append([runs, name, common + before.get(name, 0.0), common + after.get(name, 0.0)])
        compass_rows.append([runs, "R² v (u, r)", f"{kinematic['v'][0]:.3f} ({kinematic['u'][0]:.3f}, "
                             f"{kinematic['r'][0]:.3f})", f"{got['v'][0]:.3f} ({got['u'][0]:.3f}, {got['r'][0]:.3f})"])
        raw_compass.append({"runs": runs, "kinematic": {**before}, "from_sway": {**after},
                            "scores_kinematic": kinematic, "scores_from_sway": got})
    spins = lever_arm(recordings, prior)
    found = (spins.change.get("dx_m", 0.0), spins.change.get("dy_m", 0.0))
    refit_rows, raw_refit = [], []
    for label, (dx, dy) in (("where the spins put it", found), ("its x alone", (found[0], 0.0)),
                            ("its y alone", (0.0, found[1]))):
        placed = replace(prior, sensors=replace(prior.sensors, antenna_offset_m=(dx, dy)))
        refit = identify(fitted, placed, sources=[r.source for r in fitted]).vessel
        got, spread = scores(calibrate(judged, refit)[0], judged)
        raw_refit.append({"antenna": label, "dx_m": dx, "dy_m": dy, "scores": got, "v_spread_m_s": spread})
        refit_rows.append([label, f"{dx:+.2f}", f"{dy:+.2f}", spread, got["u"][0], got["v"][0], got["v"][1],
                           got["r"][0]])
    drivers = {runs: [sway_alone.SwayDrivers(p.u, p.v, p.r, differential_thrust_n(p), p.segment, p.settings.grid_dt)
                      for p in prepared(recs, seen)]
               for runs, seen, recs in (("fitted", on_fitted, fitted), ("judged", on_judged, judged))}
    alone_rows, raw_alone = [], []
    best: dict[str, list] = {}  # each form starts from the best smaller form it holds
    for form in SWAY_FORMS:
        fits = {}
        for runs in ("fitted", "judged"):
            nested = [f for f in best.get(runs, []) if set(f.terms) <= set(form)]
            start = max(nested, key=lambda f: f.r2).coefficients if nested else None
            fits[runs] = sway_alone.fit(drivers[runs], form, HORIZON_S, STRIDE_S, start=start)
            best.setdefault(runs, []).append(fits[runs])
        on_fit, on_own = fits["fitted"], fits["judged"]
        beyond = sway_alone.score(on_fit.coefficients, drivers["judged"], HORIZON_S, STRIDE_S)
        raw_alone.append({"terms": list(form), "fitted_on_fitted": on_fit.coefficients, "r2_fitted": on_fit.r2,
                          "r2_judged": beyond, "fitted_on_judged": on_own.coefficients, "r2_judged_own": on_own.r2})
        alone_rows.append([", ".join(form), on_fit.r2, beyond, on_own.r2])
    thrust_rows, raw_thrust = sway_with_speed_thrust(on_fitted, fitted, on_judged, judged)
    steps = np.vstack([heading_at_steps(on_fitted, fitted), heading_at_steps(on_judged, judged)])
    grid_dt = prepared(fitted[:1], on_fitted)[0].settings.grid_dt
    step_rows = [[f"{k * grid_dt:.1f}", float(steps[:, k].mean()), float(steps[:, k].std(ddof=1) / np.sqrt(len(steps)))]
                 for k in range(STEP_SAMPLES)] if len(steps) > 1 else []
    rate_rows = rate_column_checks(recordings)
    fused_rows, raw_fused = [], []
    for tau in FUSION_TAUS_S:
        on_rate = {log_name(r.source): heading_on_rate(r, tau) for r in recordings}
        fit_recs = [on_rate[log_name(r.source)][0] for r in fitted]
        judged_recs = [on_rate[log_name(r.source)][0] for r in judged]
        refit = identify(fit_recs, prior, sources=[r.source for r in fit_recs]).vessel
        got, _ = scores(calibrate(judged_recs, refit)[0], judged_recs)
        change = float(np.sqrt(np.mean([x[1] ** 2 for x in on_rate.values()])))
        raw_fused.append({"tau_s": tau, "heading_rms_change_deg": change, "scores": got})
        fused_rows.append([f"{tau:g}", change, *[got[d][0] for d in "uvr"]])
    timing_rows, raw_timing = [], []
    for what, label in (("gnss_latency_s", "GNSS"), ("heading_latency_s", "heading")):
        for latency in LATENCIES_S:
            late = replace(twin, sensors=replace(twin.sensors, **{what: latency}))
            got, _ = scores(calibrate(judged, late)[0], judged)
            # the same latency in the prior, the twin identified with it: a twin that read the fitted runs
            # through a late stream is not the one that read them on time
            late_prior = replace(prior, sensors=replace(prior.sensors, **{what: latency}))
            refit = identify(fitted, late_prior, sources=[r.source for r in fitted]).vessel
            beyond, _ = scores(calibrate(judged, refit)[0], judged)
            own, _ = scores(calibrate(fitted, refit)[0], fitted)
            raw_timing.append({"stream": what, "latency_s": latency, "scores": got, "refit_scores": beyond,
                               "refit_scores_fitted": own})
            timing_rows.append([label, f"{latency:+.2f}", *[got[d][0] for d in "uvr"],
                                *[beyond[d][0] for d in "uvr"], own["v"][0], own["r"][0]])
    base = raw_antenna[ANTENNA_DX_M.index(0.0)]["scores"]
    refit_rows.insert(0, ["the twin's (its MJCF site)", "+0.00", "+0.00",
                          raw_antenna[ANTENNA_DX_M.index(0.0)]["v_spread_m_s"], base["u"][0], base["v"][0],
                          base["v"][1], base["r"][0]])
    best_refit = max(raw_refit, key=lambda x: x["scores"]["v"][0])
    answers = twin.sensors.input_answer_s
    aft = raw_antenna[-1]
    best_late = max(raw_timing, key=lambda x: x["refit_scores"]["v"][0])
    at = LATENCIES_S.index(best_late["latency_s"])  # its neighbours: the latencies on either side, same stream
    neighbours = " and ".join(f"{x['refit_scores']['v'][0]:.3f} at {x['latency_s']:+g} s" for x in raw_timing
                              if x["stream"] == best_late["stream"]
                              and x["latency_s"] in LATENCIES_S[max(at - 1, 0): at + 2]
                              and x["latency_s"] != best_late["latency_s"])
    summary = (
        f"The identified twin predicts the most active runs' sway at R² {base['v'][0]:.3f} (MAE {base['v'][1]:.4f} m/s). "
        f"Taking the antenna {abs(ANTENNA_DX_M[-1]):g} m further aft raises that R² to {aft['scores']['v'][0]:.3f} "
        f"while the MAE grows to {aft['scores']['v'][1]:.4f} m/s: the measured sway gains a part x·r that the "
        f"twin's own r predicts (its spread {raw_antenna[ANTENNA_DX_M.index(0.0)]['v_spread_m_s']:.4f} → "
        f"{aft['v_spread_m_s']:.4f} m/s), so the R² of v moves with the yardstick, not the twin. What the twin misses "
        f"follows u·r (correlation {residual_rows[-1][2]:.2f} over all samples); in turns under way the hull "
        f"pivots about a point {abs(pivot_rows[-1][3]):.2f} m {'aft' if pivot_rows[-1][3] < 0 else 'forward'} of the "
        f"reference point at {pivot_rows[-1][0]} m/s, where the twin puts it {abs(pivot_rows[-1][5]):.2f} m "
        f"{'aft' if pivot_rows[-1][5] < 0 else 'forward'}; the measured v leads u·r "
        f"(best at {leads['judged, against u·r'][0]:+.1f} s on the judged runs, "
        f"{leads['fitted, against u·r'][0]:+.1f} s on the fitted; r itself by {-leads['judged, against r'][0]:.1f} "
        f"and {-leads['fitted, against r'][0]:.1f} s), "
        "where a sway that answers the turn through its own lag would follow it; it follows the differential "
        f"thrust closely (correlation {leads['judged, against the differential thrust'][1]:.2f} at "
        f"{leads['judged, against the differential thrust'][0]:+.1f} s on the judged runs). With r the heading's slope "
        "(the yaw-rate column of these logs is not read: see below), a heading stamped that much late would read the same, but on the fitted runs "
        f"the heading answers the input steps within {abs(answers[1] - answers[0]):.2f} s of the GNSS (the "
        f"twin's input answers: surge {answers[0]:+.2f} s, yaw {answers[1]:+.2f} s; fit/kinematic.py). An "
        "added-mass coupling set by hand buys v only with r. Each log's compass offset fitted to its own sway "
        f"(in-sample, one number per log) takes v to {raw_compass[0]['scores_from_sway']['v'][0]:.3f} on the judged "
        f"runs and {raw_compass[1]['scores_from_sway']['v'][0]:.3f} on the fitted: the compass calibration is not "
        f"what v misses. Refitted with the antenna where the runs' spins put it ({found[0]:+.2f} m along, "
        f"{found[1]:+.2f} m across), or with either part of that alone, the twin predicts v at R² "
        f"{min(x['scores']['v'][0] for x in raw_refit):.3f} to {best_refit['scores']['v'][0]:.3f}: no reading of the "
        "antenna these runs allow is what v misses either. The sway equation alone, driven by the measured surge, yaw "
        "rate and thrust instead of the twin's predictions, reaches 10-s R² v "
        f"{max(x['r2_judged'] for x in raw_alone):.3f} at best on the judged runs when fitted on the fitted ones, "
        f"and {max(x['r2_judged_own'] for x in raw_alone):.3f} at best fitted on the judged runs themselves: no "
        "sway equation of these forms predicts much more of these runs' sway, even with u and r known. "
        f"What is left follows the speed times the differential thrust: u·ΔT and u·ΣT fitted on the fitted runs' "
        f"residual take the judged runs' v from R² {thrust_rows[0][3]:.3f} to {thrust_rows[0][4]:.3f} (the form "
        "looked at on these runs first: a check, not a proof); it is the form a heading error that grows with "
        f"the motors' currents takes, {thrust_rows[0][1]:+.2f}° per 10 N of ΔT, but the heading does not jump "
        f"at a step of ΔT ({step_rows[1][1]:+.2f} ± {step_rows[1][2]:.2f}° per 10 N one sample after "
        f"{len(steps)} steps, then growing as a turn's does), so it is not a compass that follows the current "
        "at once. Nor is it a slower compass error: with the heading taken from the runs' own yaw-rate column at "
        f"periods under {FUSION_TAUS_S[0]:g} to {FUSION_TAUS_S[-1]:g} s (it changes the heading by "
        f"{min(x['heading_rms_change_deg'] for x in raw_fused):.1f}-{max(x['heading_rms_change_deg'] for x in raw_fused):.1f}° "
        "RMS) and the twin refitted, v on the judged runs reads "
        f"{min(x['scores']['v'][0] for x in raw_fused):.3f} to {max(x['scores']['v'][0] for x in raw_fused):.3f}; with "
        f"the GNSS or the heading stamped up to {max(LATENCIES_S):g} s late or early, "
        f"{min(x['scores']['v'][0] for x in raw_timing):.3f} to {max(x['scores']['v'][0] for x in raw_timing):.3f}; "
        f"identified again with that latency, {min(x['refit_scores']['v'][0] for x in raw_timing):.3f} to "
        f"{best_late['refit_scores']['v'][0]:.3f}, the highest ({best_late['stream'].split('_')[0]} "
        f"{best_late['latency_s']:+g} s) with r at {best_late['refit_scores']['r'][0]:.3f} and its neighbours "
        f"{neighbours}: v bought with r, not a timing the runs agree on." if step_rows else "sway equation of these forms predicts much more of these runs' sway, even with u and r known.")
    page = ResultPage(
        "blueboat_sway", "The BlueBoat's sway beyond its fitted runs", "python scripts/blueboat_sway.py",
        f"The ten shared BlueBoat runs [BlueBoat-SI]; `twin identify` with its defaults on the five least active "
        f"({', '.join(split.fitted)}), judged on the five most active ({', '.join(split.judged)}), 10-s free "
        "runs from measured states every 2 s",
        summary,
        [ResultTable("The same twin with its antenna moved along the hull (nothing refitted, each log's compass "
                     "calibration held): 10-s R² and MAE (u, v m/s; r rad/s) on the judged runs",
                     ["antenna Δx (m)", "spread of measured v (m/s)", "R² u", "MAE u", "R² v", "MAE v", "R² r",
                      "MAE r"], antenna_rows),
         ResultTable("The sway residual (measured less predicted v, every free-run sample on the judged runs) "
                     "against u·r, by speed",
                     ["u (m/s)", "window samples (overlapping)", "correlation with u·r", "slope (s)"],
                     residual_rows),
         ResultTable(f"Where the hull pivots in turns (|r| > {PIVOT_TURNING_RAD_S:g} rad/s, every free-run sample on "
                     "the judged runs): the point along the hull whose sway vanishes, x = −v/r (m from the reference "
                     "point, negative aft), measured and as the twin predicts it",
                     ["u (m/s)", "window samples (overlapping)", "mean |r| (rad/s)", "measured x (m)",
                      "correlation of v and r", "twin's x (m)"], pivot_rows),
         ResultTable("The measured v against u·r, r and the differential thrust on the prepared runs: the lag "
                     "of the best correlation (negative: v leads)",
                     ["runs", "lag (s)", "correlation"],
                     [[k, lag, c] for k, (lag, c) in leads.items()]),
         ResultTable("An added-mass coupling Y_ṙ = N_v̇ set on the identified twin (nothing refitted): 10-s R² "
                     "on the judged runs", ["Y_ṙ = N_v̇ (kg m)", "R² u", "R² v", "R² r"], coupling_rows),
         ResultTable("Each log's compass offset (°): from its straight running (fit/calibrate.py, as every page "
                     "reads it; a log without enough keeps the twin's) and fitted to its own sway through the "
                     "twin (compass_from_sway: in-sample); last row of each group: the 10-s R² v (u, r) with each",
                     ["runs", "log", "from straight running", "fitted to its sway"], compass_rows),
         ResultTable(f"The antenna where the spins of all ten runs put it (kinematic.lever_arm: {spins.basis}; "
                     f"{spins.why}), `twin identify` refitted on the fitted runs with it there: 10-s R² (and MAE v, "
                     "m/s) on the judged runs",
                     ["antenna", "Δx (m)", "Δy (m)", "spread of measured v (m/s)", "R² u", "R² v", "MAE v", "R² r"],
                     refit_rows),
         ResultTable("The sway equation alone (fit/sway_alone.py: v̇ = −θ_v·v − θ_|v|v·|v|v − θ_|u|v·|u|v + θ_ur·u·r "
                     "+ θ_r·r + θ_ṙ·ṙ + θ_ΔT·ΔT), driven by the measured u, r, ṙ and the twin's thrust map of the "
                     "logged PWM (ΔT left less right), 10-s free runs of v from measured starts every 2 s: R² v",
                     ["terms", "fitted on the fitted runs: R² there", "the same, R² on the judged runs",
                      "fitted on the judged runs: R² there"], alone_rows),
         ResultTable("The sway residual against the speed times the thrusts (the twin's map of the logged PWM): "
                     "u·ΔT and u·ΣT by least squares, as the heading error δ = a·ΔT + b·ΣT they would be (the "
                     "measured v lowered by u·δ); 10-s R² v without and with them",
                     ["fitted on", "a (° per 10 N of ΔT)", "b (° per 10 N of ΣT)", "R² v, the twin",
                      "R² v, with u·ΔT and u·ΣT"], thrust_rows),
         ResultTable(f"The heading at each step of ΔT of {STEP_N:g} N or more from a ΔT steady within {STEADY_N:g} N "
                     f"over {STEADY_S:g} s ({len(steps)} steps, all ten runs): its change less the rate before "
                     "carried on, ° per 10 N of the step; a heading error of a·ΔT would show a from the step's "
                     "own sample on", ["s after the step", "mean (° per 10 N)", "standard error"], step_rows),
         ResultTable("The runs' own yaw-rate column taken for a gyro: the heading's delay against it "
                     "(prepare/timing.py; negative: the heading leads) and how fast its integral drifts from the "
                     "heading over the run", ["log", "heading against the column (s)", "drift (° per minute)"],
                     rate_rows),
         ResultTable("The heading from the yaw-rate column at periods under τ and from the compass above, every run, "
                     "`twin identify` refitted on the fitted runs: 10-s R² on the judged runs",
                     ["τ (s)", "heading changed (° RMS)", "R² u", "R² v", "R² r"], fused_rows),
         ResultTable("The identified twin with its GNSS fixes or its heading stamped late (negative: early): "
                     "10-s R² on the judged runs with nothing refitted, and with `twin identify` run again on the "
                     "fitted runs read with that latency (and that twin's R² v, r on the fitted runs themselves)",
                     ["stream", "latency (s)", "R² u", "R² v", "R² r", "refitted: R² u", "R² v", "R² r",
                      "on the fitted runs: R² v", "R² r"], timing_rows)],
        notes=["A lever arm moves the sway at the reference point by x·r exactly (prepare); where the real "
               "antenna sits is not settled by the kinematics of these runs' spins (kinematic.lever_arm: the "
               "hull creeps while it spins)."],
        raw={"split": {"fitted": list(split.fitted), "judged": list(split.judged)}, "antenna": raw_antenna,
             "residual_by_speed": residual_rows, "lead_of_v_over_ur": leads, "coupling": raw_coupling,
             "input_answer_s": list(answers), "compass": raw_compass, "pivot_by_speed": pivot_rows,
             "antenna_refit": raw_refit, "spins": spins.to_dict(), "sway_alone": raw_alone,
             "speed_thrust": raw_thrust, "heading_at_steps": step_rows, "steps": len(steps),
             "rate_column": rate_rows, "heading_on_rate": raw_fused, "timing": raw_timing,
             "seconds": round(time.time() - started, 1)})
    print(page.write(args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
