"""Kept data and atomic writes, the cases a fresh-venv trial found: a dataset's truth over the JSON size
guard, a fleet log named like the fleet summary, a user's fleet.md, a file that appears at an output path
during a run, a recording given as SITL's parameter file, and SIGTERM during a write."""
from __future__ import annotations

import json
import random
import signal
import subprocess
import sys
import textwrap
from pathlib import Path
from types import SimpleNamespace

import pytest

import twin.files as files
import twin_command
from twin.errors import TwinError

ROOT = Path(__file__).resolve().parent.parent
RECORDING_CSV = "t,x,y,psi,u,v,r,pwm_left,pwm_right\n" + "".join(
    f"{k * 0.1:.1f},{k * 0.1:.2f},0,0,1,0,0,1600,1600\n" for k in range(50))


def twin(*args, cwd=None):
    return twin_command.twin(*args, cwd=cwd)


def no_temporaries(folder: Path) -> bool:
    return not list(folder.glob(".*.tmp"))


# ---------------------------------------------------------------- 1. a truth of any size

def big_truth(path: Path, logs=("big.csv",), size: int = 60_000_000) -> None:
    """A dataset's truth as `twin dataset` writes it (its logs first, its states last), made `size` bytes
    long by a hole in the file (sparse: the disk holds a few kB)."""
    head = {"logs": list(logs), "vessel": {"name": "blueboat", "mjcf": "package:blueboat.xml"},
            "effects": [], "noise": {"gnss_m": 0.0}, "seed": 0,
            "segments": [{"manoeuvre": "rc", "t0_s": 0.0, "t1_s": 10.0}]}
    text = json.dumps(head, indent=2)[:-2] + ',\n  "states": "'
    with open(path, "wb") as f:
        f.write(text.encode())
        f.seek(size - 2)
        f.write(b'"}')


def test_a_truth_over_the_size_guard_is_still_a_truth_and_its_logs_are_read_from_its_head(tmp_path):
    truth = tmp_path / "big.truth.json"
    big_truth(truth)
    assert truth.stat().st_size > 50_000_000
    assert files.kept_data(truth) == "dataset's truth"
    assert files.truth_logs(truth) == [tmp_path / "big.csv"]
    (tmp_path / "big.csv").write_text(RECORDING_CSV)
    assert files.truths_of(tmp_path / "big.csv") == [truth]
    named = tmp_path / "day.json"  # a truth named as the user likes (`twin dataset --truth`)
    big_truth(named, logs=("big.csv",))
    assert files.kept_data(named) == "dataset's truth"


def test_a_truth_named_in_capitals_describes_its_log(tmp_path):
    big_truth(tmp_path / "A.JSON", logs=("a.csv",), size=4096)
    (tmp_path / "a.csv").write_text(RECORDING_CSV)
    assert files.truths_of(tmp_path / "a.csv") == [tmp_path / "A.JSON"]
    with pytest.raises(TwinError, match="described by a dataset's truth"):
        files.check_new([tmp_path / "a.csv"], True, "--out", writes=files.RUNS)


def test_the_commands_keep_a_big_truth_and_the_log_it_describes(tmp_path):
    folder = tmp_path / "big"
    folder.mkdir()
    truth, log = folder / "big.truth.json", folder / "big.csv"
    big_truth(truth)
    log.write_text(RECORDING_CSV)
    before = log.read_bytes(), truth.stat().st_size
    done = twin("simulate", "--vessel", "blueboat", "--duration", "2", "--out", log, "--force")
    assert done.returncode == 2 and "described by a dataset's truth" in done.stderr, done.stderr
    done = twin("params", "--vessel", "blueboat", "--write-model", truth, "--force")
    assert done.returncode == 2 and "dataset's truth" in done.stderr, done.stderr
    done = twin("evaluate", log, "--vessel", "blueboat", "--json", truth)
    assert done.returncode == 2 and "dataset's truth" in done.stderr, done.stderr
    assert (log.read_bytes(), truth.stat().st_size) == before and no_temporaries(folder)


def test_a_json_head_is_read_as_the_whole_parse_reads_it(tmp_path, monkeypatch):
    """json_head, read in pieces as small as a byte, gives the members json.loads gives, and only whole
    values from a file cut short or read to a limit."""
    rng = random.Random(3)

    def value(depth=0):
        c = rng.random()
        if depth > 3 or c < 0.3:
            return rng.choice([1, -2.5e-3, 12345678901234, True, False, None, 'a\u00e9\u4e2d"x', 0.1, 1e300])
        if c < 0.6:
            return [value(depth + 1) for _ in range(rng.randint(0, 4))]
        return {f"k{i}\u00e9": value(depth + 1) for i in range(rng.randint(0, 4))}

    path = tmp_path / "x.json"
    for chunk in (1, 3, 64):
        monkeypatch.setattr(files, "JSON_READ_CHUNK", chunk)
        for limit in (10**9, 40):
            monkeypatch.setattr(files, "JSON_HEAD_LIMIT", limit)
            for _ in range(60):
                obj = {f"m{i}": value() for i in range(rng.randint(0, 5))}
                path.write_text(json.dumps(obj, indent=rng.choice([None, 1]), ensure_ascii=rng.random() < 0.5),
                                encoding="utf-8")
                got = files.json_head(path)
                whole = {k: v for k, v in got.items() if v is not files._PENDING}
                assert (got == obj) if limit > 1e6 else all(obj[k] == v for k, v in whole.items())
                data = path.read_bytes()
                path.write_bytes(data[:rng.randint(0, len(data))])
                assert set(files.json_head(path)) <= set(obj)


