"""Synthetic identification datasets at scale: many randomised vessels (factors on the mass and
coefficients, effects with drawn values, optionally the identified covariance), each logged
through `twin dataset`'s manoeuvres and noisy sensors (`synth.dataset.generate`), written in
shards with one truth index.

Layout of the output folder:
  shard-00000/vessel-000000.mcap    one recording per vessel (format of the settings)
  shard-00000/truth.json            the shard's truths: per vessel the truth vessel, effects,
                                    noise, seed and noise-free states (what `twin dataset`
                                    writes as OUT.truth.json), and the shard's index entries
  index.json, index.csv             one row per vessel: file, shard, seed, factors, effects and
                                    the truth's coefficients (the labels a learner needs)

In a sea (`Settings.sea`, a physics.waves.Sea) every recording is made by the 6-DOF hull in its
own realisation of it, drawn from that vessel's seed (as `twin dataset --sea` draws it from its
seed); the index and the truth carry the sea each vessel saw.

A shard is one batch: its vessels are drawn from the batch's own seed, so a shard is the same
file whoever made it. Shards are written (recordings first, the truth last, each atomically) as
they come back; a shard whose truth file exists with the same settings, and whose files still
have the digests it lists, is complete, which is what `resume` relies on to finish a job that was
cut short. Workers return bytes and never
write, so a cluster needs no shared file system.
"""
from __future__ import annotations

import csv
import hashlib
import io
import json
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..effects import coefficients
from ..engine.mjcf import compile_vessel
from ..fit.uncertainty import check_drawable
from ..errors import TwinError
from ..files import write_bytes_atomic, write_text_atomic
from ..formats import write_recording
from ..progress import Progress, steps
from ..synth import manoeuvres as man
from ..synth.dataset import generate, noise_profile
from ..vessel import Vessel
from .batches import Batch, Executor, LocalExecutor, plan
from .draws import MASS, Variation

FORMATS = (".mcap", ".tlog", ".bin", ".csv")
DEFAULT_MANOEUVRES = ("rc", "forward_constant", "forward_varying", "zigzag", "circle_constant", "circle_varying")
INDEX_COLUMNS = ("vessel_index", "shard", "file", "seed", "mass_kg", "segments", "logged_s")


@dataclass(frozen=True)
class Settings:
    """What a sharded dataset is made of (all of it goes into the fingerprint)."""

    vessels: int
    per_shard: int = 16
    segments: int = 8
    manoeuvres: tuple[str, ...] = DEFAULT_MANOEUVRES
    noise: str = "realistic"
    fmt: str = ".mcap"
    seed: int = 0
    variation: Variation = field(default_factory=Variation)
    sea: object = None  # physics.waves.Sea: each vessel in its own realisation of it

    def __post_init__(self):
        if self.fmt not in FORMATS:
            raise TwinError(f"--format {self.fmt.lstrip('.')}: a dataset's recordings are "
                            f"{', '.join(f.lstrip('.') for f in FORMATS)}")
        if self.vessels < 1 or self.per_shard < 1 or self.segments < 1:
            raise TwinError("a dataset needs at least one vessel, one vessel per shard and one segment each")
        unknown = [m for m in self.manoeuvres if m not in man.KNOWN]
        if unknown or not self.manoeuvres:
            raise TwinError(f"unknown manoeuvre(s) {', '.join(unknown) or '(none given)'} "
                            f"(known: {', '.join(man.KNOWN)})")

    def to_dict(self) -> dict:
        return {"vessels": self.vessels, "per_shard": self.per_shard, "segments": self.segments,
                "manoeuvres": list(self.manoeuvres), "noise": self.noise, "format": self.fmt, "seed": self.seed,
                "variation": self.variation.to_dict(), **({} if self.sea is None else {"sea": self.sea.to_dict()})}


def fingerprint(vessel: Vessel, settings: Settings) -> str:
    """A digest of the base vessel and the settings: shards with the same one belong together."""
    data = {"vessel": vessel.to_dict() | {"mjcf": Path(vessel.mjcf).name}, "settings": settings.to_dict()}
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:16]


@dataclass(frozen=True)
class _Job:
    vessel: Vessel
    settings: Settings
    fingerprint: str
    mass_kg: float


