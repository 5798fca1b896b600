"""Writing files so that a reader never sees half of one and a failed write loses nothing:
a temporary name in the same folder (same file system), then an atomic rename."""
from __future__ import annotations

import codecs
import json
import math
import os
import re
import signal
import stat
import tempfile
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Callable, Iterator

import numpy as np

from .errors import TwinError

# rerun application ids: runs recorded (a simulation, a SITL session) against a report's view of
# runs; the one is data a user keeps, the other a report may replace
RRD_RUN, RRD_VIEW = "twin-run", "twin-view"


# the open all_or_nothing blocks, innermost last: each holds its written temporaries and what to do
# once they are in place
_STAGES: list[dict] = []


# the paths an open command found free when it checked them (check_new), each with the option and the
# name it was given by: the write there makes a new file and replaces none, so that a file which
# appears at the path during the run (a copy, another run writing there) is kept (_put). Held while
# an output_scope is open (a command; all_or_nothing opens one), forgotten when the outermost ends.
_FRESH: dict[str, tuple[str, str]] = {}
_SCOPE_DEPTH = [0]


@contextmanager
def output_scope() -> Iterator[None]:
    """A command's span for its outputs: a path check_new finds free in it is written as a new file
    (never replacing one that appeared there since the check); outside any scope paths are not held."""
    _SCOPE_DEPTH[0] += 1
    try:
        yield
    finally:
        _SCOPE_DEPTH[0] -= 1
        if not _SCOPE_DEPTH[0]:
            _FRESH.clear()


def _key(path) -> str:
    """The path with its folder resolved but not its own name: a symbolic link that appears at a path
    found free is a file that appeared there (written through, it would replace what it names)."""
    path = os.path.abspath(str(path))
    return os.path.join(os.path.realpath(os.path.dirname(path)), os.path.basename(path))


def _appeared(path) -> TwinError:
    option, shown = _FRESH.get(_key(path), ("output", str(path)))
    return TwinError(f"{option} '{shown}' appeared during the run and was kept: this run's output was not written "
                     "(give another name, or run again)")


def _put(tmp, target) -> None:
    """Put the finished temporary `tmp` at `target`: over a file there (os.replace), or, where the
    command found `target` free (_FRESH), as a new file only, a file that appeared there since being
    kept (TwinError; the temporary removed)."""
    key = _key(target)
    if key not in _FRESH:
        os.replace(tmp, target)
        return
    try:
        try:
            os.link(tmp, target)  # fails, whatever the timing, where a file is there
        except FileExistsError:
            raise _appeared(target) from None
        except OSError:  # a file system without hard links (FAT, some network shares): claim the name first
            try:
                fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            except FileExistsError:
                raise _appeared(target) from None
            os.close(fd)
            try:
                os.replace(tmp, target)
            except OSError:
                Path(target).unlink(missing_ok=True)  # the empty file claimed above is this run's own
                raise
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    Path(tmp).unlink(missing_ok=True)
    _FRESH.pop(key, None)


class _Terminated(SystemExit):
    """SIGTERM while temporaries are open: raised, as Ctrl-C raises KeyboardInterrupt, so that they are
    removed on the way out; the process then ends with 128 + 15, as a shell reports the signal."""


def _on_sigterm(signum, frame):
    raise _Terminated(128 + signum)


_TERM = {"depth": 0, "previous": None}


def _hold_sigterm() -> None:
    """From now until _release_sigterm, SIGTERM removes the temporaries as Ctrl-C does; only where
    SIGTERM would kill the process outright (its default handler, in the main thread): a handler set
    by the command (SITL's, which writes the session) is left alone."""
    if _TERM["depth"] == 0:
        _TERM["previous"] = None
        if threading.current_thread() is threading.main_thread():
            try:
                if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
                    _TERM["previous"] = signal.signal(signal.SIGTERM, _on_sigterm)
            except (ValueError, OSError, AttributeError):
                pass
    _TERM["depth"] += 1


