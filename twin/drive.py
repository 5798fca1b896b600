"""What drives a run: thruster input series (open loop, zero-order hold) and controllers
(closed loop: the scenarios step, turn, zig-zag, spin, random RC driving).

An input series holds PWM (µs) or thrust (N) per thruster, or a propeller-and-rudder ship's
propeller speed (rps) and rudder angle (rad) (kind "propeller_rudder"). A controller is a function
(t, η, ν) → (surge command, yaw command), both normalised to [−1, 1], evaluated at the
autopilot rate; a positive yaw command speeds the left thruster up and the right one
down, which turns the vessel to starboard (r > 0, [Yellowfish-TR eq. 26c]); on a propeller-and-rudder
ship the surge command is the propeller speed and the yaw command the rudder angle, as fractions
of their bounds (δ > 0 turns to starboard too).

A wind series (`WindSeries`) is a measured wind held like the inputs: the air's velocity over
ground, which the engine takes as two extra controls and the analytic model as a known input.
A supply series (`SupplySeries`) is a battery's voltage held like the inputs, for thrusters whose
thrust follows it; an input series may carry it (`supply_v`, on the series' own times).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import TwinError
from .files import check_unique_columns
from .physics.thrusters import SeveralInputs, ThrusterModel

PWM_COLUMNS = ("pwm_left", "pwm_right")
THRUST_COLUMNS = ("thrust_left", "thrust_right")
PROPELLER_RUDDER_COLUMNS = ("prop_rps", "rudder_deg")
KINDS = ("pwm", "thrust", "propeller_rudder")
INPUT_WORDS = {"pwm": "PWM", "thrust": "thrust", "propeller_rudder": "propeller speed and rudder angle"}


def inputs_mismatch(vessel_name: str, wanted: str, held: str | None) -> str:
    """The words for a recording whose inputs (`held`, a kind of KINDS) cannot drive a vessel that
    takes `wanted`."""
    holds = INPUT_WORDS.get(held, held) if held else "no inputs"
    return f"vessel '{vessel_name}' is driven by {INPUT_WORDS.get(wanted, wanted)}; the recording holds {holds}"


_HOLD_EPS_S = 1e-9  # a time within this of an input's stamp counts as at it (its value held from there)


def _held(t: np.ndarray, values: np.ndarray, times) -> np.ndarray:
    """Zero-order hold: values[i] from t[i] until t[i+1], the first value before t[0]."""
    idx = np.searchsorted(t, np.asarray(times, float) + _HOLD_EPS_S, side="right") - 1
    return values[np.clip(idx, 0, len(t) - 1)]


@dataclass(frozen=True)
class InputSeries:
    """values[i] holds from t[i] until t[i+1] (zero-order hold); kind 'pwm' (µs, left, right),
    'thrust' (N, left, right) or 'propeller_rudder' (n rps, δ rad)."""

    t: np.ndarray
    values: np.ndarray  # (n, 2): left, right
    kind: str
    supply_v: np.ndarray | None = None  # (n,) battery voltage V held like the values (None: not logged)

    def at(self, times: np.ndarray) -> np.ndarray:
        return _held(self.t, self.values, times)

    def supply_at(self, times: np.ndarray) -> np.ndarray | None:
        """The battery voltage (V) held at `times` (no delay: the ESC sees the pack as it is), None
        without one."""
        return None if self.supply_v is None else _held(self.t, np.asarray(self.supply_v, float), times)

    def commanded_thrust(self, thrusters: ThrusterModel, times: np.ndarray, start_s: float = 0.0) -> np.ndarray:
        """Thrust command (N) per thruster at `times` (s, this series' clock), before gains, lag and
        advance loss: the input held at t − delay_s, decayed by the recording time start_s + t and
        scaled by the supply voltage held at t (thrusters that follow it, a series that logs it).
        For a propeller and rudder: the engine's two controls (n rps, δ rad) held at t − delay_s."""
        times = np.asarray(times, float)
        return thrusters.command(self.kind, self.driven(thrusters).at(times - thrusters.delay_s), times + start_s,
                                 self.supply_at(times) if thrusters.follows_supply else None)

    def thrust_on_steps(self, thrusters: ThrusterModel, n_steps: int, step_s: float, start_s: float = 0.0) -> np.ndarray:
        """(n_steps, 2) thrust command (N) held over engine step k (k·step_s to (k+1)·step_s): the step's
        mean of `commanded_thrust` (`StepPieces`); with a thrust ramp, the step's mean of the ramp
        heading for the input held over each part of the step (`StepPieces.through_ramp`). A ramp is
        not fed the step's mean: an input that reverses within a step would turn the ramp a whole
        step's slew the wrong way."""
        pieces = StepPieces.of(self, thrusters, n_steps, step_s, start_s)
        if thrusters.ramping:
            pieces = pieces.through_ramp(thrusters, step_s)
        return pieces.mean()

    def driven(self, thrusters: ThrusterModel) -> "InputSeries":
        """The series as the motors answer it: a PWM series through `ThrusterModel.as_driven` (a stopped
        motor's pulse is neutral until it passes its start edge); the series itself otherwise."""
        if self.kind != "pwm" or not thrusters.hysteretic:
            return self
        return InputSeries(self.t, thrusters.as_driven(self.values), self.kind, self.supply_v)

    def pwm_at(self, times: np.ndarray) -> np.ndarray:
        if self.kind == "pwm":
            return self.at(times).astype(float)
        return np.full((len(np.atleast_1d(times)), 2), np.nan)


def checked_series(series: InputSeries) -> InputSeries:
    """A series a user built (Python API), its arrays as float arrays, else TwinError in one sentence:
    a kind of KINDS, times finite and increasing, one row of two finite values per time (and one
    finite voltage per time, where given); the reader of an inputs CSV checks the same of a file."""
    if series.kind not in KINDS:
        raise TwinError(f"InputSeries kind is one of {', '.join(KINDS)}, got {series.kind!r:.40}")
    try:
        t, values = np.asarray(series.t, float), np.asarray(series.values, float)
        supply = None if series.supply_v is None else np.asarray(series.supply_v, float)
    except (TypeError, ValueError):
        raise TwinError("InputSeries t, values and supply_v are arrays of numbers") from None
    if t.ndim != 1 or len(t) == 0:
        raise TwinError(f"InputSeries t is a 1-D array of at least one time (s), got shape {t.shape}")
    if values.shape != (len(t), 2):
        raise TwinError(f"InputSeries values are one row of two per time, shape ({len(t)}, 2), got {values.shape}")
    if supply is not None and supply.shape != t.shape:
        raise TwinError(f"InputSeries supply_v is one voltage per time, shape ({len(t)},), got {supply.shape}")
    for name, a in (("t", t), ("values", values), ("supply_v", supply)):
        if a is not None and not np.all(np.isfinite(a)):
            raise TwinError(f"InputSeries {name}: NaN or infinite values")
    if np.any(np.diff(t) <= 0):
        raise TwinError(f"InputSeries t goes backwards or repeats at index {int(np.argmax(np.diff(t) <= 0)) + 1}")
    return InputSeries(t, values, series.kind, supply)


@dataclass(frozen=True)
class StepPieces:
    """An input series over the engine's steps: on step k the command `first[k]` (N, or a propeller
    and rudder's controls) for the share `share[k]` of the step, then `rest[k]`, the mean of what
    is held for the rest of it (`first` throughout where share is 1).

    The inputs reach the thrusters delay_s after their stamps, and neither a stamp nor a delay need
    fall on a step's start: an input that changes within a step acts for the share of the step it
    is held, as in the continuous-time model (analytic.simulate) and in the fit's free runs
    (fit/windows), not a whole step late. The decay and the supply factor are those at the step's
    start."""

    first: np.ndarray  # (n, 2)
    share: np.ndarray  # (n,) in (0, 1]
    rest: np.ndarray  # (n, 2)
    several: SeveralInputs | None = None  # the steps whose rest holds two inputs or more, each in turn

    @classmethod
    def of(cls, series: InputSeries, thrusters: ThrusterModel, n_steps: int, step_s: float,
           start_s: float = 0.0) -> "StepPieces":
        """The pieces of steps 0 … n_steps − 1 of step_s; start_s: the recording time of t = 0 (the
        thrust decay's clock). A stamp that repeats the input held before it changes nothing."""
        driven = series.driven(thrusters)
        changed = np.r_[True, np.any(np.diff(driven.values, axis=0) != 0, axis=1)]
        t, values = np.asarray(driven.t, float)[changed], driven.values[changed]
        times = np.arange(n_steps) * step_s
        supply = series.supply_at(times) if thrusters.follows_supply else None
        start = times - thrusters.delay_s
        end = start + step_s
        first_i = np.clip(np.searchsorted(t, start + _HOLD_EPS_S, side="right") - 1, 0, len(t) - 1)
        last_i = np.maximum(np.clip(np.searchsorted(t, end - _HOLD_EPS_S, side="right") - 1, 0, len(t) - 1),
                            first_i)
        first = thrusters.command(series.kind, values[first_i], times + start_s, supply)
        several = np.flatnonzero(last_i > first_i)
        share = np.ones(n_steps)
        rest = first.copy()
        several_inputs = None
        if len(several):
            lo, hi = first_i[several], last_i[several]
            change = t[lo + 1]
            share[several] = (change - start[several]) / step_s
            total = np.zeros((len(several), first.shape[1]))
            depth = int(np.max(hi - lo))
            held, commands = np.zeros((len(several), depth)), np.zeros((len(several), depth, first.shape[1]))
            for d in range(1, depth + 1):
                m = np.minimum(lo + d, hi)
                until = np.where(lo + d < hi, t[np.minimum(lo + d + 1, len(t) - 1)], end[several])
                held_s = np.where(lo + d <= hi, until - t[m], 0.0)
                command = thrusters.command(series.kind, values[m], times[several] + start_s,
                                            None if supply is None else supply[several])
                total += held_s[:, None] * command
                held[:, d - 1], commands[:, d - 1] = held_s / step_s, command
            many = hi - lo > 1
            # one input over the rest: its command itself (a mean of one rounds, and would split a step
            # whose command does not change)
            rest[several] = np.where(many[:, None], total / (end[several] - change)[:, None], commands[:, 0])
            alike = np.all((commands == first[several][:, None, :]) | (held[:, :, None] == 0.0), axis=(1, 2))
            share[several[alike]] = 1.0  # inputs that differ but command the same thrust (both at a bound)
            rest[several[alike]] = first[several[alike]]
            many &= ~alike
            if np.any(many):
                several_inputs = SeveralInputs(several[many], held[many], commands[many])
        return cls(first, share, rest, several_inputs)

    @property
    def split(self) -> np.ndarray:
        """The steps whose command changes within them."""
        return np.flatnonzero((self.share < 1.0) & np.any(self.first != self.rest, axis=1))

    def through_ramp(self, thrusters: ThrusterModel, step_s: float) -> "StepPieces":
        """The pieces as the thrusters' slew limit gives them (settled at the first command): on a
        step within which the command changes (`split`), the ramp's mean over its share under the
        first command, then over the rest heading for each input held there in turn; elsewhere the
        step's mean of the ramp (ThrusterModel.slewed_parts). Within the bounds; unchanged but bounded
        without a ramp."""
        share = np.ones(len(self.share))
        k = self.split
        share[k] = self.share[k]
        first, rest = thrusters.slewed_parts(self.first, share, self.rest, step_s, self.several)
        return StepPieces(first, share, rest)

    def mean(self) -> np.ndarray:
        """(n, 2) each step's mean command."""
        k = self.split
        out = self.first.copy()
        w = self.share[k, None]
        out[k] = w * self.first[k] + (1.0 - w) * self.rest[k]
        return out


@dataclass(frozen=True)
class SupplySeries:
    """A battery's terminal voltage held from t[i] until t[i+1] (s, the run's clock; zero-order hold,
    the first value before the first time): what thrusters that follow the supply answer
    (physics/thrusters.py)."""

    t: np.ndarray
    volt_v: np.ndarray  # (n,) V

    def at(self, times) -> np.ndarray:
        return _held(self.t, np.asarray(self.volt_v, float), times)


@dataclass(frozen=True)
class WindSeries:
    """A wind over ground held from t[i] until t[i+1] (s, the run's clock, zero-order hold):
    air_ned[i] is the air's velocity (north, east m/s: where it goes)."""

    t: np.ndarray
    air_ned: np.ndarray  # (n, 2)

    @classmethod
    def from_speed_direction(cls, t, speed_m_s, from_deg) -> "WindSeries":
        """From speeds (m/s) and the directions the wind blows FROM (deg clockwise from north)."""
        a = np.radians(np.asarray(from_deg, float))
        speed = np.asarray(speed_m_s, float)
        t = np.asarray(t, float)
        if t.ndim != 1 or len(t) < 1 or speed.shape != t.shape or a.shape != t.shape:
            raise TwinError("a wind series needs one speed and one direction per time")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(speed)) and np.all(np.isfinite(a))):
            raise TwinError("a wind series holds NaN or infinite values")
        if np.any(np.diff(t) <= 0):
            raise TwinError("a wind series' times must increase")
        return cls(t, -speed[:, None] * np.column_stack([np.cos(a), np.sin(a)]))

    def at(self, times) -> np.ndarray:
        """(n, 2) air velocity NED (m/s) held at `times`; the first value before the first time."""
        return _held(self.t, self.air_ned, times)

    def shifted(self, dt_s: float) -> "WindSeries":
        """The same wind on a clock started dt_s later (t − dt_s)."""
        return WindSeries(self.t - dt_s, self.air_ned)


