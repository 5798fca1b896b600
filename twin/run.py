"""A simulated or replayed run: time series of state and inputs, SI units, NED."""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from .drive import InputSeries
from .errors import TwinError

CSV_COLUMNS = ("t", "x", "y", "psi", "u", "v", "r", "pwm_left", "pwm_right", "thrust_left", "thrust_right")
SIX_DOF_COLUMNS = ("down", "roll", "pitch")  # a 6-DOF run's body origin below the mean surface (m), rad
# a propeller-and-rudder ship's inputs, in the columns the recording readers take (formats/csv.py)
PROPELLER_RUDDER_COLUMNS = ("prop_rps", "rudder_deg")


@dataclass
class Run:
    """States at the sample times t (s): η = (x, y, ψ) in m, m, rad (NED); ν = (u, v, r)
    in m/s, m/s, rad/s; inputs held over each sample: PWM (µs, NaN when the run
    was driven by thrust) and the thrust each thruster delivers (N)."""

    t: np.ndarray
    eta: np.ndarray  # (n, 3)
    nu: np.ndarray  # (n, 3)
    pwm_us: np.ndarray  # (n, 2)
    thrust_n: np.ndarray  # (n, 2)
    meta: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        if not len(self.t):
            return "Run(empty)"
        return (f"Run({self.meta.get('vessel', '?')}, {self.t[-1] - self.t[0]:g} s, {len(self.t)} samples, final "
                f"position ({self.eta[-1, 0]:.2f}, {self.eta[-1, 1]:.2f}) m)")

    def columns(self) -> dict[str, np.ndarray]:
        return {
            "t": self.t, "x": self.eta[:, 0], "y": self.eta[:, 1], "psi": self.eta[:, 2],
            "u": self.nu[:, 0], "v": self.nu[:, 1], "r": self.nu[:, 2],
            "pwm_left": self.pwm_us[:, 0], "pwm_right": self.pwm_us[:, 1],
            "thrust_left": self.thrust_n[:, 0], "thrust_right": self.thrust_n[:, 1],
        }

    def propeller_rudder(self) -> np.ndarray | None:
        """(n, 2) a propeller-and-rudder ship's inputs held at the samples: propeller speed (rps) and
        rudder angle (rad), as the run's input series gave them (before the thrusters' delay, as
        pwm_us is); None for a run driven by PWM or thrust, or one without its inputs."""
        inputs = self.meta.get("inputs")
        if getattr(inputs, "kind", None) != "propeller_rudder":
            return None
        return np.asarray(inputs.at(np.asarray(self.t, float) - float(self.meta.get("start_s", 0.0))), float)

    def to_csv_text(self) -> str:
        """The run layout: a header of CSV_COLUMNS (then PROPELLER_RUDDER_COLUMNS, rps and degrees, for
        a propeller-and-rudder ship: its pwm columns are empty and its thrust columns hold the
        propeller thrust and the rudder normal force, so without them nothing could replay the
        run; and SIX_DOF_COLUMNS for a 6-DOF run), then one row per sample, each value '{:.9g}' and an empty cell for NaN (or infinity)."""
        return "".join(self.csv_blocks())

    def csv_blocks(self, rows: int = 65536) -> Iterator[str]:
        """to_csv_text in pieces of `rows` samples (the header first): a long run's text is never whole
        in memory. Formatted a column at a time, not a cell at a time through csv.writer (a 1-h run
        has 400 000 cells); the cells need no quoting."""
        cols = self.columns()
        names = list(CSV_COLUMNS)
        held = self.propeller_rudder()
        if held is not None:
            cols.update({"prop_rps": held[:, 0], "rudder_deg": np.degrees(held[:, 1])})
            names += list(PROPELLER_RUDDER_COLUMNS)
        six = self.meta.get("six_dof")
        if six is not None:
            cols.update({"down": six["down_m"], "roll": six["roll_rad"], "pitch": six["pitch_rad"]})
            names += list(SIX_DOF_COLUMNS)
        yield ",".join(names) + "\n"
        for first in range(0, len(self.t), rows):
            cells = [_cells(cols[c][first:first + rows]) for c in names]
            yield "".join([",".join(row) + "\n" for row in zip(*cells)])


def _cells(values) -> list[str]:
    """'{:.9g}' of each value of one column, "" where it is not finite."""
    values = np.asarray(values, dtype=float)
    fmt = "{:.9g}".format
    finite = np.isfinite(values)
    if finite.all():
        return list(map(fmt, values.tolist()))
    return [fmt(x) if ok else "" for x, ok in zip(values.tolist(), finite.tolist())]


def read_csv(path: str | Path) -> Run:
    """Read a run written by `Run.to_csv_text` (empty cells are NaN); a propeller-and-rudder ship's
    inputs come back as the run's input series (meta "inputs", "start_s")."""
    path = Path(path)
    try:
        rows = list(csv.DictReader(path.read_text().splitlines()))
    except (OSError, UnicodeDecodeError) as exc:
        raise TwinError(f"{path.name}: cannot read ({exc})") from None
    if not rows or set(CSV_COLUMNS) - set(rows[0]):
        raise TwinError(f"{path.name}: not a run CSV (needs columns {', '.join(CSV_COLUMNS)})")
    names = CSV_COLUMNS + tuple(c for c in PROPELLER_RUDDER_COLUMNS if c in rows[0])
    a = {c: np.array([float(r[c]) if r[c] != "" else np.nan for r in rows]) for c in names}
    meta = {}
    if set(PROPELLER_RUDDER_COLUMNS) <= set(a) and len(a["t"]):
        start = float(a["t"][0])
        meta = {"start_s": start, "inputs": InputSeries(a["t"] - start, np.column_stack(
            [a["prop_rps"], np.radians(a["rudder_deg"])]), "propeller_rudder")}
    return Run(
        a["t"], np.column_stack([a["x"], a["y"], a["psi"]]), np.column_stack([a["u"], a["v"], a["r"]]),
        np.column_stack([a["pwm_left"], a["pwm_right"]]), np.column_stack([a["thrust_left"], a["thrust_right"]]),
        meta=meta,
    )