# ---------------------------------------------------------------- 2, 3. fleet

def fake_diagnose(recordings, vessel, **options):
    return SimpleNamespace(effects=[], to_dict=lambda: {"vessel": vessel.name, "effects": []})


@pytest.fixture(scope="module")
def fleet_logs(tmp_path_factory):
    from twin.formats import write_recording
    from twin.synth.dataset import PROFILES, generate
    from twin.vessel import load

    d = tmp_path_factory.mktemp("fleetlogs")
    ds = generate(load("yellowfish"), n_segments=1, manoeuvres=["rc"], seed=0, noise=PROFILES["none"],
                  segment_s=(20.0, 20.0))
    write_recording(ds.recording, d / "fleet.mcap")
    write_recording(ds.recording, d / "a.mcap")
    return d


def test_a_log_named_fleet_has_a_report_of_its_own_beside_the_summary(fleet_logs, tmp_path):
    from twin.scale import fleet

    assert fleet._report_names([SimpleNamespace(path=Path(p)) for p in
                                ("d/fleet.csv", "e/Fleet.mcap", "f/a.csv", "g/a.failed.csv", "h/fleet-2.csv")]) == \
        ["fleet-3", "Fleet-4", "a", "a.failed-2", "fleet-2"]
    logs = [fleet.Log(fleet_logs / "fleet.mcap", "yellowfish"), fleet.Log(fleet_logs / "a.mcap", "yellowfish")]
    done = fleet.diagnose_fleet(logs, tmp_path / "out", diagnose=fake_diagnose)
    assert sorted(p.name for p in done.reports.values()) == ["a.json", "fleet-2.json"]
    summary = json.loads((tmp_path / "out" / "fleet.json").read_text())
    assert summary["logs"] == 2 and summary["diagnosed"] == 2
    assert fleet.is_fleet_report(tmp_path / "out" / "fleet-2.json")
    assert json.loads((tmp_path / "out" / "fleet-2.json").read_text())["log"].endswith("fleet.mcap")


def test_fleet_keeps_a_users_fleet_md_without_force_before_any_work(fleet_logs, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "fleet.md").write_text("my notes\n")
    done = twin("fleet", fleet_logs / "a.mcap", "--vessel", "yellowfish", "--out", out)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "fleet.md' exists: it is kept (--force replaces it)" in done.stderr
    assert (out / "fleet.md").read_text() == "my notes\n" and sorted(p.name for p in out.iterdir()) == ["fleet.md"]


# ---------------------------------------------------------------- 4. a file that appears during the run

def test_a_file_that_appears_during_a_write_is_kept(tmp_path):
    out = tmp_path / "same.csv"
    with files.output_scope():
        files.check_new([out], False, "--out")

        def fill(fh):
            fh.write(b"the run's\n")
            out.write_text("someone's\n")  # appears while the run writes

        with pytest.raises(TwinError, match=r"^--out '.*same.csv' appeared during the run and was kept"):
            files.write_stream_atomic(out, fill)
    assert out.read_text() == "someone's\n" and no_temporaries(tmp_path)
    # a path that was there when checked (--force) is replaced, and outside a command nothing is held
    with files.output_scope():
        files.check_new([out], True, "--out")
        files.write_text_atomic(out, "the run's\n")
    assert out.read_text() == "the run's\n"
    files.check_new([tmp_path / "new.csv"], False, "--out")
    (tmp_path / "new.csv").write_text("someone's\n")
    files.write_text_atomic(tmp_path / "new.csv", "a report\n")
    assert (tmp_path / "new.csv").read_text() == "a report\n"


def test_a_link_that_appears_during_a_write_is_kept_and_so_is_what_it_names(tmp_path):
    out, theirs = tmp_path / "same.csv", tmp_path / "theirs.csv"
    theirs.write_text("someone's\n")
    for started in (False, True):  # the link there before the write begins, and while it writes
        out.unlink(missing_ok=True)
        with files.output_scope():
            files.check_new([out], False, "--out")

            def fill(fh):
                fh.write(b"the run's\n")
                if started:
                    out.symlink_to(theirs)

            if not started:
                out.symlink_to(theirs)
            with pytest.raises(TwinError, match=r"^--out '.*same.csv' appeared during the run and was kept"):
                files.write_stream_atomic(out, fill)
        assert theirs.read_text() == "someone's\n" and out.is_symlink() and no_temporaries(tmp_path)


