"""What the BlueBoat's turns under way tell of where its GNSS antenna sits, from kinematics alone.

    python scripts/antenna_under_way.py [--page-only] [--out DIR]

The diagnosis reads the antenna only from turns on the spot (twin.fit.kinematic.lever_arm). Under way,
the velocity over ground at an antenna p = (x, y) (body axes, forward and to starboard) is the hull's
plus r × p: u_g = u − r·y and v_g = v + r·x. Neither u nor v is known without a dynamic model, so each
reading takes a form for them that needs no twin:

- x: v_g, read at the twin's reference point, regressed on r (one coefficient per run: its reading),
  u_g·r (a steady sideslip growing with speed and rate, as the Munk moment's sway balance gives; one
  coefficient for all runs, u_g the surge over ground at the antenna), and per run a constant sway and
  the current across the hull (−sin ψ, cos ψ). It reads the antenna against the twin's plus the hull's
  own sway per unit rate at rest;
- y: u_g, read at the twin's reference point, within WINDOW_S windows (end to end) in which r moves by
  at least MIN_SWING_RAD_S, less a line in time, r², and the current along the hull (cos ψ, sin ψ) per
  window; y is minus the coefficient of r. It reads the antenna against the twin's plus whatever of
  the surge's answer to the thrust is odd in the turn's hand.

Either reading moves with the antenna (the last row moves it on purpose); whether a diagnosis could
name an antenna from them depends on how far they move from run to run with the antenna where it is.
Without ../shared/data the script says so and exits 0.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.engine.mjcf import compile_vessel  # noqa: E402
from twin.fit.extrapolation import by_activity  # noqa: E402
from twin.ident.identify import calibrate, prepared, read  # noqa: E402
from twin.physics.sensors import antenna_body_m, log_name  # noqa: E402
from twin.prepare.prepared import Prepared  # noqa: E402
from twin.viz.pages import ResultPage, ResultTable, study_main  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "blueboat"
# samples that count for x: turning at least this fast, where an antenna 0.1 m off (the smallest the
# spins tell) moves the sideways velocity by 0.01 m/s, twice the prepared v's white noise (0.005 m/s)
TURNING_RAD_S = 0.1
MIN_EACH_HAND_S = 5.0  # of turning to each side: a run turning one way only cannot tell its constant sway from x
WINDOW_S, MIN_SWING_RAD_S = 6.0, 0.2
MIN_WINDOWS = 6
MOVED_M = 0.3
MAD_TO_SIGMA = 1.4826


@dataclass(frozen=True)
class Turning:
    """One run's samples in turns: surge over ground at the antenna u_g, v and u at the twin's
    reference point (m/s), yaw rate r (rad/s), heading ψ (rad)."""

    u_g: np.ndarray
    u: np.ndarray
    v: np.ndarray
    r: np.ndarray
    psi: np.ndarray


def _turning(prep: Prepared, antenna_m: np.ndarray) -> Turning | None:
    """The samples of `prep` turning at TURNING_RAD_S or more, None where either hand has under
    MIN_EACH_HAND_S of them. antenna_m: the twin's antenna (x, y), where prepare read u and v from."""
    m = np.isfinite(prep.u) & np.isfinite(prep.v) & (np.abs(prep.r) >= TURNING_RAD_S)
    dt = prep.settings.grid_dt
    if min(np.sum(m & (prep.r > 0)), np.sum(m & (prep.r < 0))) * dt < MIN_EACH_HAND_S:
        return None
    # prepare moved the fixes' velocity from the antenna to the reference point: u = u_g + r·y
    u_g = prep.u[m] - prep.r[m] * float(antenna_m[1])
    return Turning(u_g, prep.u[m], prep.v[m], prep.r[m], prep.psi[m])


def _x_readings(runs: list[Turning], shared_x: bool) -> list[float]:
    """x (m) per run (or one for all with `shared_x`) from v on r, u_g·r, and per run a constant
    sway and the current across the hull (module docstring)."""
    r = np.concatenate([t.r for t in runs])
    which = np.concatenate([np.full(len(t.r), k) for k, t in enumerate(runs)])
    psi = np.concatenate([t.psi for t in runs])
    arm = [r] if shared_x else [np.where(which == k, r, 0.0) for k in range(len(runs))]
    cols = arm + [np.concatenate([t.u_g * t.r for t in runs])]
    for k in range(len(runs)):
        own = which == k
        cols += [own.astype(float), np.where(own, -np.sin(psi), 0.0), np.where(own, np.cos(psi), 0.0)]
    coef = np.linalg.lstsq(np.column_stack(cols), np.concatenate([t.v for t in runs]), rcond=None)[0]
    return [float(c) for c in coef[:len(arm)]]