def read_inputs_csv(path: str | Path) -> InputSeries:
    """CSV with a `t` column (s) and pwm_left,pwm_right (µs), thrust_left,thrust_right (N) or, for a
    propeller-and-rudder ship, prop_rps,rudder_deg (rps; degrees, > 0 turns to starboard).

    The first row must be at t ≤ 0: the run starts at t = 0 and nothing says what the
    thrusters did before a later first row. An empty input cell holds that input's last value, and
    a row with no inputs at all (a recording's row of another stream, as in the generic log layout)
    is passed over. Spreadsheets may prefix a UTF-8 byte-order mark."""
    path = Path(path)
    if path.is_dir():
        raise TwinError(f"inputs file '{path}' is a folder: give the CSV file")
    if not path.is_file():
        raise TwinError(f"inputs file '{path}' not found")
    try:
        # line by line: a stray quote must not join the lines after it into one cell
        lines = path.read_text(encoding="utf-8-sig").splitlines()
        rows = [next(csv.reader([text]), []) for text in lines]
    except UnicodeDecodeError:
        raise TwinError(f"{path.name}: not a text CSV file") from None
    except csv.Error as exc:  # a cell past the csv module's 128 kB
        raise TwinError(f"inputs file '{path}': not readable as CSV ({exc})") from None
    if len(rows) < 2:
        raise TwinError(f"{path.name}: needs a header and at least one row")
    header = [h.strip() for h in rows[0]]
    check_unique_columns(header, path.name)
    if "t" not in header:
        looks = (" (it looks like a vessel file: give that with --model)" if path.suffix.lower() == ".json"
                 or header[:1] == ["{"] else "")
        raise TwinError(f"{path.name}: missing column 't': an inputs file is a CSV of t and the inputs{looks}")
    kind, cols = _input_columns(header, path)
    idx = [header.index(c) for c in ("t", *cols)]
    data = []
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(header) and '"' in lines[line - 1]:
            raise TwinError(f"{path.name}: line {line} holds a quote character, which leaves {len(row)} cells under a "
                            f"header of {len(header)} columns: an inputs file holds numbers only")
        if len(row) > len(header) and any(c.strip() for c in row[len(header):]):
            raise TwinError(f"{path.name}: line {line} has {len(row)} cells under a header of {len(header)} columns")
        if len(row) < len(header):  # a row cut short (a file cut off mid-line): its last number is partial
            raise TwinError(f"{path.name}: line {line} has {len(row)} cells under a header of {len(header)} columns "
                            "(cut short?)")
        cells = [row[i].strip() if i < len(row) else "" for i in idx]
        if cells[0] and not any(cells[1:]):
            continue  # a recording's row without inputs (another stream's sample): the last ones hold
        held = data[-1][1:] if data else None
        try:
            values = [float(cells[0])] + [float(c) if c else (held[k] if held else float("nan"))
                                           for k, c in enumerate(cells[1:])]
        except ValueError:
            raise TwinError(f"{path.name}: line {line}: not a number in t/{cols[0]}/{cols[1]}") from None
        if any(c and not np.isfinite(v) for c, v in zip(cells, values)):
            raise TwinError(f"{path.name}: line {line}: NaN or infinite value in t/{cols[0]}/{cols[1]}")
        if not np.all(np.isfinite(values[1:])) and not data:
            raise TwinError(f"{path.name}: line {line}: the first inputs row has an empty {cols[0]} or {cols[1]}")
        data.append(values)
    if not data:
        raise TwinError(f"{path.name}: needs a header and at least one row")
    a = np.array(data)
    if not np.all(np.isfinite(a)):
        raise TwinError(f"{path.name}: NaN or infinite values")
    if np.any(np.diff(a[:, 0]) <= 0):
        line = int(np.argmax(np.diff(a[:, 0]) <= 0)) + 3
        raise TwinError(f"{path.name}: time goes backwards or repeats at line {line}")
    if a[0, 0] > 0:
        raise TwinError(f"{path.name}: the first row is at t = {a[0, 0]:g} s; the run starts at t = 0, so the "
                        "first row must be at t ≤ 0 (add a row at t = 0 with the inputs to hold until then)")
    values = a[:, 1:]
    if kind == "propeller_rudder":
        values = np.column_stack([values[:, 0], np.radians(values[:, 1])])
    return InputSeries(a[:, 0], values, kind)


