"""Twin-thruster actuation: the T200 PWM→thrust map with its dead zone
[Yellowfish-TR eq. 27, Table VII], the allocation [Yellowfish-TR eq. 26], the force and
torque bounds (Table VIII), the first-order thrust lag [Morel-2024 eq. 15], and
what real thrusters add to a datasheet curve:

- a transport delay between the logged PWM and the thrust (ESC and autopilot
  latency): the thrusters act on the PWM of `delay_s` earlier;
- thrust decay over a run (battery sag): the command is scaled by
  1 − decay_per_min·t/60 s, t from the start of the recording;
- thrust that follows the supply voltage: an ESC drives its motor with a duty cycle of the pack's
  terminal voltage V, so one PWM gives less thrust as the pack sags and under the load's own
  IR drop. Where the recording logs V (ArduPilot's BAT.Volt, the CSV `voltage`) the command is
  scaled by (V/V_ref)^k (`supply_exponent` k, `supply_ref_v` V_ref: the voltage the map holds
  at): a known input, like a measured wind, not a fitted trend in time. k is fitted, not
  assumed (a propeller's thrust goes as n², n roughly as V at a given duty, so k ≈ 2 is the
  ideal; an ESC's losses and current limit lower it). Without a logged voltage (a closed-loop
  scenario, SITL, a log with no battery monitor) the map acts as at V_ref. The thrust bounds
  stay the map's at full PWM: V_ref is meant as the fullest pack (a diagnosis takes the logs'
  highest voltage), so the factor stays at or below 1 and a command is never held at them by it;
- a slew limit (an ESC's or autopilot's ramp, ArduPilot's MOT_SLEWRATE in kind): the thrust
  command, within the bounds, changes no faster than the full forward thrust in `ramp_s`
  seconds, whatever the PWM asks. Its state is the command the ramp has reached, so like the
  hysteresis it acts on a series (`slewed`), from the thrust it starts at. On a step grid the
  engine is given each step's mean of the continuous ramp (`slew_step`), so the impulse a
  thruster delivers does not depend on the step size; a step within which the input changes (a
  delay or stamps off the step grid) is taken in two parts, the ramp heading for the input held
  over each (`slewed_parts`);
- a motor that starts late (start/stop hysteresis of a sensorless ESC): a stopped motor starts
  only when the PWM passes a start edge beyond the dead-zone edge (`start_fwd`, `start_rev`),
  and a running one keeps its branch of the map until the PWM comes back inside the dead zone.
  Which branch drives a sample depends on the PWM before it, so the map acts on a series
  (`as_driven`, `motor_states`), not on one pulse: a stopped motor's pulse counts as neutral;
- a forward curve that saturates (`full_share` s): a propeller near the surface draws air under
  heavy load (ventilation), a worn propeller or an ESC's current limit gives less at the top of the
  datasheet's curve while the thrust near the dead zone is the map's. The forward branch T of the
  map becomes T/√(1 + k·(T/T_full)²), k = 1/s² − 1, with T_full the map's thrust at full PWM: s·T_full
  at full, rising with the PWM for any s > 0 (its slope (1 + k·(T/T_full)²)^(−3/2) > 0), bending
  over smoothly instead of at a knee; s > 1 steepens the top. Astern has its own scale (`reverse`);
- one thruster's ESC answering another PWM range than the autopilot's output (`pwm_span_left`,
  `pwm_span_right` s): that ESC takes neutral + s·(δ − neutral) for the logged pulse δ, clipped to the
  PWM range, as an ESC calibrated to a narrower or wider throttle range than the one the autopilot
  sends. Through the map's curve, its dead zone and its end at full PWM this is not a thrust scale:
  a pulse scale of 1/0.75 is a thrust ratio of about 1.3-1.8 at part throttle and 1 at full;
- thrust loss with advance speed: with K_T linear in the advance ratio J = u_a/(nD),
  K_T = K_T0(1 − J/J_0), a propeller turning at n gives T = ρD⁴K_T0·n|n| − ρD³(K_T0/J_0)·|n|·u_a.
  Its static thrust T0 = ρD⁴K_T0·n|n| fixes |n| = √(|T0|/(ρD⁴K_T0)), so

      T = T0 − c·√|T0|·u_a,    c = √(ρK_T0)·D/J_0   (√N·s/m, `advance_loss`)

  with u_a the thruster's own speed through the water along body x, u_r − r·y_i. The loss
  acts against the advance whichever way the propeller turns: a propeller is a damper whose
  strength grows with its speed. Going ahead it lowers a forward thrust and strengthens a
  reversed one (crash stop); in a spin it weakens the reversed thruster, which backs into its
  own jet, and strengthens the forward one. (T0·(1 − k·u_a), the simpler form, gets
  every reversed thruster's case the wrong way round.) The engine applies it in the
  hydrodynamic callback from each actuator's force (physics.hydrodynamics).

A single propeller and rudder (kind "propeller_rudder", the Esso Osaka model): the inputs are the
propeller speed n (rps, signed) and the rudder angle δ (rad, > 0 turns to starboard), carried to
the engine unchanged as its two controls; the forces they make (MMG standard method) are the
hydrodynamic callback's (physics/mmg.py), not the actuators'.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
from numba import njit


@dataclass(frozen=True)
class ThrusterModel:
    """Static map from a PWM pulse (µs) to one thruster's thrust (N).

    `kind = "t200"`: [Yellowfish-TR eq. 27] with δ̃ = δ/400 − 3.75 and separate forward and
    reverse quadratics in δ̃ (coefficients [a, b, c] of a·δ̃² + b·δ̃ + c), zero
    thrust inside the dead zone (deadzone_rev, deadzone_fwd). start_fwd / start_rev (δ̃, None:
    the dead-zone edge): where a stopped motor starts (module docstring); an edge inside the
    dead zone is the dead-zone edge, since no motor runs there.
    `kind = "direct"`: inputs are thrusts in N; no PWM map is known.
    `kind = "propeller_rudder"`: inputs are the propeller speed n (rps) and the rudder angle δ (rad),
    bounded by |n| ≤ rps_max and |δ| ≤ rudder_max_deg where given (which a scenario's full
    normalised command also asks for); gains, lag, decay and speed loss do not apply.
    Thrust bounds (N) are the map's values at full PWM, or, for "direct", thrust_min_n and
    thrust_max_n where the vessel's source gives them: none given, the thrust is not bounded.
    command_scale_n: the thrust a full normalised command (a scenario's ±1) asks of an unbounded
    "direct" thruster; a scale for scenarios, not a limit.
    """

    kind: str = "t200"
    pwm_scale_us: float = 400.0
    pwm_offset: float = 3.75
    forward: tuple[float, float, float] = (14.35, 14.97, -0.6218)
    reverse: tuple[float, float, float] = (-12.8, 9.5, -0.3595)
    deadzone_fwd: float = 0.0775
    deadzone_rev: float = -0.0925
    pwm_min_us: float = 1100.0
    pwm_max_us: float = 1900.0
    thrust_min_n: float | None = None
    thrust_max_n: float | None = None
    command_scale_n: float | None = None
    lag_s: float = 0.0
    delay_s: float = 0.0
    decay_per_min: float = 0.0
    advance_loss: float = 0.0  # c of the module docstring, √N·s/m
    gain_left: float = 1.0
    gain_right: float = 1.0
    reversed_channels: tuple[str, ...] = field(default_factory=tuple)
    start_fwd: float | None = None
    start_rev: float | None = None
    rps_max: float | None = None
    rudder_max_deg: float | None = None
    ramp_s: float = 0.0  # slew limit: s for the command to change by the full forward thrust; 0 = none
    supply_exponent: float = 0.0  # k of (V/V_ref)^k, the thrust's answer to the supply voltage; 0 = none
    supply_ref_v: float | None = None  # V_ref, V: the supply voltage the map holds at
    full_share: float = 1.0  # forward thrust at full PWM as a share of the map's, a smooth saturation
    # one thruster's own dead-zone edges (forward, reverse δ̃), in place of the shared ones for it: an ESC
    # or a motor of its own; None: the shared edges (the start edges stay the shared ones)
    deadzone_left: tuple[float, float] | None = None
    deadzone_right: tuple[float, float] | None = None
    # one thruster's ESC takes neutral + span·(logged − neutral) (module docstring); 1: the pulse as logged
    pwm_span_left: float = 1.0
    pwm_span_right: float = 1.0

    @property
    def ramping(self) -> bool:
        """A thrust ramp (slew limit) acts: its state must be carried along a run."""
        return self.ramp_s > 0 and self.kind != "propeller_rudder"

    @property
    def slew_n_per_s(self) -> float:
        """The fastest the thrust command changes (N/s): the full forward thrust (the upper bound, or
        command_scale_n for an unbounded thruster) over ramp_s; inf without a ramp."""
        if not self.ramp_s > 0:
            return np.inf
        hi = self.bounds()[1]
        full = hi if np.isfinite(hi) else self.command_scale_n
        if full is None or not full > 0:
            raise ValueError("a thrust ramp needs a bounded thruster or command_scale_n")
        return float(full) / self.ramp_s

    def slewed(self, command_n, dt_s: float, start_n=None) -> tuple[np.ndarray, np.ndarray]:
        """(n, 2) thrust commands (N, one per step of dt_s, held over it) through the slew limit,
        within the bounds: (each step's mean thrust command, the ramp's value at the end).
        `start_n`: where the ramp stands before the first step (None: settled at the first command).
        Unchanged (but bounded) without a ramp."""
        cmd = np.clip(np.asarray(command_n, float), *self.bounds())
        if not self.ramping or not len(cmd):
            return cmd, (cmd[-1] if len(cmd) else np.asarray(start_n, float))
        start = cmd[0] if start_n is None else np.asarray(start_n, float)
        return _slewed(cmd, self.slew_n_per_s * dt_s, np.array(start, float))

    def slewed_parts(self, first_n: np.ndarray, share: np.ndarray, rest_n: np.ndarray, dt_s: float,
                     several: "SeveralInputs | None" = None) -> tuple[np.ndarray, np.ndarray]:
        """Steps of dt_s taken in two parts through the slew limit, settled at the first command: on
        step k the ramp heads for `first_n[k]` (N) over the share `share[k]` of the step, then for
        `rest_n[k]` over the rest (a step with share 1 is one part, as `slewed`); `several`: the
        steps whose rest holds several commands, the ramp heading for each in turn over its share.
        Returns each part's mean thrust command, (n, 2) each, within the bounds: the first part's,
        the rest's (the first's where share is 1)."""
        lo, hi = self.bounds()
        first = np.clip(np.asarray(first_n, float), lo, hi)
        rest = np.clip(np.asarray(rest_n, float), lo, hi)
        if not self.ramping or not len(first):
            return first, np.where(np.asarray(share)[:, None] < 1.0, rest, first)
        which = np.full(len(first), -1, np.int64)
        held, commands = np.zeros((1, 1)), np.zeros((1, 1, first.shape[1]))
        if several is not None:
            which[several.steps] = np.arange(len(several.steps))
            held, commands = several.held, np.clip(np.asarray(several.commands, float), lo, hi)
        return _slewed_parts(first, np.asarray(share, float), rest, self.slew_n_per_s * dt_s, first[0].copy(),
                             which, np.asarray(held, float), commands)

    @property
    def input_kind(self) -> str:
        """What a recording or input series must hold to drive these thrusters: "pwm" (µs),
        "thrust" (N) or "propeller_rudder" (rps, rad)."""
        return {"t200": "pwm", "propeller_rudder": "propeller_rudder"}.get(self.kind, "thrust")

    def channel_bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((lo, hi) of the first input, (lo, hi) of the second) in the engine's control units:
        thrust N for thrusters, rps and rad for a propeller and rudder (±inf where none)."""
        if self.kind == "propeller_rudder":
            n = np.inf if self.rps_max is None else float(self.rps_max)
            d = np.inf if self.rudder_max_deg is None else float(np.radians(self.rudder_max_deg))
            return (-n, n), (-d, d)
        return self.bounds(), self.bounds()

    def as_logged(self) -> "ThrusterModel":
        """These thrusters as a recording's replay drives them. A propeller and rudder's logged
        speed and angle are what the ship did: its bounds (rps_max, rudder_max_deg) are what the
        twin's own scenarios and controllers may command, and a replay clipped to them would run a
        faster test at the bound's speed. A PWM stays bounded by the ESC's range, which clips the
        real pulse too."""
        if self.kind != "propeller_rudder" or (self.rps_max is None and self.rudder_max_deg is None):
            return self
        return replace(self, rps_max=None, rudder_max_deg=None)

    def normalised(self, pwm_us):
        """δ̃ = δ/400 − 3.75 [Yellowfish-TR §V-B], clipped to the PWM range."""
        pwm = np.clip(np.asarray(pwm_us, dtype=float), self.pwm_min_us, self.pwm_max_us)
        return pwm / self.pwm_scale_us - self.pwm_offset

    @property
    def start_edges(self) -> tuple[float, float]:
        """(forward, reverse) δ̃ at which a stopped motor starts: never inside the dead zone."""
        f = self.deadzone_fwd if self.start_fwd is None else max(self.start_fwd, self.deadzone_fwd)
        r = self.deadzone_rev if self.start_rev is None else min(self.start_rev, self.deadzone_rev)
        return f, r

    @property
    def hysteretic(self) -> bool:
        """A PWM map whose motors start beyond the dead-zone edges (the map acts on a series)."""
        return self.kind == "t200" and self.start_edges != (self.deadzone_fwd, self.deadzone_rev)

    @property
    def neutral_us(self) -> float:
        """The PWM of δ̃ = 0 (µs)."""
        return self.pwm_offset * self.pwm_scale_us

    @property
    def spanned(self) -> bool:
        """One thruster's ESC answers another PWM range than the logged one (pwm_span_left/right)."""
        return self.kind == "t200" and (self.pwm_span_left != 1.0 or self.pwm_span_right != 1.0)

    def received(self, pwm_us):
        """The pulses (µs) the ESCs answer for logged pulses with a last axis of two (left, right):
        neutral + span·(logged − neutral) (module docstring; the map clips them to the PWM range).
        Other shapes (one thruster's curve, the map's ends) are taken as they are."""
        pwm = np.asarray(pwm_us, dtype=float)
        if not self.spanned or not pwm.shape or pwm.shape[-1] != 2:
            return pwm
        neutral = self.neutral_us
        return neutral + np.array([self.pwm_span_left, self.pwm_span_right]) * (pwm - neutral)

    def as_driven(self, pwm_us) -> np.ndarray:
        """(n, 2) PWM series (µs, in time order, motors stopped before it) as the motors answer it:
        a stopped motor's pulse becomes neutral (module docstring). Unchanged without hysteresis.
        The pulses stay the logged ones (the ESCs' own range acts in the map), the states are the
        received pulses'."""
        pwm = np.array(pwm_us, dtype=float)
        if not self.hysteretic:
            return pwm
        start_f, start_r = self.start_edges
        seen = self.received(pwm)
        for j in range(pwm.shape[1]):
            running = motor_states(self.normalised(seen[:, j]), start_f, self.deadzone_fwd, start_r, self.deadzone_rev)
            pwm[(running == 0) & np.isfinite(pwm[:, j]), j] = self.neutral_us
        return pwm

    def driven_step(self, states: tuple[int, int], pwm_us) -> tuple[tuple[int, int], tuple[float, float]]:
        """One pulse pair after `states` (+1 ahead, −1 astern, 0 stopped): (new states, the pair as
        the motors answer it): `as_driven` for a controller that makes its PWM as it goes."""
        if not self.hysteretic:
            return states, (float(pwm_us[0]), float(pwm_us[1]))
        start_f, start_r = self.start_edges
        seen = self.received(np.array([float(pwm_us[0]), float(pwm_us[1])]))
        new = tuple(motor_state_step(s, float(self.normalised(p)), start_f, self.deadzone_fwd, start_r,
                                     self.deadzone_rev) for s, p in zip(states, seen))
        return new, tuple(float(p) if s else self.neutral_us for s, p in zip(new, pwm_us))

    def thrust_from_pwm(self, pwm_us):
        """Commanded thrust T(δ) in N [Yellowfish-TR eq. 27], before gains and lag; a last axis of
        two is (left, right), each with its own dead zone and PWM span where it has one."""
        if self.kind != "t200":
            raise ValueError("this vessel has no PWM model: give thrust in N")
        return self._map(self.received(pwm_us))

    def _map(self, pwm_us):
        """thrust_from_pwm of pulses as the ESCs receive them."""
        x = self.normalised(pwm_us)
        fwd = np.polyval(self.forward, x)
        if self.full_share != 1.0:
            fwd = saturated(fwd, self.full_forward_n, self.full_share)
        rev = np.polyval(self.reverse, x)
        edge_fwd, edge_rev = self.deadzone_edges(np.shape(x))
        return np.where(x >= edge_fwd, fwd, np.where(x <= edge_rev, rev, 0.0))

    def edges_of(self, side: int) -> tuple[float, float]:
        """(forward, reverse) dead-zone edges (δ̃) of thruster `side` (0 left, 1 right)."""
        own = self.deadzone_left if side == 0 else self.deadzone_right
        return (self.deadzone_fwd, self.deadzone_rev) if own is None else (float(own[0]), float(own[1]))

    def deadzone_edges(self, shape: tuple = ()):
        """The dead-zone edges to compare inputs of `shape` with: per thruster along a last axis of two
        where a thruster has edges of its own, else the shared ones."""
        if (self.deadzone_left is None and self.deadzone_right is None) or not shape or shape[-1] != 2:
            return self.deadzone_fwd, self.deadzone_rev
        left, right = self.edges_of(0), self.edges_of(1)
        return np.array([left[0], right[0]]), np.array([left[1], right[1]])

    @property
    def full_forward_n(self) -> float:
        """The map's forward thrust at full PWM (N), before its saturation."""
        return float(np.polyval(self.forward, float(self.normalised(self.pwm_max_us))))

    def forward_rises(self) -> bool:
        """The forward branch's thrust grows with the PWM from its edge to full (a quadratic's slope
        is linear in δ̃: both ends suffice)."""
        a, b, _ = self.forward
        ends = (self.deadzone_fwd, float(self.normalised(self.pwm_max_us)))
        return all(2 * a * x + b > 0 for x in ends)

    def reverse_falls(self) -> bool:
        """The astern branch's thrust grows astern as the PWM falls from its edge to full astern."""
        a, b, _ = self.reverse
        ends = (self.deadzone_rev, float(self.normalised(self.pwm_min_us)))
        return all(2 * a * x + b > 0 for x in ends)

    def edge_thrusts_n(self) -> tuple[float, float]:
        """(forward, astern) thrust (N) of the map at its dead-zone edges: ≥ 0 and ≤ 0 for a map whose
        branches push the way their PWM asks."""
        return float(np.polyval(self.forward, self.deadzone_fwd)), float(np.polyval(self.reverse, self.deadzone_rev))

    def bounds(self) -> tuple[float, float]:
        """(T_min, T_max) of one thruster in N; ±inf where no bound is given."""
        if self.kind == "t200":
            ends = self._map(np.array([self.pwm_min_us, self.pwm_max_us]))  # the map's ends, not a pair
            return float(ends[0]), float(ends[1])
        if self.kind == "propeller_rudder":
            return -np.inf, np.inf  # no thrust input: the inputs' own bounds are channel_bounds()
        lo = -np.inf if self.thrust_min_n is None else float(self.thrust_min_n)
        hi = np.inf if self.thrust_max_n is None else float(self.thrust_max_n)
        return lo, hi

    @property
    def bounded(self) -> bool:
        return bool(np.all(np.isfinite(self.bounds())))

    def command_range(self) -> tuple[float, float]:
        """The thrust (N) a normalised command of −1 and +1 stands for: the bounds, or
        ±command_scale_n for an unbounded thruster (ValueError if neither is given)."""
        lo, hi = self.bounds()
        if np.isfinite(lo) and np.isfinite(hi):
            return lo, hi
        if self.command_scale_n is None:
            raise ValueError("an unbounded direct-thrust model needs command_scale_n to run a scenario")
        return -float(self.command_scale_n), float(self.command_scale_n)

    def at_escs(self, pwm_us) -> np.ndarray:
        """PWM (µs) as the ESCs take it, within their range (pwm_min_us, pwm_max_us): what a run
        records, as an autopilot's log holds its outputs within the range it may send (NaN stays)."""
        pwm = np.asarray(pwm_us, float)
        return np.clip(pwm, self.pwm_min_us, self.pwm_max_us) if self.kind == "t200" else pwm

    def gains(self) -> np.ndarray:
        return np.array([self.gain_left, self.gain_right])

    def decay_factor(self, t_s):
        """Fraction of the commanded thrust left t_s seconds into the recording (floored at 0)."""
        return np.maximum(0.0, 1.0 - self.decay_per_min * np.asarray(t_s, float) / 60.0)

    @property
    def follows_supply(self) -> bool:
        """The thrust answers a logged supply voltage ((V/V_ref)^k with k > 0)."""
        return self.supply_exponent > 0 and self.kind != "propeller_rudder"

    def supply_factor(self, volt_v):
        """(V/V_ref)^k per sample of the supply voltage volt_v (V); 1 without one (None) or where a
        sample is NaN (no voltage logged yet), and 1 for thrusters that do not follow it."""
        if volt_v is None or not self.follows_supply:
            return 1.0
        ratio = np.asarray(volt_v, float) / self.supply_ref_v
        return np.where(np.isfinite(ratio), np.abs(ratio) ** self.supply_exponent, 1.0)

    def command(self, kind: str, held, t_s, supply_v=None):
        """Thrust command (N) per thruster, (n, 2), from inputs held at times t_s (s, recording clock).

        `held` are the inputs in force at t_s − delay_s (the caller looks them up):
        PWM in µs through eq. 27 (kind "pwm") or thrust in N (kind "thrust"), then
        the decay and, with `supply_v` (V at t_s, one per time), the supply factor. Gains, lag
        and the advance-speed loss act later, in the engine.
        A propeller and rudder's (n rps, δ rad) (kind "propeller_rudder") are the controls as
        they are (the MMG forces clip them to the bounds).
        """
        if self.kind == "propeller_rudder" or kind == "propeller_rudder":
            if kind != self.input_kind:
                raise ValueError(f"thrusters of kind '{self.kind}' are driven by {self.input_kind} inputs, "
                                 f"not {kind}")
            held = np.asarray(held, float)
            return held * np.ones_like(np.asarray(t_s, float))[..., None]
        raw = self.thrust_from_pwm(held) if kind == "pwm" else np.asarray(held, float)
        factor = np.asarray(self.decay_factor(t_s)) * np.asarray(self.supply_factor(supply_v))
        return raw * factor[..., None]


