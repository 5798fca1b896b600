"""Does recording the trial a diagnosis proposes settle what it could not?

    python scripts/separating_trials.py [--set SET] [--page-only]

Where `twin diagnose` keeps an effect beside a rival the recording cannot tell from it, it proposes
the trial (twin.synth.manoeuvres.TRIALS) on which the two readings' twins part most, and how much of
it to record (twin/diagnose/separate.py). This study takes that advice and checks it: for each
concealed effect, two outings of a `twin dataset` of the BlueBoat (4 and 2 segments of its default
manoeuvres, as the README's tour makes them) are diagnosed together from the shipped, untuned twin;
where a rival is left unsettled, a third outing of the same truth is made of the proposed trial alone
(as many of its programs, 30-49 s each, as the proposal's minutes take, rounded up), and the three are diagnosed together.

Proof set `first`, fixed before it was run: six truths of the library's thrust and drag families (the
ones whose readings share a steady state), each at its own seeds. Exact: the truth named with each
value within 30 % and nothing else named; settled: exact with no rival left unsettled. The truths are
the library's own forms: the study checks the proposal, not the diagnosis's reach beyond its forms
(scripts/blind_truths.py and scripts/independent_truths.py do that).

Results land in docs/results/separating_trials.md and data/separating_trials.json.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.diagnose.doctor import diagnose  # noqa: E402
from twin.diagnose.separate import settling  # noqa: E402
from twin.effects import as_effect  # noqa: E402
from twin.synth.dataset import generate  # noqa: E402
from twin.synth.manoeuvres import trial  # noqa: E402
from twin.viz.pages import ResultPage, ResultTable, checkout_commit  # noqa: E402

TOLERANCE = 0.30
SETS = {  # "tour": the README's own two logs (seeds 3 and 5)
    "tour": [("thrust_gain=0.85", 3)],
    "first": [("thrust_gain=0.85", 21), ("thrust_speed_loss=3.0", 31), ("full_thrust=0.8", 41),
              ("surge_resistance=1.4", 51), ("thrust_decay=0.04", 61), ("thruster_gain_left=0.85", 71)],
    # fixed before the rival's refit on each trial (separate.py) was run on any set: other seeds and values
    "second": [("thrust_gain=0.88", 121), ("thrust_speed_loss=2.6", 131), ("full_thrust=0.75", 141),
               ("surge_resistance=1.5", 151), ("thrust_decay=0.05", 161), ("thruster_gain_right=0.85", 171)],
    # fixed before a trial was proposed only where it parts the readings (separate.settling) and before a
    # second round of proposals was taken
    "third": [("thrust_gain=0.83", 221), ("thrust_speed_loss=3.4", 231), ("full_thrust=0.78", 241),
              ("surge_resistance=1.35", 251), ("thrust_decay=0.035", 261), ("thruster_gain_left=0.88", 271)],
    # fixed once the trials' windows started from each reading's own lag state and its commands
    # carried from the trial's start, refits past the cap while none settles, hull and thruster effects only
    "fourth": [("thrust_gain=0.86", 321), ("thrust_speed_loss=2.8", 331), ("full_thrust=0.82", 341),
               ("surge_resistance=1.45", 351), ("thrust_decay=0.045", 361), ("thruster_gain_right=0.82", 371)],
    # fixed once screening ranked candidates on windows its step did not fit and the fewest quantities
    # decided between rivals the blocks lean to neither way
    "fifth": [("thrust_gain=0.84", 421), ("thrust_speed_loss=3.2", 431), ("full_thrust=0.79", 441),
              ("surge_resistance=1.4", 451), ("thrust_decay=0.05", 461), ("thruster_gain_left=0.8", 471)],
    # fixed once screening took two Gauss-Newton steps, not one
    "sixth": [("thrust_gain=0.87", 521), ("thrust_speed_loss=3.0", 531), ("full_thrust=0.8", 541),
              ("surge_resistance=1.5", 551), ("thrust_decay=0.04", 561), ("thruster_gain_right=0.78", 571)],
}
# how each set took the advice: (rule, rounds) of _record_proposals
PROTOCOL = {"first": ("first", 1), "second": ("each", 1), "third": ("settling", 2), "fourth": ("settling", 2), "fifth": ("settling", 2), "sixth": ("settling", 2)}
# what the diagnosis did with each set: a set's figures stand for the code it ran on, and no set is rerun
METHODS = {"first": "the trial on which the two readings as fitted on the log part most (no refit); the first "
                    "unsettled rival's trial recorded",
           "second": "the rival refitted on each trial to the kept reading's free runs (the least discrepancy it can "
                     "reach); every unsettled rival's best trial recorded, each as an outing of its own",
           "third": "as the second, but a trial proposed only where it parts the two readings by at least what the "
                    "twin still misses, and the advice taken again where the recorded trials leave a new rival",
           "fourth": "as the third, with the trials' windows started from each reading's own thrust-lag state and "
                     "commands, refits continued while no trial settles, and only hull and thruster effects compared",
           "fifth": "as the fourth, with the search's screening ranked on windows its step did not fit and, of rivals "
                    "the blocks lean to neither way, the one with the fewest quantities kept",
           "sixth": "as the fifth, with each candidate screened by two Gauss-Newton steps, not one, on held-out "
                    "windows spread within each log, and a thrust scale kept for its fewer quantities checked for a "
                    "loss with speed"}


def _named(d) -> list[dict]:
    return [{"name": e["name"], "parameters": dict(e["parameters"]), "kind": e.get("kind", "dynamic"),
             "unsettled": [r["name"] for r in e.get("rivals", []) if not r["separable"]]} for e in d.effects]


def judge(truth: str, named: list[dict]) -> dict:
    """Exact: the truth named within TOLERANCE and nothing else; settled: exact with no rival left."""
    t = as_effect(truth)
    hit = next((e for e in named if e["name"] == t.name), None)
    close = hit is not None and all(abs(hit["parameters"][k] - v) <= TOLERANCE * abs(v)
                                    for k, v in t.flat().items() if k in hit["parameters"])
    others = [e["name"] for e in named if e is not hit]
    exact = bool(close and not others)
    return {"exact": exact, "settled": bool(exact and not hit["unsettled"]), "others": others}


def _record_proposals(d, truth: str, seed: int, prior, proposals: list[dict], rule: str) -> list:
    """The outings of the trials the diagnosis `d` proposes for its first kept effect with an unsettled
    rival (rule "first": its first rival's best trial; "each": every rival's best, or "settling": every
    rival's trial that separate.settling proposes), each trial once; appended to `proposals`."""
    kept = next((e for e in d.effects if any(e.get("separations", {}).values())), None)
    extra = []
    if kept is None:
        return extra
    for rival, seps in kept["separations"].items():
        sep = settling(seps) if rule == "settling" else (seps[0] if seps else None)
        if sep is None or any(p["trial"] == sep["trial"] for p in proposals):
            continue
        length_s = float(trial(sep["trial"]).t[-1]) + 0.1
        minutes = sep["minutes"] if sep["minutes"] is not None else 5.0
        segments = max(1, math.ceil(minutes * 60.0 / length_s))
        proposals.append({"kept": kept["name"], "rival": rival, **sep, "segments": segments,
                          "length_s": round(length_s, 1)})
        extra.append(generate(prior, effects=[truth], n_segments=segments, manoeuvres=[sep["trial"]],
                              seed=seed + 4 + 2 * len(proposals), segment_s=(length_s, length_s)).recording)
        if rule == "first":
            break
    return extra


def _pairs_left(proposals: list[dict], named: list[dict]) -> list[str]:
    """The rivals of `proposals` still not told from the effect they were proposed against: either of the
    two named with the other unsettled beside it."""
    unsettled = {(e["name"], x) for e in named for x in e["unsettled"]}
    return sorted({p["rival"] for p in proposals
                   if (p["kept"], p["rival"]) in unsettled or (p["rival"], p["kept"]) in unsettled})


def run_case(truth: str, seed: int, prior, rule: str, rounds: int) -> dict:
    started = time.time()
    logs = [generate(prior, effects=[truth], n_segments=n, seed=s).recording for n, s in ((4, seed), (2, seed + 2))]
    d = diagnose(logs, prior)
    row = {"truth": truth, "seed": seed, "before": _named(d), "proposals": [], "rounds": [],
           **{f"before_{k}": v for k, v in judge(truth, _named(d)).items()}}
    for _ in range(rounds):
        n_before = len(row["proposals"])
        extra = _record_proposals(d, truth, seed, prior, row["proposals"], rule)
        for p in row["proposals"][n_before:]:
            p["round"] = len(row["rounds"]) + 1
        if not extra:
            break
        logs = logs + extra
        d = diagnose(logs, prior)
        named = _named(d)
        row["rounds"].append({"named": named, **judge(truth, named),
                              "rivals_left": _pairs_left(row["proposals"][n_before:], named)})
    if row["rounds"]:
        row["after"] = row["rounds"][-1]["named"]
        row.update({f"after_{k}": v for k, v in judge(truth, row["after"]).items()})
    row["seconds"] = round(time.time() - started, 1)
    return row


def _text(named: list[dict]) -> str:
    if not named:
        return "nothing"
    return "; ".join(f"{e['name']} ({', '.join(f'{k} {v:.3g}' for k, v in e['parameters'].items())})"
                     + (f" or {', '.join(e['unsettled'])} (unsettled)" if e["unsettled"] else "") for e in named)


def _proposals(r: dict) -> str:
    if not r["proposals"]:
        return "-"
    return "; ".join(f"{'round ' + str(p['round']) + ': ' if p.get('round', 1) > 1 else ''}{p['trial']} "
                     f"({p['segments']} × {p['length_s']:g} s; {p['dof']} {p['ratio']:.1f}× what the "
                     f"twin still misses{'' if p.get('refitted') else ', not refitted'}) to tell {p['kept']} from "
                     f"{p['rival']}" for p in r["proposals"])


def _rounds(r: dict) -> list[dict]:
    """A row's rounds of recorded trials (a row without them: its one diagnosis after the trial)."""
    if "rounds" in r:
        return r["rounds"]
    return [] if "after" not in r else [{"named": r["after"], **judge(r["truth"], r["after"]),
                                         "rivals_left": _pairs_left(r["proposals"], r["after"])}]


def _set_summary(name: str, rows: list[dict]) -> str:
    proposed = [r for r in rows if _rounds(r)]
    first = [_rounds(r)[0] for r in proposed]
    last = [_rounds(r)[-1] for r in proposed]
    targeted = sum(len({p["rival"] for p in r["proposals"] if p.get("round", 1) == 1}) for r in proposed)
    told = targeted - sum(len(f["rivals_left"]) for f in first)
    text = (f"Set {name} ({METHODS[name]}): of {len(rows)} truths, the two outings named "
            f"{sum(r['before_exact'] for r in rows)} exactly and {sum(r['before_settled'] for r in rows)} with no rival "
            f"left; in {len(proposed)} a trial was proposed and recorded. The rivals the first trials were proposed for "
            f"were told apart in {told} of {targeted}; settled after them (the truth named exactly, no rival left): "
            f"{sum(f['settled'] for f in first)} of {len(proposed)}")
    if any(len(_rounds(r)) > 1 for r in proposed):
        text += f"; after the advice taken again: {sum(x['settled'] for x in last)} of {len(proposed)}"
    wrong = sum(not x["exact"] for x in last)
    return text + f"; named otherwise or beside another effect at the end: {wrong}."


def page(sets: dict) -> ResultPage:
    tables = []
    for name, got in sets.items():
        rows = got["rows"]
        tables.append(ResultTable(
            f"Set {name} (commit {got['commit']}): the two outings' diagnosis, the trials it proposed, and the "
            "diagnosis with them recorded",
            ["truth", "seed", "two outings: named", "exact", "proposed trials (outings; the twins' difference)",
             "with the trials: named", "exact", "settled", "s"],
            [[r["truth"], r["seed"], _text(r["before"]), "yes" if r["before_exact"] else "no", _proposals(r),
              " → ".join(_text(x["named"]) for x in _rounds(r)) or "-",
              ("yes" if _rounds(r)[-1]["exact"] else "no") if _rounds(r) else "-",
              ("yes" if _rounds(r)[-1]["settled"] else "no") if _rounds(r) else "-", r["seconds"]] for r in rows]))
    return ResultPage(
        name="separating_trials", title="Recording the trials a diagnosis proposes",
        ran="python scripts/separating_trials.py --set SET",
        data="`twin dataset` outings of the shipped BlueBoat with one effect concealed (4 and 2 segments of the "
             "default manoeuvres at the truth's seed and the seed + 2; each proposed trial's outing at the seed + 4, "
             "+ 6, ...), diagnosed from the shipped, untuned twin",
        summary=" ".join(_set_summary(name, got["rows"]) for name, got in sets.items()),
        tables=tables,
        notes=["Exact: the truth named with each value within 30 % and nothing else named; settled: exact, and no "
               "rival that the recording cannot tell from it.",
               "A proposal is a trial on which the kept effect's twin and an unsettled rival's part most against what "
               "the twin still misses (twin/diagnose/separate.py), with the minutes of it that would give ten 30-s "
               "blocks in which they differ; each set was fixed before it was run and run once, at the commit shown.",
               "The truths are the library's own forms: the study checks the proposal, not the diagnosis's reach "
               "beyond its forms."],
        raw={"sets": sets})


def _saved(raw: Path) -> dict:
    """The sets run so far ({} without a file); a file of one set's rows (one proposal per row) is read
    as that set with its proposal as the list of one."""
    if not raw.is_file():
        return {}
    saved = json.loads(raw.read_text())
    if "sets" in saved:
        return saved["sets"]
    rows = [{**{k: v for k, v in r.items() if k != "proposal"},
             "proposals": [] if r.get("proposal") is None else [r["proposal"]]} for r in saved["rows"]]
    return {saved["set"]: {"commit": saved["commit"], "rows": rows}}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", default="first", choices=sorted(SETS))
    ap.add_argument("--page-only", action="store_true", help="rewrite the page from its raw figures")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results")
    args = ap.parse_args()
    raw = args.out / "data" / "separating_trials.json"
    sets = _saved(raw)
    if not args.page_only:
        prior, rows = vessel_mod.load("blueboat"), []
        sets[args.set] = {"commit": checkout_commit(ROOT), "rows": rows}
        for truth, seed in SETS[args.set]:
            rows.append(run_case(truth, seed, prior, *PROTOCOL[args.set]))
            r = rows[-1]
            print(f"{truth} seed {seed}: before {_text(r['before'])}; proposals {_proposals(r)}; "
                  f"after {_text(r['after']) if 'after' in r else '-'} ({r['seconds']} s)", flush=True)
    print(f"wrote {page(dict(sorted(sets.items(), key=lambda kv: list(SETS).index(kv[0])))).write(args.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