def _release_sigterm() -> None:
    _TERM["depth"] -= 1
    if _TERM["depth"] == 0 and _TERM["previous"] is not None:
        try:
            if signal.getsignal(signal.SIGTERM) is _on_sigterm:
                signal.signal(signal.SIGTERM, _TERM["previous"])
        except (ValueError, OSError):
            pass
        _TERM["previous"] = None


@contextmanager
def all_or_nothing(keep_on: tuple[type[BaseException], ...] = ()) -> Iterator[None]:
    """Every atomic write in the block (write_bytes_atomic, commit) lands only when the block ends:
    a command that writes several files and fails at the third leaves none of them written or
    replaced, and the files already there whole. An exception of a `keep_on` class (a command's
    chosen exit code) ends the block as a success does; any other removes the temporaries (SIGTERM
    too, once one is written). What was deferred with after_writes runs once the files are in place.
    The block is an output_scope: a path check_new found free is written as a new file only."""
    stage: dict = {"writes": [], "after": [], "term": False}
    with output_scope():
        _STAGES.append(stage)
        try:
            try:
                yield
            except keep_on:
                _STAGES.remove(stage)
                _land(stage)
                raise
            except BaseException:
                _STAGES.remove(stage)
                for tmp, _ in stage["writes"]:
                    Path(tmp).unlink(missing_ok=True)
                raise
            _STAGES.remove(stage)
            _land(stage)
        finally:
            if stage["term"]:
                _release_sigterm()


def _land(stage: dict) -> None:
    writes, landed = stage["writes"], []
    try:
        for tmp, target in writes:  # a file that appeared where one was to be new: none is written
            if _key(target) in _FRESH and (target.exists() or target.is_symlink()):
                raise _appeared(target)
        for tmp, target in writes:
            _put(tmp, target)
            landed.append(target)
    except OSError as exc:  # a rename in the file's own folder: it fails only with the folder gone
        done = f" ({', '.join(map(str, landed))} written before it)" if landed else ""
        raise TwinError(f"cannot write '{writes[len(landed)][1]}': {exc.strerror or exc}{done}") from None
    except TwinError as exc:
        done = f" ({', '.join(map(str, landed))} written before it)" if landed else ""
        raise TwinError(f"{exc}{done}") from None
    finally:  # an interrupt or a failed rename leaves no temporary behind
        for tmp, _ in writes[len(landed):]:
            Path(tmp).unlink(missing_ok=True)
    for fn in stage["after"]:
        fn()


def after_writes(fn: Callable[[], None]) -> None:
    """fn() once the open all_or_nothing block's files are in place (now, outside one): a line saying
    a file was written is said when it is."""
    if _STAGES:
        _STAGES[-1]["after"].append(fn)
    else:
        fn()


def commit(tmp, target) -> None:
    """Put the finished temporary `tmp` in place of `target` (os.replace; a new file only where the
    command found `target` free: _put), or hold it for the open all_or_nothing block."""
    if _STAGES:
        stage = _STAGES[-1]
        stage["writes"].append((Path(tmp), Path(target)))
        if not stage["term"]:  # a temporary waits for the block's end: SIGTERM meanwhile removes it
            stage["term"] = True
            _hold_sigterm()
    else:
        _put(tmp, target)


def read_only(path) -> bool:
    """Whether `path` is a file its owner has marked read-only (no write permission for anyone).
    By the mode bits, not os.access: a superuser may write anything, yet a file marked so was
    meant to be kept."""
    try:
        mode = Path(path).stat().st_mode
    except OSError:
        return False
    return stat.S_ISREG(mode) and not mode & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH)


def link_target(path) -> Path:
    """`path`, or where it points if it is a symbolic link (through a chain of links; a dangling link's
    target too, which a write creates)."""
    path = Path(path)
    return Path(os.path.realpath(path)) if path.is_symlink() else path