def saturated(thrust_n, full_n: float, share: float):
    """Forward thrust through the saturation T/√(1 + k·(T/T_full)²), k = 1/share² − 1 (module
    docstring); scalars or arrays."""
    k = 1.0 / share ** 2 - 1.0
    return thrust_n / (1.0 + k * (thrust_n / full_n) ** 2) ** 0.5


def motor_states(x, start_fwd: float, stop_fwd: float, start_rev: float, stop_rev: float) -> np.ndarray:
    """+1 (running ahead), −1 (astern) or 0 (stopped) per sample of one motor's δ̃ series, stopped
    before it: ahead from a sample ≥ start_fwd until one < stop_fwd, astern from one ≤ start_rev
    until one > stop_rev (a NaN sample changes nothing). The last start must be later than the
    last stop: two running maxima, no loop over the samples."""
    x = np.asarray(x, float)
    idx = np.arange(len(x))

    def since(started, stopped) -> np.ndarray:
        return np.maximum.accumulate(np.where(started, idx, -1)) > np.maximum.accumulate(np.where(stopped, idx, -1))
    return since(x >= start_fwd, x < stop_fwd).astype(int) - since(x <= start_rev, x > stop_rev).astype(int)


def motor_state_step(state: int, x: float, start_fwd: float, stop_fwd: float, start_rev: float,
                     stop_rev: float) -> int:
    """`motor_states` one sample at a time: the state after δ̃ = x."""
    if x != x:
        return state
    if (state == 1 and x < stop_fwd) or (state == -1 and x > stop_rev):
        state = 0
    if state == 0:
        state = 1 if x >= start_fwd else (-1 if x <= start_rev else 0)
    return state