@dataclass(frozen=True)
class ShardResult:
    """A shard as a worker returns it: (relative path, bytes) of its recordings, its truth file's
    content and its index entries."""

    files: tuple[tuple[str, bytes], ...]
    truth: dict
    entries: tuple[dict, ...]

    @property
    def nbytes(self) -> int:
        return sum(len(b) for _, b in self.files)


def shard_name(index: int) -> str:
    return f"shard-{index:05d}"


def run_shard(job: _Job, b: Batch, extra=None) -> ShardResult:
    """One shard's vessels drawn from its seed, each one's dataset generated and serialised."""
    s = job.settings
    rng = b.rng()
    drawn, _ = s.variation.draw(job.vessel, b.size, rng)
    seeds = rng.integers(0, 2 ** 63 - 1, size=b.size)
    labels = coefficients(job.vessel)
    files, truths, entries = [], [], []
    for k, (d, seed) in enumerate(zip(drawn, seeds)):
        i = b.start + k
        sea = None if s.sea is None else replace(s.sea, seed=int(seed))
        ds = generate(d.vessel, effects=d.effects, n_segments=s.segments, manoeuvres=list(s.manoeuvres),
                      seed=int(seed), noise=noise_profile(s.noise), sea=sea)
        name = f"{shard_name(b.index)}/vessel-{i:06d}{s.fmt}"
        files.append((name, _serialised(ds.recording, s.fmt)))
        entry = {"vessel_index": i, "shard": b.index, "file": name, "seed": int(seed),
                 "mass_kg": round(job.mass_kg * d.factors.get(MASS, 1.0), 6), "segments": len(ds.runs),
                 "logged_s": round(float(sum(r.t[-1] - r.t[0] for r in ds.runs)), 3),
                 "factors": d.factors, "effects": [e.text for e in d.effects],
                 "labels": _labels(labels, ds.truth_vessel), **({} if sea is None else {"sea": sea.to_dict()})}
        entries.append(entry)
        truths.append({"vessel_index": i, "file": name, **ds.truth()})
    # each file's digest: a shard is complete (resume) only where every file is still what was written
    digests = {name: _digest(data) for name, data in files}
    truth = {"fingerprint": job.fingerprint, "shard": b.index, "entries": entries, "truths": truths,
             "digests": digests}
    return ShardResult(tuple(files), truth, tuple(entries))


def _digest(data: bytes) -> str:
    return hashlib.blake2b(data, digest_size=16).hexdigest()


def _labels(quantities: dict, vessel: Vessel) -> dict:
    """Every coefficient identification can fit, as the truth has it."""
    out = {}
    for name, q in quantities.items():
        try:
            out[name] = float(q.get(vessel))
        except (ValueError, ZeroDivisionError):
            continue
    return out


def _serialised(recording, fmt: str) -> bytes:
    """The recording as the bytes of a file of format fmt (the writers want a path)."""
    with tempfile.TemporaryDirectory(prefix="twin-shard-") as folder:
        path = Path(folder) / f"recording{fmt}"
        write_recording(recording, path)
        return path.read_bytes()


@dataclass
class DatasetIndex:
    """What `generate_shards` wrote: the index and how many shards were made now or found."""

    folder: Path
    index: dict
    made: int
    reused: int
    bytes_written: int

    @property
    def entries(self) -> list[dict]:
        return self.index["entries"]