def written_path(path, make_folder: bool = False) -> Path:
    """The file a write to `path` replaces: a symbolic link's target (through a chain of links), so
    that the rename replaces the file the link names and the link stays. Its folder must exist
    (TwinError naming it) unless `make_folder`: an output into a mistyped folder is refused, not
    written into a new one nobody looks in; a writer filling its own folder tree makes its subfolders."""
    if _key(path) in _FRESH and (Path(path).exists() or Path(path).is_symlink()):
        raise _appeared(path)  # found free, and a file or a link is there now: it is kept
    target = link_target(path)
    if target.exists() and not target.is_file():  # a device, a pipe or a folder is not replaced by a file
        raise TwinError(f"'{path}' is not a regular file" + (f" ('{target}')" if target != Path(path) else "")
                        + ": give a file's name")
    folder = target.parent
    if folder.exists() and not folder.is_dir():
        raise TwinError(f"'{path}': '{folder}' is a file, not a folder")
    if not folder.is_dir():
        if not make_folder:
            raise TwinError(f"'{path}': folder '{folder}' does not exist (create it first)")
        folder.mkdir(parents=True, exist_ok=True)
    return target


def write_bytes_atomic(path, data: bytes, make_folder: bool = False) -> None:
    """`data` to `path` (through a link: written_path) atomically, with the usual permissions (umask).
    A read-only file there is refused (TwinError), not replaced: the rename would need only the
    folder's permission. A failed write (a full disk) names the file and leaves the old one whole."""
    write_stream_atomic(path, lambda fh: fh.write(data), make_folder)


def write_stream_atomic(path, fill: Callable[[IO[bytes]], object], make_folder: bool = False) -> None:
    """fill(file) writes the content to a temporary file beside `path`, which then replaces it as
    write_bytes_atomic does: for a content written piece by piece, never whole in memory (a long
    recording)."""
    if read_only(path):
        raise TwinError(f"'{path}' is read-only: it is kept (give another output name)")
    target = written_path(path, make_folder)
    _hold_sigterm()  # SIGTERM while the temporary is written removes it, as Ctrl-C does
    try:
        try:
            fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
        except OSError as exc:
            raise TwinError(f"cannot write '{path}': {exc.strerror or exc}") from None
        try:
            with os.fdopen(fd, "wb") as fh:
                fill(fh)
                fh.flush()
                # on disk before the rename: a crash leaves the old file or the new one, never an empty one
                os.fsync(fh.fileno())
            os.chmod(tmp, 0o666 & ~_umask())
            commit(tmp, target)
        except OSError as exc:
            Path(tmp).unlink(missing_ok=True)
            raise TwinError(f"cannot write '{path}': {exc.strerror or exc} (the file there, if any, is kept)") from None
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    finally:
        _release_sigterm()


def write_text_atomic(path, text: str, make_folder: bool = False) -> None:
    """`text` (UTF-8) to `path` atomically."""
    write_bytes_atomic(path, text.encode("utf-8"), make_folder)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def same_file(a, b) -> bool:
    """Whether two paths name one file: by the file itself where both exist (links, other spellings),
    else by their resolved paths."""
    a, b = Path(a), Path(b)
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
        return a.resolve() == b.resolve()
    except OSError:  # a path that cannot be resolved names no file a run could replace
        return False


def json_default(x):
    """json.dumps' default= for the project's results: numpy numbers and arrays as plain values,
    objects with to_dict() as that, anything else as its text."""
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    if hasattr(x, "to_dict"):
        return x.to_dict()
    return str(x)


def finite_json(x):
    """`x` (dicts, lists, numbers, numpy values, objects with to_dict()) as plain JSON values with
    every non-finite number as None: strict JSON has no inf or NaN, and a result may hold one (a
    time constant of a motion that never decays)."""
    if isinstance(x, dict):
        return {str(k) if not isinstance(k, str) else k: finite_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [finite_json(v) for v in x]
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, (str, int, bool)) or x is None:
        return x
    return finite_json(json_default(x))