# Published maximum thrust of a T200 by supply voltage (kgf, forward and reverse) [BlueRobotics-T200], and
# the voltage [Yellowfish-TR eq. 27]'s map holds at: its 28.7 N forward per thruster is the 12 V figure
# scaled down the same power law, which puts it at 10 V.
T200_MAX_KGF = {12.0: (3.71, 2.92), 16.0: (5.25, 4.10), 20.0: (6.70, 5.05)}
T200_MAP_VOLTAGE_V = 10.0


def t200_voltage_gain(volts: float) -> float:
    """The T200's forward thrust at `volts` over its thrust at the map's 10 V: a power law through
    the published maximum thrusts (log-log interpolation between 12, 16 and 20 V, the 12-16 V law
    below 12 V and the 16-20 V law above 20 V)."""
    vs = sorted(T200_MAX_KGF)
    fwd = [T200_MAX_KGF[v][0] for v in vs]

    def thrust(v: float) -> float:
        i = 0 if v <= vs[1] else 1
        k = math.log(fwd[i + 1] / fwd[i]) / math.log(vs[i + 1] / vs[i])
        return fwd[i] * (v / vs[i]) ** k

    return thrust(float(volts)) / thrust(T200_MAP_VOLTAGE_V)


def advance_speed(nu_r: np.ndarray, thruster_y_m) -> np.ndarray:
    """u_a = u_r − r·y_i (m/s) per thruster: its own speed through the water along body x."""
    return np.asarray(nu_r, float)[..., :1] - np.asarray(nu_r, float)[..., 2:3] * np.asarray(thruster_y_m, float)