def _y_reading(preps: list[Prepared]) -> tuple[float | None, int]:
    """y (m) from u's part that follows r within end-to-end windows (module docstring), None from
    under MIN_WINDOWS of them; the windows used."""
    r_part, u_part = [], []
    for p in preps:
        ok = np.isfinite(p.u) & np.isfinite(p.r)
        for start in np.arange(p.t[0], p.t[-1] - WINDOW_S, WINDOW_S):
            m = ok & (p.t >= start) & (p.t < start + WINDOW_S)
            if m.sum() < 10 or np.ptp(p.r[m]) < MIN_SWING_RAD_S:
                continue
            t_s = p.t[m] - start
            basis = np.column_stack([np.ones_like(t_s), t_s, p.r[m] ** 2, np.cos(p.psi[m]), np.sin(p.psi[m])])
            out = np.eye(len(t_s)) - basis @ np.linalg.pinv(basis)
            r_part.append(out @ p.r[m])
            u_part.append(out @ p.u[m])
    if len(r_part) < MIN_WINDOWS:
        return None, len(r_part)
    r_res, u_res = np.concatenate(r_part), np.concatenate(u_part)
    return float(-(r_res @ u_res) / (r_res @ r_res)), len(r_part)


def _readings(names: list[str], preps: dict[str, Prepared], antenna_m: np.ndarray) -> list[dict]:
    """One row per run, then the five most active and all runs pooled (one x each)."""
    turning = {n: _turning(preps[n], antenna_m) for n in names}
    read_runs = [n for n in names if turning[n] is not None]
    per_run = dict(zip(read_runs, _x_readings([turning[n] for n in read_runs], shared_x=False))) if read_runs else {}
    rows = []
    for n in names:
        y, windows = _y_reading([preps[n]])
        rows.append({"runs": n, "x_m": per_run.get(n), "turning_s": 0.0 if turning[n] is None else
                     round(len(turning[n].r) * preps[n].settings.grid_dt, 1), "y_m": y, "y_windows": windows})
    return rows


def _pooled(label: str, names: list[str], preps: dict[str, Prepared], antenna_m: np.ndarray) -> dict:
    turning = [t for t in (_turning(preps[n], antenna_m) for n in names) if t is not None]
    y, windows = _y_reading([preps[n] for n in names])
    return {"runs": label, "x_m": _x_readings(turning, shared_x=True)[0] if turning else None,
            "turning_s": round(sum(len(t.r) for t in turning) * preps[names[0]].settings.grid_dt, 1),
            "y_m": y, "y_windows": windows}


def run_study() -> dict:
    """Every run's readings, the pooled ones, and the five most active again with the twin's antenna
    moved MOVED_M back and to port (the data's antenna then MOVED_M forward and to starboard of it)."""
    prior = vessel_mod.load("blueboat")
    recs = read(sorted(DATA.glob("fixed_*.csv")))
    calibrated = calibrate(recs, prior)[0]
    names = [log_name(r.source) for r in recs]
    preps = dict(zip(names, prepared(recs, calibrated)))
    active = list(by_activity([preps[n] for n in names]).judged)
    antenna_m = antenna_body_m(compile_vessel(calibrated).geometry.gnss_pos_m, calibrated.sensors)
    rows = _readings(names, preps, antenna_m)
    rows += [_pooled("five most active", active, preps, antenna_m), _pooled("all", names, preps, antenna_m)]
    s = calibrated.sensors
    moved = replace(calibrated, sensors=replace(s, antenna_offset_m=(s.antenna_offset_m[0] - MOVED_M,
                                                                     s.antenna_offset_m[1] - MOVED_M)))
    moved_preps = dict(zip(active, prepared([r for r, n in zip(recs, names) if n in active], moved)))
    moved_antenna = antenna_body_m(compile_vessel(moved).geometry.gnss_pos_m, moved.sensors)
    rows.append(_pooled(f"five most active, the data's antenna {MOVED_M:g} m forward and {MOVED_M:g} m to starboard "
                        "of the twin's", active, moved_preps, moved_antenna))
    return {"rows": rows, "twin_antenna_m": [float(a) for a in antenna_m], "active": active}


