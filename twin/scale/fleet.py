"""`twin diagnose` over a fleet's logs: one diagnosis per log, a report per log, and a fleet
summary of which effects were found, how often, how large, per vessel and per day.

Each log is diagnosed alone against its vessel (a log's effects are its own: a current on
Tuesday is not Wednesday's). Logs go to the workers as bytes, read when their batch is
submitted, and reports come back as data, so a cluster needs no shared file system; the
driver writes every report atomically as it arrives. A log that cannot be diagnosed (no PWM,
too short, or an unexpected error in its diagnosis) is reported with its one-line reason and
the others go on: one bad log must not end a month's job. A run in which no log could be
diagnosed writes nothing (the reports a previous run left in the folder stay) and is an error; a
log that fails where a previous run diagnosed it keeps that report (its failure is written beside
it as <name>.failed.json).

Logs and their vessels: one vessel for all (`--vessel` / `--model`), or a manifest CSV with a
`recording` column and optional `vessel` (a shipped name or a vessel file) and `day`
(YYYY-MM-DD) columns, paths relative to the manifest's folder. A log's day, when the manifest
does not give it, is the date (UTC) of the log's own clock when that is a calendar time, else
a date in the file's name (2020-10-14, 20201014 or 14-Oct-2020, a year 2000-2099), else the date
of the file's modification time (a copy's is the day it was copied).
"""
from __future__ import annotations

import csv
import datetime as dt
import json
import os
import re
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..diagnose import doctor
from ..diagnose.report import as_json, write_html
from ..errors import TooShort, TwinError
from ..files import finite_json, json_default, kept_data, same_file, write_bytes_atomic, write_text_atomic
from ..formats import read_recording
from ..progress import Progress
from ..vessel import load
from .batches import Batch, Executor, LocalExecutor, plan

EPOCH_2000_S, EPOCH_2100_S = 946684800.0, 4102444800.0
MONTHS = ("jan", "feb", "mar", "apr", "may", "jun", "jul", "aug", "sep", "oct", "nov", "dec")
# a date written into a log's name by loggers and test series: ISO with or without dashes, or 14-Oct-2020;
# the digits must not run on (00000216 is a log counter, not a day)
_NAME_DATES = (
    (re.compile(r"(?<!\d)(20\d\d)-?(\d\d)-?(\d\d)(?!\d)"), lambda m: (m[1], m[2], m[3])),
    (re.compile(r"(?<!\d)(\d\d?)-(" + "|".join(MONTHS) + r")[a-z]*-(20\d\d)(?!\d)", re.IGNORECASE),
     lambda m: (m[3], str(MONTHS.index(m[2].lower()) + 1), m[1])),
)


@dataclass(frozen=True)
class Log:
    """A recording of the fleet, the vessel it was logged on (a shipped name or a vessel file)
    and its day (YYYY-MM-DD; "" to take it from the log)."""

    path: Path
    vessel: str
    day: str = ""