def advance_loss(c: float, static_thrust_n, u_a_m_s) -> np.ndarray:
    """−c·√|T0|·u_a (N) per thruster: what the advance takes off the static thrust T0 (module docstring)."""
    return -c * np.sqrt(np.abs(np.asarray(static_thrust_n, float))) * np.asarray(u_a_m_s, float)


def delivered(c: float, static_thrust_n, nu_r: np.ndarray, thruster_y_m) -> np.ndarray:
    """T0 − c·√|T0|·u_a (N) per thruster (module docstring)."""
    return np.asarray(static_thrust_n, float) + advance_loss(c, static_thrust_n, advance_speed(nu_r, thruster_y_m))


def advance_force(c: float, static_thrust_n, nu_r: np.ndarray, thruster_y_m) -> np.ndarray:
    """Body-frame (X, Y, N) of both thrusters' advance loss at one state ν_r [Yellowfish-TR eq. 26]."""
    return allocation_matrix(thruster_y_m) @ advance_loss(c, static_thrust_n, advance_speed(nu_r, thruster_y_m))


def allocation_matrix(thruster_y_m: tuple[float, float]) -> np.ndarray:
    """B mapping [T_L, T_R] to τ = [Fu, Fv, τr] ([Yellowfish-TR eq. 26; Bertoni-2024] B).

    Thrusters push along body x at lateral positions y_L (port, < 0 in FRD) and
    y_R; the yaw moment of a force F_x at y is −y·F_x, so for y = ∓d/2 this is
    τr = d/2·T_L − d/2·T_R as in eq. 26c.
    """
    y_left, y_right = thruster_y_m
    return np.array([[1.0, 1.0], [0.0, 0.0], [-y_left, -y_right]])