def _spreads(values: list[float]) -> tuple[float, float]:
    """(standard deviation, MAD × 1.4826) of run readings, m: the second is not led by one run."""
    v = np.asarray(values, float)
    if len(v) < 2:
        return float("nan"), float("nan")
    return float(np.std(v, ddof=1)), float(MAD_TO_SIGMA * np.median(np.abs(v - np.median(v))))


def page(raw: dict) -> ResultPage:
    """The study's page from its raw figures."""
    single = [r for r in raw["rows"] if r["runs"].endswith(".csv")]
    xs = {r["runs"]: r["x_m"] for r in single if r["x_m"] is not None}
    ys = {r["runs"]: r["y_m"] for r in single if r["y_m"] is not None}
    pooled = next(r for r in raw["rows"] if r["runs"] == "five most active")
    moved = raw["rows"][-1]

    def told(readings: dict[str, float], axis: str) -> str:
        if len(readings) < 2:
            return f"the {axis} reading comes from {len(readings)} of the {len(single)} runs only"
        sd, mad = _spreads(list(readings.values()))
        return (f"the {axis} reading spreads over {min(readings.values()):+.2f} to {max(readings.values()):+.2f} m in "
                f"{len(readings)} of the {len(single)} runs (standard deviation {sd:.2f} m, {mad:.2f} m from the median absolute deviation)")
    summary = (f"Run by run, {told(xs, 'x')}; {told(ys, 'y')}. Pooled over the five most active runs the readings "
               f"are x {pooled['x_m']:+.2f} m and y {pooled['y_m']:+.2f} m against the twin's antenna; with the data's "
               f"antenna {MOVED_M:g} m forward and to starboard of the twin's they are x {moved['x_m']:+.2f} m and y "
               f"{moved['y_m']:+.2f} m (moved by {moved['x_m'] - pooled['x_m']:+.2f} and "
               f"{moved['y_m'] - pooled['y_m']:+.2f} m). A reading holds the hull's own sway per unit rate (x) or "
               "the surge's odd answer to the thrust (y) beside the antenna, and nothing in the kinematics tells "
               "that part from the antenna: a change of antenna shows only as a reading that moves against "
               "the runs' spread, which runs turning both ways under way this seldom cannot measure. The diagnosis reads the antenna from turns on the spot only "
               "(twin.fit.kinematic.lever_arm).")
    fmt = (lambda v: "-" if v is None else round(v, 3))  # noqa: E731
    return ResultPage(
        name="antenna_under_way", title="The GNSS antenna read from turns under way (BlueBoat)",
        ran="python scripts/antenna_under_way.py",
        data="the ten shared BlueBoat runs [BlueBoat-SI], read and prepared as `twin identify` does (each log's "
             "compass calibration, the shipped BlueBoat's sensors); the five most active as "
             "twin.fit.extrapolation.by_activity ranks them",
        summary=summary,
        tables=[ResultTable(f"Readings per run and pooled (m, against the twin's antenna): x from the sideways "
                            f"velocity in turns (|r| ≥ {TURNING_RAD_S:g} rad/s, at least {MIN_EACH_HAND_S:g} s each "
                            f"way), y from the surge in end-to-end windows of {WINDOW_S:g} s whose r moves by "
                            f"{MIN_SWING_RAD_S:g} rad/s or more (at least {MIN_WINDOWS}); \"-\": too few",
                            ["runs", "x m", "turning s", "y m", "windows"],
                            [[r["runs"], fmt(r["x_m"]), r["turning_s"], fmt(r["y_m"]), r["y_windows"]]
                             for r in raw["rows"]])],
        notes=[f"The twin's antenna (MJCF site plus sensors.antenna_offset_m) sits at {raw['twin_antenna_m']} m; each "
               "reading is the data's antenna less the twin's, plus the hull's own sway per unit rate (x) or the "
               "thrust's answer odd in the turn's hand (y).",
               "Per-run x readings come from one regression over all runs turning enough, sharing the u_g·r "
               "coefficient; the pooled rows fit one x for their runs.",
               "The study chooses nothing for the diagnosis; it measures whether turns under way could."],
        raw=raw)


def main() -> int:
    return study_main(__doc__.splitlines()[0], "antenna_under_way", DATA, "BlueBoat recordings", run_study, page, ROOT / "docs" / "results")


if __name__ == "__main__":
    sys.exit(main())