RECORDING_HEADS = {"lat", "x", "pwm_left", "heading_deg", "prop_rps", "lat_deg", "north_m"}
# a recording places the boat; a table of inputs alone (simulate --inputs) holds no position or heading
POSITION_HEADS = {"lat", "x", "lat_deg", "north_m", "heading_deg", "psi"}
INPUT_HEADS = {"pwm_left", "pwm_right", "thrust_left", "thrust_right", "prop_rps", "rudder_deg"}


BAND = "Monte Carlo band"  # kept_data's name for `twin montecarlo`'s band (JSON, CSV or rerun)
INPUTS = "table of inputs"  # kept_data's name for a CSV of inputs alone (`twin simulate --inputs`)
RRD_BAND = "twin-montecarlo"  # the rerun application id of a band


# how far into a JSON file kept_data reads to say what it is: a bound on the time it takes (a report's
# tens of MB are not read to their end); a file's kind is told by its first members, which is where
# the writers put what marks it (a dataset's truth of any size: its states come last)
JSON_HEAD_LIMIT = 50_000_000
JSON_READ_CHUNK = 1 << 16
_WS = re.compile(r"[ \t\n\r]*")
_PENDING = object()  # json_head's value of a member whose key is read and its value not yet


def json_kind(keys) -> str | None:
    """What a JSON object with these top-level keys is as kept data (kept_data), or None."""
    keys = set(keys)
    return ("vessel file" if {"mjcf", "thrusters"} <= keys
            else "dataset's truth" if {"vessel", "effects", "segments"} <= keys
            else BAND if {"draws", "percentiles", "nominal", "band"} <= keys else None)


def json_head(path, enough: Callable[[dict], bool] | None = None, limit: int | None = None) -> dict:
    """The top-level members of the JSON object in `path`, in their order, read from its start only as
    far as needed: up to the member at which enough(members) is true (asked as each key is read, that
    key's value still unread: `_PENDING`), the object's end, a flaw in the text (what came before it is
    returned), or `limit` bytes (JSON_HEAD_LIMIT). Not an object: {}. OSError as the read raises it;
    RecursionError for a value nested beyond the parser's depth."""
    limit = JSON_HEAD_LIMIT if limit is None else limit
    decoder = json.JSONDecoder()
    members: dict = {}
    with open(path, "rb") as f:
        utf8 = codecs.getincrementaldecoder("utf-8")(errors="replace")
        state = {"text": "", "read": 0, "end": False}

        def more() -> bool:  # read on: a head, 16 times as much, then the rest (a value cut short is decoded again twice at most)
            if state["end"] or state["read"] >= limit:
                return False
            step = (JSON_READ_CHUNK if not state["read"] else 15 * state["read"] if state["read"] <= JSON_READ_CHUNK
                    else limit)
            chunk = f.read(min(step, limit - state["read"]))
            state["read"] += len(chunk)
            state["end"] = not chunk or state["read"] >= limit
            state["text"] += utf8.decode(chunk, final=state["end"])
            return bool(chunk)

        def at(i: int) -> int:  # past the white space from i, with a character there to read if the file has one
            while True:
                j = _WS.match(state["text"], i).end()
                if j < len(state["text"]) or not more():
                    return j

        def value(i: int, follow: str):  # (the value at i, where it ends), read on until what must follow it is
            # read too: a value cut by the read's end (a number 1e+300 read as 1) is read again whole
            while True:
                text = state["text"]
                try:
                    v, end = decoder.raw_decode(text, i)
                except ValueError:
                    v, end = _PENDING, None
                if end is not None:
                    j = _WS.match(text, end).end()
                    if j < len(text) and text[j] in follow:
                        return v, end
                if not more():
                    if end is None or state["read"] >= limit:  # not JSON, or cut by the limit: not read
                        raise ValueError("not JSON")
                    return v, end

        i = at(0)
        if state["text"][i:i + 1] == "\ufeff":  # a byte-order mark
            i = at(i + 1)
        if state["text"][i:i + 1] != "{":
            return {}
        i = at(i + 1)
        if state["text"][i:i + 1] == "}":
            return members
        try:
            while True:
                key, i = value(i, ":")
                if not isinstance(key, str):
                    return members
                i = at(i)
                if state["text"][i:i + 1] != ":":
                    return members
                members[key] = _PENDING
                if enough is not None and enough(members):
                    return members
                members[key], i = value(at(i + 1), ",}")
                i = at(i)
                sep = state["text"][i:i + 1]
                if sep != ",":
                    return members  # "}": the end; anything else: a flaw, what came before it stands
                i = at(i + 1)
        except ValueError:
            return members