def force_torque_bounds(model: ThrusterModel, thruster_y_m) -> dict[str, float]:
    """Fu and τr bounds for both thrusters saturated [Yellowfish-TR Table VIII]; None for an
    unbounded thruster."""
    t_min, t_max = model.bounds()
    if not (np.isfinite(t_min) and np.isfinite(t_max)):
        return {"Fu_min_n": None, "Fu_max_n": None, "tau_r_min_nm": None, "tau_r_max_nm": None}
    B = allocation_matrix(thruster_y_m)
    corners = np.array([[a, b] for a in (t_min, t_max) for b in (t_min, t_max)]) * model.gains()
    tau = corners @ B.T
    return {
        "Fu_min_n": float(tau[:, 0].min()),
        "Fu_max_n": float(tau[:, 0].max()),
        "tau_r_min_nm": float(tau[:, 2].min()),
        "tau_r_max_nm": float(tau[:, 2].max()),
    }


def lag_time_constant_s(alpha: float, sample_s: float) -> float:
    """Continuous time constant of [Morel-2024 eq. 15], T(k) = αT(k−1) + βT_st(k−1)."""
    if not 0.0 < alpha < 1.0:
        raise ValueError("alpha must lie in (0, 1) for a stable first-order lag")
    return -sample_s / np.log(alpha)