def read_manifest(path: Path, default_vessel: str | None = None) -> list[Log]:
    """The logs of a manifest CSV (module docstring)."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8-sig").splitlines()
        # line by line: a stray quote must not join the lines after it into one cell
        parsed = [next(csv.reader([text]), []) for text in lines]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise TwinError(f"manifest '{path}': cannot read ({exc})") from None
    header = [h.strip() for h in parsed[0]] if parsed else []
    rows = [dict(zip(header, cells)) for cells in parsed[1:] if cells]
    if not rows or "recording" not in rows[0]:
        raise TwinError(f"manifest '{path.name}': needs a header with a 'recording' column (and optional vessel, day)")
    for line, (text, cells) in enumerate(zip(lines[1:], parsed[1:]), start=2):
        if cells and len(cells) != len(header) and '"' in text:
            raise TwinError(f"manifest '{path.name}': line {line} holds a quote character, which leaves {len(cells)} "
                            f"cells under a header of {len(header)} columns")
    out = []
    for line, row in enumerate(rows, start=2):
        rec = (row.get("recording") or "").strip()
        vessel = (row.get("vessel") or "").strip() or default_vessel
        day = (row.get("day") or "").strip()
        if not rec:
            raise TwinError(f"manifest '{path.name}': line {line}: empty recording")
        if not vessel:
            raise TwinError(f"manifest '{path.name}': line {line}: no vessel (add a vessel column or give --vessel)")
        if day:
            _check_day(day, f"manifest '{path.name}': line {line}")
        model = Path(vessel)
        if vessel.endswith(".json") and not model.is_absolute():
            vessel = str(path.parent / model)
        out.append(Log(_resolved(path.parent, rec), vessel, day))
    return out


def _resolved(folder: Path, name: str) -> Path:
    p = Path(name)
    return p if p.is_absolute() else folder / p


def _check_day(day: str, where: str) -> None:
    try:
        dt.date.fromisoformat(day)
    except ValueError:
        raise TwinError(f"{where}: day '{day}' is not YYYY-MM-DD") from None


# ---------------------------------------------------------------- the work

@dataclass(frozen=True)
class _Job:
    vessels: dict  # the text that named a vessel -> Vessel
    options: dict  # keyword arguments of the diagnosis (window_s, library)
    html: bool
    diagnose: Callable | None  # None: twin.diagnose.doctor.diagnose


@dataclass(frozen=True)
class _Item:
    """One log as a worker gets it."""

    index: int
    name: str
    data: bytes
    vessel: str
    day: str
    file_day: str


REPORT_KEYS = frozenset({"index", "log", "vessel", "ok", "seconds"})  # every per-log report has them (_diagnosed)
HTML_MARK = b"<title>twin diagnose:"  # diagnose/report.py's page title
SUMMARY_FILES = ("fleet.json", "fleet.md")  # the fleet summary's files in --out, beside the per-log reports


def run_logs(job: _Job, b: Batch, items: list[_Item]) -> list[dict]:
    """The diagnoses of a batch's logs (the task a worker runs)."""
    return [_diagnosed(job, item) for item in items]


def _diagnosed(job: _Job, item: _Item) -> dict:
    started = time.perf_counter()
    out = {"index": item.index, "log": item.name, "vessel": item.vessel}
    with tempfile.TemporaryDirectory(prefix="twin-fleet-") as folder:
        path = Path(folder) / Path(item.name).name  # its own name: per-log calibrations go by it
        path.write_bytes(item.data)
        try:
            rec = read_recording(path)
            out["day"], out["day_from"] = _day(rec, item)
            out["measured_wind"] = bool(len(rec.wind))
            diagnose = job.diagnose or _default_diagnose()
            result = diagnose([rec], job.vessels[item.vessel], **job.options)
            out.update(ok=True, report=_plain(as_json(result) if isinstance(result, doctor.Diagnosis) else result.to_dict()), effects=_plain(list(result.effects)))
            if job.html:
                page = Path(folder) / "report.html"
                write_html(result, page)
                out["html"] = page.read_bytes()
        except Exception as exc:  # one log's failure, expected (TwinError) or not, must not end a month's job
            text = str(exc) if isinstance(exc, TwinError) else f"{type(exc).__name__}: {exc}".splitlines()[0]
            text = text.replace(str(path), Path(item.name).name)  # the worker's copy is the user's file
            out.update(ok=False, error=text, **({} if isinstance(exc, TwinError) else {"unexpected": True}),
                       **({"too_short": True} if isinstance(exc, TooShort) else {}))
            if "day" not in out:
                named = day_in_name(item.name)
                out["day"] = item.day or named or item.file_day
                out["day_from"] = "manifest" if item.day else ("file name" if named else "file time")
    out["seconds"] = round(time.perf_counter() - started, 3)
    return out


def _default_diagnose():
    return doctor.diagnose  # read when called: a stand-in set on the module is the one used


def _day(rec, item: _Item) -> tuple[str, str]:
    if item.day:
        return item.day, "manifest"
    if EPOCH_2000_S <= rec.origin_s <= EPOCH_2100_S:
        return dt.datetime.fromtimestamp(rec.origin_s, dt.timezone.utc).date().isoformat(), "log clock"
    named = day_in_name(item.name)
    if named:
        return named, "file name"
    return item.file_day, "file time"


def day_in_name(name: str) -> str | None:
    """The calendar day (YYYY-MM-DD) a log's file name carries, or None (no date, or not a real day).

    Args:
        name: the file name, e.g. turn_14-Oct-2020_14_29_49.csv or 2026-05-02_survey.bin.

    Returns:
        The ISO date, or None.
    """
    stem = Path(name).name
    for pattern, parts in _NAME_DATES:
        for m in pattern.finditer(stem):
            year, month, day = (int(x) for x in parts(m))
            try:
                return dt.date(year, month, day).isoformat()
            except ValueError:
                continue
    return None


def _plain(x):
    """JSON-ready copy (numpy numbers and arrays as plain values)."""
    return json.loads(json.dumps(x, allow_nan=True, default=json_default))


# ---------------------------------------------------------------- the fleet

@dataclass
class Fleet:
    """Every log's outcome (in the order given) and the summary."""

    results: list[dict]
    summary: dict
    reports: dict  # log index -> report file written


def diagnose_fleet(logs: list[Log], out: Path, *, window_s: float | None = None, library: list[str] | None = None,
                   html: bool = False, batch_size: int = 1, executor: Executor | None = None,
                   progress: Progress | None = None, diagnose: Callable | None = None,
                   wind: str | None = None) -> Fleet:
    """Diagnose every log (module docstring), writing OUT/<log name>.json (and .html) per log,
    OUT/fleet.json and OUT/fleet.md. `diagnose`: the per-log diagnosis, (recordings, vessel,
    **options) -> an object with .effects and .to_dict() (default twin.diagnose.doctor.diagnose);
    `wind` "measured": each log's measured wind a known input (`twin diagnose --wind-measured`)."""
    out = Path(out)
    if not logs:
        raise TwinError("no logs to diagnose")
    if out.exists() and not out.is_dir():
        raise TwinError(f"--out '{out}' is a file: give a folder")
    if not out.parent.is_dir():
        raise TwinError(f"--out '{out}': folder '{out.parent}' does not exist (create it first)")
    if not os.access(out if out.is_dir() else out.parent, os.W_OK):
        raise TwinError(f"--out '{out}': cannot write there (choose another folder)")
    for log in logs:
        if not log.path.is_file():
            raise TwinError(f"{log.path}: no such file")
    vessels = {name: load(name) for name in sorted({log.vessel for log in logs})}
    options = {k: v for k, v in (("window_s", window_s), ("library", library), ("wind", wind)) if v is not None}
    job = _Job(vessels, options, html, diagnose)
    names = _report_names(logs)
    _check_inputs_kept(out, names, html, [log.path for log in logs] + [Path(v) for v in vessels if v.endswith(".json")])
    created = not out.exists()
    out.mkdir(exist_ok=True)
    batches = plan(len(logs), batch_size, 0)
    results: list[dict | None] = [None] * len(logs)
    reports = {}
    # failure records wait until a log of this run is diagnosed: a run in which every log fails (a bad
    # option, a wrong vessel) must not replace the reports a previous run left in the folder
    waiting: list[dict] = []

    def items(b: Batch) -> list[_Item]:
        return [_item(i, logs[i]) for i in range(b.start, b.stop)]

    try:
        for _, batch_results in (executor or LocalExecutor()).run(run_logs, job, batches, items, progress):
            for r in batch_results:
                r["log"] = str(logs[r["index"]].path)
                results[r["index"]] = r
                waiting.append(r)
                if any(w.get("ok") for w in waiting) or reports:
                    for w in waiting:
                        reports[w["index"]] = _write_report(out, names[w["index"]], w)
                    waiting = []
    except BaseException:  # interrupted (Ctrl-C) or failed: a folder this run made and left empty goes again
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        raise
    if not reports:
        if created and not any(out.iterdir()):
            out.rmdir()
        raise _all_failed([r for r in results if r is not None], out)
    summary = {**summarise([r for r in results if r is not None]), "wind": wind or "none"}
    summary_json, summary_md = (out / name for name in SUMMARY_FILES)
    write_text_atomic(summary_json, json.dumps(finite_json(summary), indent=1, allow_nan=False) + "\n")
    write_text_atomic(summary_md, format_summary(summary) + "\n")
    return Fleet(results, summary, reports)


def _why(log: str, error: str) -> str:
    """A log's failure after its name: the reason less the name the reader's own message may begin with."""
    name = Path(log).name
    return error[len(name) + 2:] if error.startswith(f"{name}: ") else error


def _all_failed(results: list[dict], out: Path) -> Exception:
    """The error of a run in which no log could be diagnosed: bad input (TwinError) when some log's
    reason is one, else an unexpected error; either way nothing in `out` was replaced."""
    first = results[0]
    which = "the log could not" if len(results) == 1 else f"none of the {len(results)} logs could"
    text = (f"{which} be diagnosed ({'' if len(results) == 1 else 'first: '}{Path(first['log']).name}: "
            f"{_why(first['log'], first.get('error', ''))}); nothing written in {out}")
    if all(r.get("unexpected") for r in results):
        return RuntimeError(text)
    return TwinError(text)


def _item(i: int, log: Log) -> _Item:
    mtime = log.path.stat().st_mtime
    file_day = dt.datetime.fromtimestamp(mtime, dt.timezone.utc).date().isoformat()
    return _Item(i, log.path.name, log.path.read_bytes(), log.vessel, log.day, file_day)


def _check_inputs_kept(out: Path, names: list[str], html: bool, inputs: list[Path]) -> None:
    """Refuse, before anything is written, a report that would land on a file the run reads
    (a vessel file or a log kept in --out under a report's name) or on data a user keeps there
    (a twin `boat.json` beside `boat.csv`: files.kept_data)."""
    written = [out / name for name in SUMMARY_FILES]
    per_log = []
    for n in names:
        per_log += [out / f"{n}.json", out / f"{n}.failed.json"] + ([out / f"{n}.html"] if html else [])
    for path in written + per_log:
        for source in inputs:
            if same_file(path, source):
                raise TwinError(f"--out '{out}': the report '{path.name}' would replace the input '{source}' "
                                "(give another --out folder)")
        kind = kept_data(path)
        if kind:
            raise TwinError(f"--out '{out}': the report '{path.name}' would replace a {kind} kept there "
                            "(give another --out folder)")
    for path in per_log:  # a previous fleet's report is replaced; any other file of that name is the user's
        if path.exists() and not is_fleet_report(path):
            raise TwinError(f"--out '{out}': '{path.name}' is there and is not a report of `twin fleet`: a log's "
                            "report would replace it (give another --out folder)")


def is_fleet_report(path: Path) -> bool:
    """Whether `path` is a per-log report `twin fleet` writes: its JSON (a diagnosis or a failure record)
    or its HTML page."""
    try:
        if path.suffix.lower() == ".html":
            with open(path, "rb") as f:
                return HTML_MARK in f.read(4096)
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(data, dict) and REPORT_KEYS <= set(data)


def _report_files(name: str) -> set[str]:
    """The files a log's report named `name` may take in --out, case folded (a case-blind file system)."""
    return {f"{name}.json".casefold(), f"{name}.failed.json".casefold(), f"{name}.html".casefold()}


def _report_names(logs: list[Log]) -> list[str]:
    """A report name per log: its file's stem, numbered where two logs share one (run, run-2), the
    number passed over where another log's own stem is that name (run-2.csv beside two run.csv), and
    where the name's files would be another's: the summary's (a log fleet.csv: its report fleet-2.json,
    not the summary fleet.json) or another log's (a.failed.csv beside a.csv). Compared without case,
    as a case-blind file system (macOS, Windows) names files."""
    stems = [log.path.stem for log in logs]
    taken = {stem.casefold() for stem in stems}
    used = {name.casefold() for name in SUMMARY_FILES}
    out = []
    for stem in stems:
        name, n = stem, 1
        while _report_files(name) & used or (n > 1 and name.casefold() in taken):
            n += 1
            name = f"{stem}-{n}"
        taken.add(name.casefold())
        used |= _report_files(name)
        out.append(name)
    return out


def _write_report(out: Path, name: str, r: dict) -> Path:
    """OUT/<name>.json (and .html). A log that fails now, whose previous run in this folder was
    diagnosed, keeps that report: its failure goes to OUT/<name>.failed.json beside it."""
    page = r.pop("html", None)
    if page is not None:
        write_bytes_atomic(out / f"{name}.html", page)
    path = out / f"{name}.json"
    if not r.get("ok") and _diagnosed_before(path):
        path = out / f"{name}.failed.json"
    body = {k: v for k, v in r.items() if k != "effects"}
    write_text_atomic(path, json.dumps(body, indent=1, allow_nan=True, default=json_default) + "\n")
    return path


def _diagnosed_before(path: Path) -> bool:
    """Whether `path` holds a report of a log that was diagnosed (a run's good result)."""
    try:
        return bool(json.loads(path.read_text()).get("ok"))
    except (OSError, ValueError, AttributeError):
        return False


# ---------------------------------------------------------------- summary

def summarise(results: list[dict]) -> dict:
    """Which effects, how often, how large: over the fleet, per vessel and per day."""
    ok = [r for r in results if r.get("ok")]
    return {"logs": len(results), "diagnosed": len(ok),
            "effects": _effects(ok),
            "per_vessel": {v: _group(ok, results, "vessel", v) for v in sorted({r["vessel"] for r in results})},
            "per_day": {d: _group(ok, results, "day", d) for d in sorted({r.get("day", "") for r in results})},
            "failed": [{"log": r["log"], "error": r.get("error", ""), **({"too_short": True} if r.get("too_short") else {})}
                       for r in results if not r.get("ok")],
            "with_measured_wind": sum(bool(r.get("measured_wind")) for r in ok),
            "table": [{"log": r["log"], "vessel": r["vessel"], "day": r.get("day", ""), "ok": bool(r.get("ok")),
                       "effects": [e.get("name") for e in r.get("effects", [])], "seconds": r.get("seconds"),
                       **_verdicts(r)}
                      for r in results]}


def _verdicts(result: dict) -> dict:
    """A diagnosed log's verdicts beyond the effects named (report.answer): where the twin's form is
    off, and the effects the recording hints at but does not settle."""
    answer = (result.get("report") or {}).get("answer") or {}
    return {k: list(answer[k]) for k in ("form", "unsettled") if answer.get(k)}


def _group(ok: list[dict], results: list[dict], key: str, value: str) -> dict:
    mine = [r for r in ok if r.get(key) == value]
    out = {"logs": sum(r.get(key) == value for r in results), "diagnosed": len(mine), "effects": _effects(mine)}
    if key == "day":  # where the day was read, and for how many logs: a manifest, the log's clock, its name or time
        sources = [str(r.get("day_from", "")) for r in results if r.get(key) == value and r.get("day_from")]
        out["day_from"] = {s: sources.count(s) for s in DAY_SOURCES if s in sources}
    return out


def _effects(ok: list[dict]) -> dict:
    """Per effect name: logs where it was found, their share of the diagnosed logs, and each
    parameter's median and range over those logs."""
    found: dict[str, list[dict]] = {}
    for r in ok:
        for e in r.get("effects", []):
            found.setdefault(str(e.get("name")), []).append(e)
    out = {}
    for name in sorted(found, key=lambda n: (-len(found[n]), n)):
        items = found[name]
        params: dict[str, list[float]] = {}
        for e in items:
            for k, v in (e.get("parameters") or {}).items():
                if isinstance(v, (int, float)) and np.isfinite(v):
                    params.setdefault(k, []).append(float(v))
        gains = [float(g) for e in items if isinstance(g := e.get("held_out_gain"), (int, float)) and np.isfinite(g)]
        out[name] = {"logs": len(items), "share": len(items) / len(ok) if ok else 0.0,
                     "parameters": {k: {"median": float(np.median(v)), "min": min(v), "max": max(v)}
                                    for k, v in params.items()},
                     **({"held_out_gain_median": float(np.median(gains))} if gains else {})}
    return out