def kept_data(path: Path, suffix: str | None = None) -> str | None:
    """What a file at `path` is when it is data a user keeps, a recording, runs recorded in rerun
    (a simulation, a SITL session), a vessel file, a dataset's truth, a Monte Carlo band or a table
    of inputs (by its content, whatever command wrote it), else None (a report, a view, another
    table, no file). A JSON file is told by its first members (json_head), whatever its size.
    `suffix`: read the file as one of that kind whatever its own name (kept_data_by_content)."""
    if not path.is_file():
        return None
    suffix = (suffix or path.suffix).lower()
    if suffix in (".tlog", ".bin", ".mcap"):
        return "recording"
    try:
        if suffix == ".rrd":
            # rerun writes the application id near the file's start, uncompressed
            with open(path, "rb") as f:
                start = f.read(4096)
            return ("rerun recording of runs" if RRD_RUN.encode() in start
                    else BAND if RRD_BAND.encode() in start else None)
        if suffix == ".csv":
            with open(path, encoding="utf-8", errors="replace") as f:
                head = [c.strip() for c in f.readline().split(",")]
            if head[:1] == ["t_s"] and "north_m_nominal" in head:
                return BAND
            if head[:1] != ["t"] or not RECORDING_HEADS & set(head):
                return None
            return "recording" if POSITION_HEADS & set(head) else INPUTS if INPUT_HEADS & set(head) else None
        if suffix == ".json":
            return json_kind(json_head(path, lambda members: json_kind(members) is not None))
    except (OSError, ValueError, RecursionError):  # a JSON nested beyond the parser's depth is no kept data
        return None
    return None


def kept_data_by_content(path: Path) -> str | None:
    """kept_data read as a JSON, a rerun file and a CSV whatever the file's name: for an output of
    a name of its own (a parameter file, .parm), where a vessel file or a truth saved under another
    name is still someone's data."""
    for suffix in (".json", ".rrd", ".csv"):
        kind = kept_data(path, suffix)
        if kind:
            return kind
    return None


KEPT = "it is kept, {force} or not (give another name, or remove it first)"
RUNS = ("recording", "rerun recording of runs")  # the kinds of kept data a run's or a recording's outputs are


def check_new(paths, force: bool, option: str = "output", writes: tuple[str, ...] = (), truth=None,
              force_name: str = "--force") -> None:
    """Refuse, before any work is done, to write over a file that exists unless `force`: a
    recording or a vessel file there may be one the user made, and a run or a fit written over it
    would lose it. `writes`: the kinds of kept data (kept_data) this output is; data of another kind
    (a log where a band would go, a twin where a truth would) is kept even with `force`; a recording
    is not replaced under a dataset's truth that stays beside it (`truth`: the truth the run writes).
    A symbolic link is judged by the file it names, which the write replaces. `force_name`: how the
    caller's user says force (the command's --force, the API's force=True). In an output_scope (a
    command) a path found free is written as a new file only: one that appears there during the run is
    kept (a check again, as the run's own writer makes, names the first check's option)."""
    kept = KEPT.format(force=force_name)
    for p in paths:
        if p is None:
            continue
        if not Path(p).exists():
            if _SCOPE_DEPTH[0]:  # free now: the write makes a new file, and keeps one that appears meanwhile
                # (a dangling link is the user's way to name where the file goes: its target is held)
                _FRESH.setdefault(_key(link_target(p)), (option, str(p)))
            continue
        if _key(p) in _FRESH:  # found free by this command's first check, and a file is there now
            raise _appeared(p)
        kind = kept_data(Path(p))
        if kind and kind not in writes:
            raise TwinError(f"{option} '{p}' exists and is a {kind}: {kept}")
        if not force:
            raise TwinError(f"{option} '{p}' exists: it is kept ({force_name} replaces it)")
        if writes and kind is None and Path(p).suffix.lower() in (".csv", ".rrd"):
            # a table or a rerun file whose content is none of what this output writes is someone's
            # other data (notes, a manifest, a view): force replaces data with data of its kind only
            raise TwinError(f"{option} '{p}' exists and is not a {' or '.join(writes)} in twin's own layout (a log "
                            f"in another's, a table, a view): {kept}")
        if kind != "recording":
            continue
        for described_by in truths_of(Path(p)):
            if truth is None or not same_file(Path(truth), described_by):
                # the recording would change under its truth, which would then describe another log
                raise TwinError(f"{option} '{p}' is described by a dataset's truth ('{described_by}') that would no "
                                "longer describe it: move or remove the truth first, or write elsewhere")


TRUTH_HEAD_BYTES = 4096  # a truth lists its logs first (synth.dataset.Dataset.truth): its folder is read this far


def truth_logs(truth: Path, data: dict | None = None) -> list[Path]:
    """The recordings a dataset's truth says it describes (its "logs", relative to its folder as the
    truth was written there, links followed; a truth written before truths named their logs: none)."""
    if data is None:  # the logs come first: a truth's states (tens of MB) are not read
        data = json_head(truth, lambda members: members.get("logs", _PENDING) is not _PENDING)
        data = {k: v for k, v in data.items() if v is not _PENDING}
    logs = data.get("logs") if isinstance(data, dict) else None
    folder = Path(os.path.realpath(truth)).parent
    return [folder / str(name) for name in logs if isinstance(name, str) and name] if isinstance(logs, list) else []


def truths_of(log: Path) -> list[Path]:
    """The dataset truths that describe the recording `log`: LOG.truth.json beside it, and any truth in
    its folder (the link's and the file's, for a link) that names it among its logs (`twin dataset
    --truth` names the truth as the user likes). A truth kept in another folder is not looked for."""
    target = link_target(log)
    beside = target.with_name(target.stem + ".truth.json")
    found = [beside] if kept_data(beside) == "dataset's truth" else []
    folders = list(dict.fromkeys((Path(log).parent, target.parent)))
    try:
        # a truth's name as the user gave it: A.JSON is a truth as a.json is
        candidates = sorted({p for folder in folders for p in folder.iterdir() if p.suffix.lower() == ".json"})
    except OSError:
        return found
    # a truth names a log relative to its folder: by itself ("q.csv") or after a folder (".../q.csv")
    names = {Path(log).name, target.name}
    marks = [m for n in names for m in (json.dumps(n), json.dumps("/" + n)[1:])]
    for path in candidates:
        if path == beside or not path.is_file():  # a pipe named .json would block the open
            continue
        try:
            with open(path, encoding="utf-8", errors="replace") as f:
                head = f.read(TRUTH_HEAD_BYTES)
            if '"logs"' not in head or not any(m in head for m in marks) or kept_data(path) != "dataset's truth":
                continue
            if any(same_file(named, target) for named in truth_logs(path) if named.exists()):
                found.append(path)
        except (OSError, ValueError, RecursionError):
            continue
    return found


def check_unique_columns(header: list[str], name: str) -> None:
    """TwinError unless every named column of a CSV header appears once: which of two a reader took
    would be a guess (a log's CSV and an inputs CSV alike)."""
    twice = sorted({h for h in header if h and header.count(h) > 1})
    if twice:
        raise TwinError(f"{name}: column{'s' if len(twice) > 1 else ''} {', '.join(twice)} "
                        f"{'appear' if len(twice) > 1 else 'appears'} more than once in the header")