def _input_columns(header: list[str], path: Path) -> tuple[str, tuple[str, str]]:
    """'pwm', 'thrust' or 'propeller_rudder' and its two columns; two kinds at once would leave one
    silently unused."""
    kinds = {"pwm": PWM_COLUMNS, "thrust": THRUST_COLUMNS, "propeller_rudder": PROPELLER_RUDDER_COLUMNS}
    present = [k for k, cols in kinds.items() if any(c in header for c in cols)]
    if present == ["pwm", "thrust"]:
        raise TwinError(f"{path.name}: both PWM and thrust columns (a twin run's CSV has both): give "
                        "pwm_left,pwm_right (µs) or thrust_left,thrust_right (N), not both (keep t and one pair, "
                        "e.g. with cut -d, -f1,8,9 for a run's PWM)")
    if len(present) > 1:
        raise TwinError(f"{path.name}: columns of two kinds of inputs: give pwm_left,pwm_right (µs), "
                        "thrust_left,thrust_right (N) or prop_rps,rudder_deg, not more than one")
    for kind, cols in kinds.items():
        if set(cols) <= set(header):
            return kind, cols
    if present:  # one of a pair: name the other
        cols = kinds[present[0]]
        has, lacks = (cols[0], cols[1]) if cols[0] in header else (cols[1], cols[0])
        raise TwinError(f"{path.name}: has {has} but no {lacks} column (both of {','.join(cols)} are needed)")
    raise TwinError(f"{path.name}: missing columns: need pwm_left,pwm_right, thrust_left,thrust_right or "
                    "prop_rps,rudder_deg")