def generate_shards(vessel: Vessel, settings: Settings, folder: Path, *, executor: Executor | None = None,
                    resume: bool = False, progress: Progress | None = None) -> DatasetIndex:
    """The sharded dataset of `settings` in `folder` (module docstring); `resume`: keep the
    shards a previous run with the same settings completed there."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise TwinError(f"--out '{folder}' is a file: give a folder")
    if not folder.parent.is_dir():
        raise TwinError(f"--out '{folder}': folder '{folder.parent}' does not exist (create it first)")
    if folder.is_dir() and any(folder.iterdir()) and not resume:
        raise TwinError(f"--out '{folder}' is not empty: choose an empty folder, or --resume to finish a job there")
    if settings.variation.covariance and not vessel.uncertainty:
        raise TwinError(f"vessel '{vessel.name}' carries no identification uncertainty to draw from")
    if settings.variation.covariance:
        check_drawable(vessel)
    fp = fingerprint(vessel, settings)
    job = _Job(vessel, settings, fp, compile_vessel(vessel).geometry.rigid.mass_kg)
    batches = plan(settings.vessels, settings.per_shard, settings.seed)
    created = not folder.exists()  # made only once the settings have passed, and removed if left empty
    folder.mkdir(exist_ok=True)
    try:
        return _generate(folder, job, batches, resume, executor, progress)
    except BaseException:
        if created and not any(folder.iterdir()):  # a failed run leaves no empty folder behind
            folder.rmdir()
        raise


def _generate(folder: Path, job: "_Job", batches: list, resume: bool, executor: Executor | None,
              progress: Progress | None) -> DatasetIndex:
    """The shards of `batches` written into `folder` (made), reusing complete ones with --resume."""
    vessel, settings, fp = job.vessel, job.settings, job.fingerprint
    entries: dict[int, list[dict]] = {}
    for b in batches:
        found = _complete_shard(folder, b.index, fp) if resume else None
        if found is not None:
            entries[b.index] = found
    todo = [b for b in batches if b.index not in entries]
    written = 0
    say = steps(progress)
    say(f"{len(batches) - len(todo)} shards already complete", len(batches) - len(todo), len(batches))
    for b, result in (executor or LocalExecutor()).run(run_shard, job, todo, progress=progress):
        written += _write_shard(folder, result)
        entries[b.index] = list(result.entries)
    index = {"vessel": vessel.name, "fingerprint": fp, "settings": settings.to_dict(), "shards": len(batches),
             "entries": [e for i in sorted(entries) for e in entries[i]]}
    write_text_atomic(folder / "index.json", json.dumps(index, indent=1) + "\n")
    write_text_atomic(folder / "index.csv", index_csv(index["entries"]))
    return DatasetIndex(folder, index, len(todo), len(batches) - len(todo), written)


def _complete_shard(folder: Path, index: int, fp: str) -> list[dict] | None:
    """The index entries of a shard written by a job with fingerprint fp, or None. A shard
    written with other settings is an error: resuming over it would mix two datasets."""
    path = folder / shard_name(index) / "truth.json"
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError):
        return None  # a truth file is written atomically: unreadable means someone else's file
    if data.get("fingerprint") != fp:
        raise TwinError(f"{path}: made with other settings or another vessel (fingerprint {data.get('fingerprint')}, "
                        f"this job {fp}): use another folder")
    if not all((folder / e["file"]).is_file() for e in data.get("entries", [])):
        return None
    digests = data.get("digests", {})
    if any(_digest((folder / e["file"]).read_bytes()) != digests.get(e["file"]) for e in data["entries"]):
        return None  # a file cut short or changed since it was written: the shard is made again
    return list(data["entries"])


def _write_shard(folder: Path, result: ShardResult) -> int:
    for name, data in result.files:
        write_bytes_atomic(folder / name, data, make_folder=True)
    shard = shard_name(result.truth["shard"])
    write_text_atomic(folder / shard / "truth.json", json.dumps(result.truth, allow_nan=False) + "\n",
                      make_folder=True)
    return result.nbytes


def index_csv(entries: list[dict]) -> str:
    """One row per vessel: INDEX_COLUMNS, factor_<name>, effects (texts joined by ';') and
    label_<coefficient> columns."""
    factors = sorted({k for e in entries for k in e["factors"]})
    labels = sorted({k for e in entries for k in e["labels"]})
    head = [*INDEX_COLUMNS, *(f"factor_{k}" for k in factors), "effects", *(f"label_{k}" for k in labels)]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(head)
    for e in entries:
        w.writerow([*(e[c] for c in INDEX_COLUMNS), *(_num(e["factors"].get(k)) for k in factors),
                    ";".join(e["effects"]), *(_num(e["labels"].get(k)) for k in labels)])
    return buf.getvalue()


def _num(x) -> str:
    return "" if x is None or not np.isfinite(x) else f"{x:.9g}"
