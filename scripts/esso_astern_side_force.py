"""What the Esso Osaka's random tests said was missing when the propeller runs
astern, the physics put in, and the fit on tests it was not taken from.

    python scripts/esso_astern_side_force.py [--out docs]

1. The signature (twin.fit.evaluate.error_growth): over 10-s free runs from measured states every
   2 s on the 9 random tests, how the untuned twin's yaw-rate error grows, binned by the propeller's
   direction and the rudder; the anemometer's wind a known input, so the wind is not what is seen.
   Without the astern side force this error grows negative whenever the propeller runs astern,
   whatever the rudder: the ship's bow swings to starboard where the twin's does not, the
   paddle-wheel effect of a single screw backing.
2. The physics (physics/mmg.py, the vessel file's astern_side_y/_n: Hachii's form with the NAOE Esso
   3 m set's coefficients, published for this model, nothing fitted here), and the same table with it.
3. The untuned twin's pooled 30-s free-run R² on each family of tests with and without it, no wind
   and measured wind. The turning tests never run the propeller astern: there the twin is the same.

The recordings (../shared/data/esso) are read in place; without them the script says so and exits 0.
"""
from __future__ import annotations

import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.files import write_text_atomic  # noqa: E402
from twin.fit.evaluate import TwinPredictor, error_growth, evaluate  # noqa: E402
from twin.fit.windows import ModelCache  # noqa: E402
from twin.formats import read_recording  # noqa: E402
from twin.ident.identify import prepared  # noqa: E402
from esso_yaw_rate_window import DATA, DUPLICATE, esso_arguments  # noqa: E402  (scripts/ is on the path)

N_BINS = (("astern (n < −2 rps)", -np.inf, -2.0), ("stopped (|n| ≤ 2)", -2.0, 2.0), ("ahead (n > 2)", 2.0, np.inf))
RUDDER_BINS = (("δ < −5°", -np.inf, -5.0), ("|δ| ≤ 5°", -5.0, 5.0), ("δ > 5°", 5.0, np.inf))


def without_side_force(ship):
    p = replace(ship.mmg.propeller, astern_side_y=(0.0,) * 5, astern_side_n=(0.0,) * 5)
    return replace(ship, mmg=replace(ship.mmg, propeller=p))


def signature(vessel, preps) -> list[dict]:
    inputs, growth = error_growth(TwinPredictor(vessel, ModelCache(), "measured"), preps, 10.0, 2.0)
    n, rudder_deg, dr = inputs[:, 0], np.degrees(inputs[:, 1]), growth[:, 2]
    rows = []
    for n_label, n_lo, n_hi in N_BINS:
        for d_label, d_lo, d_hi in RUDDER_BINS:
            k = (n > n_lo) & (n <= n_hi) & (rudder_deg > d_lo) & (rudder_deg <= d_hi) & np.isfinite(dr)
            if k.sum() >= 5:
                rows.append({"propeller": n_label, "rudder": d_label, "windows": int(k.sum()),
                             "r_error_growth_rad_s": float(dr[k].mean()),
                             "standard_error": float(dr[k].std() / np.sqrt(k.sum()))})
    return rows


def main() -> int:
    args = esso_arguments(__doc__)
    if args is None:
        return 0
    started = time.time()
    ship = vessel_mod.load("esso_osaka")
    twins = {"without the astern side force": without_side_force(ship), "with it": ship}
    files = [f for f in sorted(DATA.glob("*.csv")) if f.name != DUPLICATE]
    preps = {fam: prepared([read_recording(f) for f in files if f.name.startswith(fam)], ship)
             for fam in ("random", "turn")}
    result = {"signature": {k: signature(v, preps["random"]) for k, v in twins.items()}, "r2": {}}
    for name, v in twins.items():
        for fam, ps in preps.items():
            for wind in (None, "measured"):
                m = evaluate(v, ps, stride_s=10.0, horizons={"free_run_30s": 30.0}, wind=wind)["free_run_30s"]
                result["r2"][f"{name} | {fam} | {wind or 'no wind'}"] = {d: m[d]["r2"] for d in "uvr"}
    seconds = time.time() - started
    lines = ["# The Esso Osaka backing its propeller: the side force the twin lacked", "",
             f"Written by `python scripts/esso_astern_side_force.py` ({seconds:.0f} s); the module docstring says "
             "what each part is.", "", "## Where the yaw-rate error grows (random tests, 10-s free runs every 2 s, "
             "measured wind a known input)", "",
             "| propeller | rudder | windows | r error growth over 10 s, without → with (rad/s) |", "|---|---|---|---|"]
    without, with_it = result["signature"].values()
    by_bin = {(b["propeller"], b["rudder"]): b for b in with_it}
    for a in without:
        b = by_bin.get((a["propeller"], a["rudder"]))
        if b is None:
            continue
        lines.append(f"| {a['propeller']} | {a['rudder']} | {a['windows']} | {a['r_error_growth_rad_s']:+.4f} ± "
                     f"{a['standard_error']:.4f} → {b['r_error_growth_rad_s']:+.4f} ± {b['standard_error']:.4f} |")
    lines += ["", "## The untuned twin, 30-s free runs from measured states every 10 s (pooled R² u / v / r)", "",
              "| twin | tests | wind | R² u / v / r |", "|---|---|---|---|"]
    for key, m in result["r2"].items():
        name, fam, wind = key.split(" | ")
        lines.append(f"| {name} | {fam} | {wind} | " + " / ".join(f"{m[d]:.3f}" for d in "uvr") + " |")
    args.out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out / "esso_astern_side_force.md", "\n".join(lines) + "\n")
    write_text_atomic(args.out / "esso_astern_side_force.json", json.dumps(result, indent=1) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