# ---------------------------------------------------------------- closed loop

Controller = Callable[[float, np.ndarray, np.ndarray], tuple[float, float]]


def step(surge: float = 0.6, at_s: float = 1.0) -> Controller:
    return lambda t, eta, nu: (surge if t >= at_s else 0.0, 0.0)


def turn(surge: float = 0.6, yaw: float = 0.3, at_s: float = 10.0) -> Controller:
    return lambda t, eta, nu: (surge, yaw if t >= at_s else 0.0)


def spin(yaw: float = 0.5, at_s: float = 1.0) -> Controller:
    return lambda t, eta, nu: (0.0, yaw if t >= at_s else 0.0)


@dataclass
class ZigZag:
    """The classic zig-zag: rudder-equivalent yaw command ±yaw, switched each
    time the heading passes ±switch_deg from the initial heading."""

    surge: float = 0.3
    yaw: float = 0.6
    switch_deg: float = 20.0
    at_s: float = 5.0
    _sign: float = 1.0
    _psi0: float | None = None

    def __call__(self, t: float, eta: np.ndarray, nu: np.ndarray) -> tuple[float, float]:
        if self._psi0 is None:
            self._psi0 = float(eta[2])
        if t < self.at_s:
            return self.surge, 0.0
        heading_deg = np.rad2deg(eta[2] - self._psi0)
        if self._sign > 0 and heading_deg >= self.switch_deg:
            self._sign = -1.0
        elif self._sign < 0 and heading_deg <= -self.switch_deg:
            self._sign = 1.0
        return self.surge, self._sign * self.yaw


def random_rc(seed: int = 0, hold_s: tuple[float, float] = (2.0, 6.0)) -> Controller:
    """RC-like driving: two joysticks (surge, yaw) held at random levels for
    random intervals, as a pilot drives for identification [Morel-2024 §6.1]."""
    rng = np.random.default_rng(seed)
    state = {"until": -1.0, "cmd": (0.0, 0.0)}

    def controller(t: float, eta: np.ndarray, nu: np.ndarray) -> tuple[float, float]:
        if t >= state["until"]:
            state["until"] = t + rng.uniform(*hold_s)
            state["cmd"] = (float(rng.uniform(0.0, 0.8)), float(rng.uniform(-0.5, 0.5)))
        return state["cmd"]

    return controller


SCENARIOS: dict[str, Callable[..., Controller]] = {
    "step": step, "turn": turn, "zigzag": ZigZag, "spin": spin, "random": random_rc,
}


# a spin turns on the spot by differential thrust, which a single screw and rudder cannot give: driven
# by one, it asks for rudder with the propeller stopped and the ship lies still
NEEDS_TWO_THRUSTERS = ("spin",)


def applicable(kind: str) -> tuple[str, ...]:
    """The scenarios that can drive thrusters of this kind (vessel.thrusters.kind)."""
    if kind == "propeller_rudder":
        return tuple(name for name in SCENARIOS if name not in NEEDS_TWO_THRUSTERS)
    return tuple(SCENARIOS)