def lag_alpha(time_constant_s: float, sample_s: float) -> float:
    """Inverse of `lag_time_constant_s`: the discrete pole α = exp(−h/τ)."""
    return float(np.exp(-sample_s / time_constant_s))


class SeveralInputs(NamedTuple):
    """Steps whose rest holds two inputs or more, each in turn: a ramp heads for each over its share."""

    steps: np.ndarray  # (m,) the steps
    held: np.ndarray  # (m, d) each input's share of its step, zero past the step's last
    commands: np.ndarray  # (m, d, 2) each input's command


@njit(cache=True)
def slew_step(start_n: float, command_n: float, max_change_n: float) -> tuple[float, float]:
    """One step of the slew limit (module docstring): a ramp at `start_n` heads for `command_n`,
    changing by at most `max_change_n` (rate × step) over the step. (The step's mean, the end value.)
    Compiled, so that a series (`_slewed`) and the closed loops' one step at a time share it."""
    d = command_n - start_n
    if d >= max_change_n:
        return start_n + 0.5 * max_change_n, start_n + max_change_n
    if d <= -max_change_n:
        return start_n - 0.5 * max_change_n, start_n - max_change_n
    # the ramp arrives within the step, after the fraction |d|/max_change of it, and holds there
    return command_n - 0.5 * d * abs(d) / max_change_n, command_n