def _logs(n: int) -> str:
    return f"{n} log{'' if n == 1 else 's'}"


def format_summary(summary: dict) -> str:
    """The summary as Markdown: effects over the fleet, per vessel, per day, and the failures."""
    lines = [f"# Fleet diagnosis: {summary['diagnosed']} of {_logs(summary['logs'])} diagnosed", ""]
    with_wind = summary.get("with_measured_wind", 0)
    if summary.get("wind") == "measured":
        lines += [f"Each log diagnosed with its measured wind a known input (--wind-measured): {with_wind} of "
                  f"{summary['diagnosed']} diagnosed logs have one.", ""]
    elif with_wind:
        lines += [f"Diagnosed without the measured wind that {with_wind} of {summary['diagnosed']} diagnosed logs "
                  "have (--wind-measured takes it as a known input).", ""]
    lines += _effect_table(summary["effects"], summary["diagnosed"])
    for title, key in (("Per vessel", "per_vessel"), ("Per day", "per_day")):
        lines += ["", f"## {title}", ""]
        for name, group in summary[key].items():
            source = _day_source(group.get("day_from", {}), group["logs"]) if key == "per_day" else ""
            lines += [f"### {name or '(unknown)'}: {group['diagnosed']} of {_logs(group['logs'])} diagnosed{source}", ""]
            lines += _effect_table(group["effects"], group["diagnosed"]) + [""]
    verdicts = [row for row in summary.get("table", []) if row.get("form") or row.get("unsettled")]
    if verdicts:
        lines += ["## Beyond the effects named", ""]
        for row in verdicts:
            lines += [f"- {Path(row['log']).name}: " + "; ".join(
                [f"twin's form: {x}" for x in row.get("form", [])] + [f"unsettled: {x}" for x in row.get("unsettled", [])])]
        lines += [""]
    if summary["failed"]:
        lines += ["## Not diagnosed", ""] + [f"- {f['log']}: {_why(f['log'], f['error'])}" for f in summary["failed"]]
    return "\n".join(lines).rstrip()


# where a log's day was read, in the order it is looked for, and how fleet.md says it
DAY_SOURCES = ("manifest", "log clock", "file name", "file time")
_DAY_SOURCE_TEXT = {"manifest": "the manifest's day column", "log clock": "the log's own clock",
                    "file name": "a date in the file's name", "file time": "the file's modification time"}


def _day_source(day_from: dict, logs: int) -> str:
    """' (the day from ...)' for a day's heading: each source with its count of logs where several
    mix; a modification time said to be a copy's date, with how to set the day instead."""
    if not day_from:
        return ""
    parts = [_DAY_SOURCE_TEXT[s] + (f" ({n} of {logs} logs)" if len(day_from) > 1 else "") for s, n in day_from.items()]
    text = " (the day from " + ", ".join(parts)
    if "file time" in day_from:  # a copy's modification time, not the outing's
        text += ": neither the log's clock nor its name gave one, and a copy's time is the day it was copied; " \
                "a --manifest's day column sets it"
    return text + ")"


def _effect_table(effects: dict, diagnosed: int) -> list[str]:
    if not effects:
        return ["no effect found" if diagnosed else "no log diagnosed"]
    rows = ["| effect | logs | share | parameters: median [min, max] |", "| --- | ---: | ---: | --- |"]
    for name, e in effects.items():
        params = "; ".join(f"{k} {p['median']:.3g} [{p['min']:.3g}, {p['max']:.3g}]"
                           for k, p in e["parameters"].items())
        rows.append(f"| {name} | {e['logs']} | {100 * e['share']:.0f} % | {params} |")
    return rows