def get(name: str, seed: int = 0, kind: str | None = None, vessel_name: str = "") -> Controller:
    """The scenario `name`'s controller; with `kind` (the thrusters' kind of the vessel it will
    drive), refused when it cannot drive them."""
    if name not in SCENARIOS:
        raise TwinError(f"unknown scenario '{name}' (known: {', '.join(SCENARIOS)})")
    if kind is not None and name not in applicable(kind):
        who = f"vessel '{vessel_name}' " if vessel_name else "a vessel "
        raise TwinError(f"scenario '{name}' needs two thrusters to turn on the spot; {who}has one propeller and "
                        f"a rudder (thrusters.kind '{kind}'): use {', '.join(applicable(kind))}")
    return SCENARIOS[name](seed=seed) if name == "random" else SCENARIOS[name]()


def to_thruster_inputs(thrusters: ThrusterModel, surge: float, yaw: float) -> tuple[str, np.ndarray]:
    """Normalised (surge, yaw) → per-thruster PWM (µs) or thrust (N) command, or a propeller and
    rudder's (n rps, δ rad) as the fractions surge and yaw of their bounds."""
    if thrusters.kind == "propeller_rudder":
        (_, n_max), (_, d_max) = thrusters.channel_bounds()
        if not (np.isfinite(n_max) and np.isfinite(d_max)):
            raise TwinError("a scenario needs the propeller and rudder's bounds (thrusters.rps_max, rudder_max_deg)")
        return "propeller_rudder", np.array([np.clip(surge, -1.0, 1.0) * n_max, np.clip(yaw, -1.0, 1.0) * d_max])
    cmd = np.clip(np.array([surge + yaw, surge - yaw]), -1.0, 1.0)
    if thrusters.kind == "t200":
        mid = 0.5 * (thrusters.pwm_min_us + thrusters.pwm_max_us)
        half = 0.5 * (thrusters.pwm_max_us - thrusters.pwm_min_us)
        return "pwm", mid + half * cmd
    t_min, t_max = thrusters.command_range()
    return "thrust", np.where(cmd >= 0, cmd * t_max, -cmd * t_min)
