"""What a diagnosis concludes beyond the effects it names, computed, not worded: the candidates that
would have earned their place but for an unphysical edge, the ones the recording hints at without
proving, how much more recording would prove them, and the thresholds these rest on. The report
(report.py) words them; the diagnosis (doctor.py) and the scripts that score diagnoses read them here.
"""
from __future__ import annotations

from ..effects import candidates
from .search import REL_EXCESS, Z_MIN

TIMING_EFFECTS = ("clock_offset", "heading_latency", "gnss_latency")
MODEL_FORM_SIGMA = 3.0  # a DOF still this many noise σ off after the amendment: the twin's form is off there
FOLLOWS_R = 0.3  # doctor._unexplained lists the signals a residual correlates with beyond this
MIN_UNANIMOUS_BLOCKS = 10  # the fewest blocks whose votes, all for, reach z ≥ 3 in the exact test (z 3.1)
PROMISING_Z = 2.0  # below Z_MIN: worth recording more for, never named
PROMISING_UNANIMOUS = 3  # or every one of at least this many affected blocks for it (4 of 4 is z 1.5 at best)


def at_edge(d) -> list[dict]:
    """Candidates of the last round that would have earned their place but for a parameter fitted
    to an unphysical edge of its range on every fold (search.at_unphysical_edge).

    Args:
        d: a diagnosis (doctor.Diagnosis), read for its rounds.

    Returns:
        The last round's candidate records (dicts of search.py) that qualify, in the round's order.
    """
    last = d.rounds[-1].get("candidates", []) if d.rounds else []
    return [c for c in last if c.get("at_edge") and c["z"] >= Z_MIN and c["excess_gain"] >= REL_EXCESS]


def more_recording_factor(candidate: dict) -> float | None:
    """How many times as long a recording of the same kind would take a candidate's z to Z_MIN if
    the further blocks voted as these did: z grows as √(blocks) at a fixed mix of votes, and no
    fewer than MIN_UNANIMOUS_BLOCKS blocks can reach it (which, every block voting for, is exactly
    what it takes).

    Args:
        candidate: a round's record of a candidate: z, blocks_for, blocks_against.

    Returns:
        The factor (≥ 1), or None where z ≤ 0 or no block is affected (no trend to extrapolate).
    """
    n = candidate["blocks_for"] + candidate["blocks_against"]
    if candidate["z"] <= 0 or n == 0:
        return None
    if candidate["blocks_against"] == 0:  # every block for: the exact test needs just ten such blocks
        return max(MIN_UNANIMOUS_BLOCKS / n, 1.0)
    return max((Z_MIN / candidate["z"]) ** 2, MIN_UNANIMOUS_BLOCKS / n)


def promising(d) -> list[dict]:
    """Candidates of the last round (the one where nothing more earned its place) that remove at
    least REL_EXCESS of the excess misfit with z ≥ PROMISING_Z or all of at least
    PROMISING_UNANIMOUS affected blocks for them, but too few blocks for z ≥ Z_MIN: the recording
    hints, it does not prove. One per family of effects (its rivals of the same family tie with it).

    Args:
        d: a diagnosis (doctor.Diagnosis), read for its rounds, effects and prior.

    Returns:
        The candidate records (dicts of search.py) hinted at, in the round's order.
    """
    if not d.rounds:
        return []
    kept = {e["name"] for e in d.effects}
    best = []
    for c in d.rounds[-1].get("candidates", []):
        unanimous = c["blocks_against"] == 0 and c["blocks_for"] >= PROMISING_UNANIMOUS
        if c["name"] in kept or c["z"] >= Z_MIN or c["excess_gain"] < REL_EXCESS or \
                not (c["z"] >= PROMISING_Z or unanimous):
            continue
        if any(family(d, c["name"]) == family(d, b["name"]) for b in best):
            continue
        best.append(c)
    return best


def family(d, name: str) -> str:
    """The family of the library's effect `name` for the diagnosed vessel ("" for a name the library
    does not offer it): what one kind of recording settles (report.NEXT)."""
    # two logs: the per-log effects have a family too; any reference voltage: the supply effect's family
    cand = candidates(d.prior, ["log 1", "log 2"], supply_ref_v=1.0).get(name)
    return cand.family if cand is not None else ""