@njit(cache=True)
def _slewed(cmd: np.ndarray, max_change_n: float, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`slew_step` over a series (a loop numpy cannot vectorise: each step starts where the last ended)."""
    means = np.empty_like(cmd)
    state = start.copy()
    for k in range(cmd.shape[0]):
        for j in range(cmd.shape[1]):
            means[k, j], state[j] = slew_step(state[j], cmd[k, j], max_change_n)
    return means, state


@njit(cache=True)
def slew_parts(start_n: float, first_n: float, share: float, rest_n: float,
               max_change_n: float) -> tuple[float, float, float]:
    """One step of the slew limit in two parts: the ramp at `start_n` heads for `first_n` over the
    share `share` of the step, then for `rest_n` over the rest (max_change_n: rate × the whole step).
    (The first part's mean, the rest's mean, the end value.)"""
    first_mean, middle = slew_step(start_n, first_n, max_change_n * share)
    rest_mean, end = slew_step(middle, rest_n, max_change_n * (1.0 - share))
    return first_mean, rest_mean, end


@njit(cache=True)
def slew_through(start_n: float, held: np.ndarray, commands: np.ndarray, max_change_n: float) -> tuple[float, float]:
    """The slew limit heading for each command in turn, each over its share `held` of the step (zero:
    none): (the mean over their shares, the end value)."""
    total, state, span = 0.0, start_n, 0.0
    for i in range(len(held)):
        if held[i] > 0.0:
            mean, state = slew_step(state, commands[i], max_change_n * held[i])
            total += held[i] * mean
            span += held[i]
    return total / span, state


@njit(cache=True)
def _slewed_parts(first: np.ndarray, share: np.ndarray, rest: np.ndarray, max_change_n: float,
                  start: np.ndarray, which: np.ndarray, held: np.ndarray,
                  commands: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`slewed_parts` over a series; a step with share 1 is `slew_step` itself (the same bits)."""
    first_means = np.empty_like(first)
    rest_means = np.empty_like(first)
    state = start.copy()
    for k in range(first.shape[0]):
        for j in range(first.shape[1]):
            if share[k] < 1.0 and which[k] >= 0:
                first_means[k, j], state[j] = slew_step(state[j], first[k, j], max_change_n * share[k])
                rest_means[k, j], state[j] = slew_through(state[j], held[which[k]], commands[which[k], :, j],
                                                          max_change_n)
            elif share[k] < 1.0:
                first_means[k, j], rest_means[k, j], state[j] = slew_parts(state[j], first[k, j], share[k],
                                                                           rest[k, j], max_change_n)
            else:
                first_means[k, j], state[j] = slew_step(state[j], first[k, j], max_change_n)
                rest_means[k, j] = first_means[k, j]
    return first_means, rest_means