def test_a_file_that_appears_before_an_all_or_nothing_block_lands_is_kept_and_none_lands(tmp_path):
    first, second = tmp_path / "a.csv", tmp_path / "b.csv"
    with pytest.raises(TwinError, match="'.*b.csv' appeared during the run and was kept"):
        with files.all_or_nothing():
            files.check_new([first, second], False, "--out")
            files.write_text_atomic(first, "run a\n")
            files.write_text_atomic(second, "run b\n")
            second.write_text("someone's\n")
    assert not first.exists() and second.read_text() == "someone's\n" and no_temporaries(tmp_path)


def test_without_hard_links_the_name_is_claimed_and_a_file_there_kept(tmp_path, monkeypatch):
    def no_link(src, dst):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(files.os, "link", no_link)
    with files.all_or_nothing():
        files.check_new([tmp_path / "new.csv"], False, "--out")
        files.write_text_atomic(tmp_path / "new.csv", "run\n")
    assert (tmp_path / "new.csv").read_text() == "run\n"
    with files.output_scope():
        files.check_new([tmp_path / "x.csv"], False, "--out")
        with pytest.raises(TwinError, match="appeared during the run"):
            files.write_stream_atomic(tmp_path / "x.csv", lambda fh: (tmp_path / "x.csv").write_text("kept\n"))
    assert (tmp_path / "x.csv").read_text() == "kept\n" and no_temporaries(tmp_path)


@pytest.mark.parametrize("when", ["before its own check", "as it is written"])
def test_simulate_keeps_a_recording_that_appears_at_its_out_during_the_run(tmp_path, monkeypatch, when):
    from twin import outputs, simulation

    out = tmp_path / "same.csv"
    theirs = "t,north_m,east_m,psi\n0,0,0,0\n"  # another's table: "force=True or not" said to a CLI user before
    if when == "as it is written":
        original = outputs.write

        def write(runs, path, **kwargs):
            out.write_text(theirs)
            return original(runs, path, **kwargs)

        monkeypatch.setattr(outputs, "write", write)
    else:
        original = simulation._output_path

        def output_path(path):
            out.write_text(theirs)
            return original(path)

        monkeypatch.setattr(simulation, "_output_path", output_path)
    for force in ([], ["--force"]):
        out.unlink(missing_ok=True)
        done = twin("simulate", "--vessel", "blueboat", "--duration", "2", "--out", out, *force)
        assert done.returncode == 2, done.stderr
        assert done.stderr.startswith(f"error: --out '{out}' appeared during the run and was kept")
        assert done.stderr.count("\n") == 1 and "force=True" not in done.stderr
        assert out.read_text() == theirs and no_temporaries(tmp_path)


# ---------------------------------------------------------------- 5. sitl --write-params

@pytest.mark.parametrize("name", ["log.txt", "log.parm"])
def test_sitl_write_params_force_keeps_a_recording_under_a_parameter_files_name(tmp_path, name):
    log = tmp_path / name
    log.write_text(RECORDING_CSV)
    done = twin("sitl", "--vessel", "blueboat", "--write-params", log, "--force")
    assert done.returncode == 2 and "exists and is a recording: it is kept, --force or not" in done.stderr, done.stderr
    assert log.read_text() == RECORDING_CSV
    twin_file = tmp_path / "v.parm"  # a vessel file saved under a parameter file's name is data too
    done = twin("params", "--vessel", "blueboat", "--write-model", tmp_path / "v.json")
    assert done.returncode == 0, done.stderr
    twin_file.write_bytes((tmp_path / "v.json").read_bytes())
    done = twin("sitl", "--vessel", "blueboat", "--write-params", twin_file, "--force")
    assert done.returncode == 2 and "exists and is a vessel file" in done.stderr, done.stderr
    assert twin_file.read_bytes() == (tmp_path / "v.json").read_bytes()
    params = tmp_path / "boat.parm"
    params.write_text("OLD 1\n")
    done = twin("sitl", "--vessel", "blueboat", "--write-params", params, "--force")
    assert done.returncode == 0 and params.read_text() != "OLD 1\n", done.stderr


# ---------------------------------------------------------------- SIGTERM

@pytest.mark.parametrize("staged", [False, True])
def test_sigterm_during_a_write_leaves_no_temporary(tmp_path, staged):
    script = textwrap.dedent(f"""
        import os, signal, sys
        from twin import files
        def fill(fh):
            fh.write(b"half")
            os.kill(os.getpid(), signal.SIGTERM)
            fh.write(b"more")
        if {staged}:
            with files.all_or_nothing():
                files.write_text_atomic(sys.argv[1] + "/a.csv", "whole")
                os.kill(os.getpid(), signal.SIGTERM)
        else:
            files.write_stream_atomic(sys.argv[1] + "/a.csv", fill)
        print("not reached")
    """)
    done = subprocess.run([sys.executable, "-c", script, str(tmp_path)], capture_output=True, text=True,
                          cwd=ROOT, timeout=60)
    assert done.returncode == 128 + signal.SIGTERM and "not reached" not in done.stdout, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == []
