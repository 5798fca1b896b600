"""Synthetic identification datasets from the twin ([Morel-2024 §6.1] in shape): a truth
vessel (the vessel description with effects injected by name), trajectory segments
of identification manoeuvres separated by gaps, and the sensors an ArduPilot boat
logs at their real rates and noise [Morel-2024 §3, Table 1]:

  GNSS     lat/lon of the antenna (MJCF gnss site + the sensors' offset, [Yellowfish-TR]
           appendix), every 200 ms, a small white jitter plus a smooth slow wander
  heading  AHRS ψ with the sensors' bias/deviation, every 20 ms, white noise
  PWM      the autopilot's output, every 100 ms, integer µs, stamped with the
           sensors' PWM clock offset
  battery  the pack's voltage every 500 ms (10 mV), only where the truth's thrust follows it
           (supply_voltage): each segment on a pack of its own charge, starting at 0.88-1 of
           V_ref (one of them full), sagging 1 % of V_ref a minute once logged

The result is a `Recording` (written by `twin.formats.write_recording` as .tlog,
.mcap or .csv) and, separately, the truth: the truth vessel, the effects, the noise,
the seed and the noise-free states. Identification never reads the truth.
Open-loop segments run in one batch (`engine.batch.simulate_many`); closed-loop
ones (zig-zag, autopilot) step the engine with their controller.
"""
from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..engine.batch import simulate_many
from ..engine.mjcf import CompiledVessel, compile_vessel
from ..engine.sim import simulate
from ..errors import TwinError
from ..geodesy import geodetic_from_ned
from ..drive import InputSeries, SupplySeries
from ..physics.kinematics import wrap_angle
from ..physics.seakeeping import site_ned
from ..physics.sensors import antenna_body_m, antenna_ned, measured_heading, motor_throttle
from ..progress import Progress, steps
from ..recording import Recording, Stream
from ..run import Run
from ..vessel import Vessel
from . import manoeuvres as man
from ..effects import apply_effects, as_effect

ORIGIN = (37.4136, -5.9786, 0.0)  # Seville, the Yellowfish's home waters; any origin works


@dataclass(frozen=True)
class SensorNoise:
    """Noise of the logged sensors. GNSS: white jitter σ per axis plus a smooth wander (σ,
    time scale): a receiver's own filter makes epoch-to-epoch jitter small (cm) while
    the position wanders by decimetres over a minute; heading: white σ. Rates of
    [Morel-2024 Table 1]."""

    gnss_white_m: float = 0.02
    gnss_wander_m: float = 0.5
    gnss_wander_s: float = 60.0
    heading_deg: float = 0.3
    gnss_dt_s: float = 0.2
    heading_dt_s: float = 0.02
    pwm_dt_s: float = 0.1


PROFILES = {"realistic": SensorNoise(), "rtk": SensorNoise(0.01, 0.0, 60.0, 0.1),
            "noisy": SensorNoise(0.1, 1.0, 60.0, 1.0), "none": SensorNoise(0.0, 0.0, 60.0, 0.0)}


def noise_profile(text: str) -> SensorNoise:
    """A profile name (realistic, rtk, none) or 'GNSS_M,HEADING_DEG' white noise levels."""
    if text in PROFILES:
        return PROFILES[text]
    try:
        gnss, heading = (float(x) for x in text.split(","))
    except ValueError:
        raise TwinError(f"noise '{text}': use {', '.join(PROFILES)} or GNSS_M,HEADING_DEG") from None
    if gnss < 0 or heading < 0:
        raise TwinError("noise levels must be ≥ 0")
    return SensorNoise(gnss, 0.0, 60.0, heading)


@dataclass
class Dataset:
    recording: Recording
    truth_vessel: Vessel
    effects: list
    noise: SensorNoise
    seed: int
    manoeuvres: list[man.Manoeuvre]
    runs: list[Run] = field(default_factory=list)  # noise-free states of each segment

    def truth(self, written_to: Path | None = None, logs=()) -> dict:
        """Everything identification must not see, as plain data; `written_to`: the file it goes to,
        against which the truth vessel's MJCF path is written (so the truth loads as a vessel file);
        `logs`: the recordings it describes, listed first (relative to `written_to`'s folder), so that
        a command about to replace one finds its truth whatever the truth is called (files.truths_of)."""
        vessel = self.truth_vessel if written_to is None else replace(self.truth_vessel, path=Path(written_to).resolve())
        folder = Path(written_to).resolve().parent if written_to is not None else Path.cwd()
        named = {"logs": [_relative(Path(p).resolve(), folder) for p in logs]} if logs else {}
        return {
            **named,
            "vessel": vessel.to_dict(),
            "effects": [as_effect(e).to_dict() for e in self.effects],
            "noise": asdict(self.noise),
            "seed": self.seed,
            "segments": [{"manoeuvre": m.name, "t0_s": float(r.t[0]), "t1_s": float(r.t[-1])}
                         for m, r in zip(self.manoeuvres, self.runs)],
            "states": [{"t": _rounded(r.t, 3), "north": _rounded(r.eta[:, 0]), "east": _rounded(r.eta[:, 1]),
                        "psi": _rounded(r.eta[:, 2]), "u": _rounded(r.nu[:, 0]), "v": _rounded(r.nu[:, 1]),
                        "r": _rounded(r.nu[:, 2]), "thrust_left": _rounded(r.thrust_n[:, 0]),
                        "thrust_right": _rounded(r.thrust_n[:, 1])} for r in self.runs],
        }


def _relative(path: Path, folder: Path) -> str:
    """`path` from `folder` ('/'-separated), or whole where no relative path joins them (two drives)."""
    try:
        return Path(os.path.relpath(path, folder)).as_posix()
    except ValueError:
        return path.as_posix()


def _rounded(a: np.ndarray, digits: int = 6) -> list[float]:
    return [round(float(x), digits) for x in a]


def generate(vessel: Vessel, *, effects=(), n_segments: int = 8, manoeuvres: list[str] | None = None, seed: int = 0,
             noise: SensorNoise = SensorNoise(), gap_s: float = 6.0,
             segment_s: tuple[float, float] = (40.0, 90.0), progress: Progress | None = None,
             sea=None) -> Dataset:
    """A dataset of `n_segments` manoeuvres of the vessel with `effects` injected (see
    twin.effects), logged by noisy sensors; reproducible from `seed`. `progress` hears which
    segment (k of n) is simulated, then logged. `sea` (physics.waves.Sea): every segment runs the
    6-DOF hull in it (one run each), the GNSS antenna at its site on the mast follows the hull's
    roll and pitch, and the log holds the attitude (roll, pitch) and the sea in its meta."""
    names = [as_effect(e).name for e in effects]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:  # applied one after the other they would compound, which no one means by naming it twice
        raise TwinError(f"effect {twice[0]} given twice: give it once, with the value the truth should have")
    truth = apply_effects(vessel, effects)
    if truth.thrusters.kind != "t200":
        raise TwinError(f"vessel '{vessel.name}' has no PWM thruster model: a dataset logs PWM")
    rng = np.random.default_rng(seed)
    plan = man.plan(list(manoeuvres or man.ALL), n_segments, rng, segment_s)
    source = f"synthetic:{vessel.name}:seed{seed}"
    own = [name for name, _, _ in truth.environment.wind_by_log]
    if own and source not in own:  # a wind for logs this dataset is not would silently do nothing
        raise TwinError(f"wind_per_log names {', '.join(own)}, not this dataset's log '{source}' (its name in the "
                        "truth file; the seed sets it): give that name, or the wind as wind=SPEED,FROM")
    # the recording's own wind, where the truth holds one for this log (wind_per_log): what it logs
    compiled = compile_vessel(replace(truth, environment=truth.environment.for_log(source)))
    starts = np.cumsum([0.0] + [m.duration_s + gap_s for m in plan[:-1]])
    eta0 = [(float(rng.uniform(-50, 50)), float(rng.uniform(-50, 50)), float(rng.uniform(-np.pi, np.pi)))
            for _ in plan]
    supplies = _supplies(truth, plan, rng)
    runs = _simulate(compiled, plan, starts, eta0, noise.heading_dt_s, steps(progress), supplies, sea)
    recording = _log(compiled, runs, noise, rng, source, steps(progress))
    if sea is not None:
        recording.meta["sea"] = sea.to_dict()
    return Dataset(recording, truth, [as_effect(e) for e in effects], noise, seed, plan, runs)


LEAD_IN_S = 5.0  # unlogged seconds before each segment: a logged segment starts under way, as real ones do
SUPPLY_DT_S = 0.5  # the battery monitor's period


def _supplies(truth: Vessel, plan, rng: np.random.Generator) -> list[SupplySeries | None]:
    """Each segment's pack voltage on its run's clock (lead-in included) where the truth's thrust
    follows it (module docstring): packs of different charge tell the supply from a decay in time.
    Their starting voltages spread evenly over 0.88-1 of V_ref in a random order, one of them full:
    the highest logged voltage is V_ref, the reference a diagnosis takes."""
    t = truth.thrusters
    if not t.follows_supply:
        return [None] * len(plan)
    levels = t.supply_ref_v * rng.permutation(np.linspace(0.88, 1.0, len(plan)))
    out = []
    for m, v0 in zip(plan, levels):
        times = np.arange(0.0, m.duration_s + LEAD_IN_S + SUPPLY_DT_S, SUPPLY_DT_S)
        out.append(SupplySeries(times, v0 - 0.01 * t.supply_ref_v * np.maximum(times - LEAD_IN_S, 0.0) / 60.0))
    return out


def _simulate(compiled: CompiledVessel, plan, starts, eta0, sample_dt_s: float, progress: Progress,
              supplies: list[SupplySeries | None], sea=None) -> list[Run]:
    runs: list[Run | None] = [None] * len(plan)
    open_idx = [i for i, m in enumerate(plan) if isinstance(m.drive, InputSeries)] if sea is None else []
    if open_idx:
        # open-loop segments run together in one batch: one report for all of them
        progress(f"simulating {len(open_idx)} open-loop segments in one batch", 0, len(plan))
        batch = simulate_many(compiled, [_led_in(plan[i].drive, supplies[i]) for i in open_idx],
                              [plan[i].duration_s + LEAD_IN_S for i in open_idx], eta0=[eta0[i] for i in open_idx],
                              start_s=[starts[i] - LEAD_IN_S for i in open_idx], sample_dt_s=sample_dt_s)
        if batch.diverged:
            (k, t), *_ = batch.diverged
            i = open_idx[k]
            raise TwinError(f"the twin diverged in segment {i + 1} ({plan[i].name}) at {t - starts[i]:.2f} s "
                            f"after its logged start: the vessel's parameters do not give a stable twin "
                            f"({batch.describe_divergence()})")
        for i, run in zip(open_idx, batch):
            runs[i] = run
    done = len(open_idx)
    for i, m in enumerate(plan):
        if runs[i] is None:
            progress(f"simulating segment {i + 1} of {len(plan)} ({m.name}, closed loop)", done, len(plan))
            done += 1
            drive = _led_in(m.drive, supplies[i]) if isinstance(m.drive, InputSeries) else m.drive
            runs[i] = simulate(compiled, drive, m.duration_s + LEAD_IN_S, control_dt_s=man.PWM_DT_S,
                               sample_dt_s=sample_dt_s, eta0=eta0[i], start_s=float(starts[i]) - LEAD_IN_S,
                               supply=None if isinstance(m.drive, InputSeries) else supplies[i], sea=sea)
    return [_logged_part(r, float(t0)) for r, t0 in zip(runs, starts)]


def _led_in(series: InputSeries, supply: SupplySeries | None = None) -> InputSeries:
    """The series delayed by the lead-in, its first input held meanwhile; with the supply voltage (on
    the run's clock) at its times."""
    t = np.concatenate([[0.0], series.t + LEAD_IN_S])
    return InputSeries(t, np.vstack([series.values[:1], series.values]), series.kind,
                       None if supply is None else supply.at(t))


def _logged_part(run: Run, t0: float) -> Run:
    keep = run.t >= t0 - 1e-9
    inputs = run.meta["inputs"]
    shifted = InputSeries(inputs.t - LEAD_IN_S, inputs.values, inputs.kind, inputs.supply_v)  # the segment's clock
    meta = {**run.meta, "inputs": shifted, "start_s": t0}
    if "six_dof" in meta:
        meta["six_dof"] = {k: (v[keep] if isinstance(v, np.ndarray) and v.shape[:1] == keep.shape else v)
                           for k, v in meta["six_dof"].items()}
    return Run(run.t[keep], run.eta[keep], run.nu[keep], run.pwm_us[keep], run.thrust_n[keep], meta=meta)


# ---------------------------------------------------------------- sensors

def _throttle(vessel: Vessel, run: Run, times_s: np.ndarray) -> np.ndarray | float:
    """The motors' throttle τ at `times_s` (the segment's clock) for a compass that follows it
    (physics.sensors.motor_throttle), 0 for one that does not."""
    if not vessel.sensors.follows_throttle:
        return 0.0
    inputs = run.meta["inputs"]
    if inputs.kind != "pwm":
        raise TwinError("a compass error that follows the throttle (sensors.compass_motor_deg) needs PWM inputs; "
                        f"these runs are driven by {inputs.kind}")
    th = vessel.thrusters
    pwm = inputs.at(times_s)
    if th.spanned:  # the pulses each ESC drives its motor with, within its range
        pwm = th.at_escs(th.received(pwm))
    return motor_throttle(pwm, (man.NEUTRAL_US, man.NEUTRAL_US), th.pwm_min_us, th.pwm_max_us)


def _wander(rng: np.random.Generator, n: int, dt: float, sigma: float, scale_s: float) -> np.ndarray:
    """Smooth random wander of standard deviation σ over time scale scale_s: white noise
    through a Gaussian filter (a first-order Markov process would be rough, and its
    derivative would swamp the velocities, which a real receiver's does not)."""
    if sigma <= 0 or n == 0:
        return np.zeros(n)
    width = scale_s / dt / 2.0
    pad = int(4 * width)
    smooth = gaussian_filter1d(rng.normal(0.0, 1.0, n + 2 * pad), width)[pad: pad + n]
    return sigma * smooth / np.sqrt(1.0 / (2.0 * np.sqrt(np.pi) * width))


def _log(compiled: CompiledVessel, runs: list[Run], noise: SensorNoise, rng: np.random.Generator,
         source: str, progress: Progress) -> Recording:
    vessel = compiled.vessel
    antenna = antenna_body_m(compiled.geometry.gnss_pos_m, vessel.sensors)
    g_t, g_n, g_e, h_t, h_psi, p_t, p_v, b_t, b_v = [], [], [], [], [], [], [], [], []
    a_t, a_roll, a_pitch = [], [], []
    for k, run in enumerate(runs):
        progress(f"logging segment {k + 1} of {len(runs)} (sensors and noise)", k, len(runs))
        t0, t1 = float(run.t[0]), float(run.t[-1])
        tg = t0 + np.arange(0.0, t1 - t0 + 1e-9, noise.gnss_dt_s)
        n_a, e_a = antenna_ned(run.eta[:, 0], run.eta[:, 1], run.eta[:, 2], antenna)
        six = run.meta.get("six_dof")
        if six is not None:  # the antenna on its mast swings with the hull's roll and pitch
            n_a, e_a, _ = site_ned(run.eta, six["down_m"], six["pitch_rad"], six["roll_rad"],
                                   np.array([antenna[0], antenna[1], compiled.geometry.gnss_pos_m[2]]))
            th_a = t0 + np.arange(0.0, t1 - t0 + 1e-9, noise.heading_dt_s)
            a_t.append(th_a)
            a_roll.append(np.interp(th_a, run.t, six["roll_rad"]) + np.radians(rng.normal(0.0, noise.heading_deg,
                                                                                        len(th_a))))
            a_pitch.append(np.interp(th_a, run.t, six["pitch_rad"]) + np.radians(rng.normal(0.0, noise.heading_deg,
                                                                                          len(th_a))))
        wander = [_wander(rng, len(tg), noise.gnss_dt_s, noise.gnss_wander_m, noise.gnss_wander_s)
                  for _ in range(2)]
        g_t.append(tg)
        taken = tg - vessel.sensors.gnss_latency_s  # a late receiver stamps an older position
        g_n.append(np.interp(taken, run.t, n_a) + wander[0] + rng.normal(0.0, noise.gnss_white_m, len(tg)))
        g_e.append(np.interp(taken, run.t, e_a) + wander[1] + rng.normal(0.0, noise.gnss_white_m, len(tg)))
        th = t0 + np.arange(0.0, t1 - t0 + 1e-9, noise.heading_dt_s)
        psi = np.interp(th - vessel.sensors.heading_latency_s, run.t, run.eta[:, 2])  # a late AHRS: older
        h_t.append(th)
        h_psi.append(wrap_angle(measured_heading(vessel.sensors.for_log(source), psi,
                                                 _throttle(vessel, run, th - vessel.sensors.heading_latency_s - t0))
                                + np.radians(rng.normal(0.0, noise.heading_deg, len(th)))))
        tp = t0 + np.arange(0.0, t1 - t0 + 1e-9, noise.pwm_dt_s)
        p_t.append(tp + vessel.sensors.pwm_clock_offset_s)
        p_v.append(np.round(run.meta["inputs"].at(tp - t0)))
        if run.meta["inputs"].supply_v is not None:
            tb = t0 + np.arange(0.0, t1 - t0 + 1e-9, SUPPLY_DT_S)
            b_t.append(tb)
            b_v.append(np.round(run.meta["inputs"].supply_at(tb - t0), 2))
    lat, lon = geodetic_from_ned(np.concatenate(g_n), np.concatenate(g_e), ORIGIN[0], ORIGIN[1], ORIGIN[2])
    pwm = np.concatenate(p_v)
    rec = Recording(source=source, kind="synthetic")
    rec.gnss = Stream(np.concatenate(g_t), {"lat_deg": lat, "lon_deg": lon, "alt_m": np.full(len(lat), ORIGIN[2])})
    rec.heading = Stream(np.concatenate(h_t), {"psi_rad": np.concatenate(h_psi)})
    rec.pwm = Stream(np.concatenate(p_t), {"left_us": pwm[:, 0], "right_us": pwm[:, 1]})
    rec.pwm_neutral_us = (man.NEUTRAL_US, man.NEUTRAL_US)
    if b_t:
        rec.battery = Stream(np.concatenate(b_t), {"voltage_v": np.concatenate(b_v)})
    if a_t:
        rec.attitude = Stream(np.concatenate(a_t), {"roll_rad": np.concatenate(a_roll),
                                                    "pitch_rad": np.concatenate(a_pitch)})
    rec.notes.append(f"synthetic dataset: {len(runs)} segments, seed and truth in the separate truth file")
    return rec
