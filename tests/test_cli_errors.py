"""Every command, given bad arguments or paths, ends in one line on stderr and exit 2: never a
traceback, never a file left behind."""
import json
import sys

import pytest
import twin_command

import twin.cli as cli

MISSING = "/nonexistent/folder"


def run(monkeypatch, capsys, args) -> tuple[int, str]:
    monkeypatch.setattr(sys, "argv", ["twin", *map(str, args)])
    with pytest.raises(SystemExit) as exit_info:
        cli.main()
    return exit_info.value.code, capsys.readouterr().err


@pytest.fixture(scope="module")
def paths(tmp_path_factory):
    root = tmp_path_factory.mktemp("bad")
    (root / "folder.csv").mkdir()
    (root / "not_a_log.csv").write_text("hello\n")
    (root / "vessel.json").write_text('{"name": "x"}')
    return root


def cases(root):
    v = ["--vessel", "yellowfish"]
    return [
        ("simulate", "--bogus"),
        ("simulate", *v, "--duration", "abc", "--out", root / "a.csv"),
        ("simulate", *v, "--out", root / "folder.csv"),
        ("simulate", *v, "--out", "/proc/x.rrd"),
        ("simulate", *v, "--out", f"{MISSING}/a.csv"),
        ("simulate", *v, "--out", root / "a.txt"),
        ("simulate", "--vessel", "titanic", "--out", root / "a.csv"),
        ("simulate", "--model", root / "vessel.json", "--out", root / "a.csv"),
        ("simulate", *v, "--out", root / "a.csv", "--origin", "95,10"),
        ("simulate", *v, "--out", root / "a.csv", "--current", "fast,10"),
        ("simulate", *v, "--out", root / "a.csv", "--inputs", root / "missing.csv"),
        ("crosscheck", *v, "--json", f"{MISSING}/c.json"),
        ("params", "--vessel", "titanic"),
        ("validate", *v, "--report", root / "r.pdf"),
        ("info",),
        ("info", root / "not_a_log.csv"),
        ("info", root / "missing.tlog"),
        ("convert", root / "not_a_log.csv", root / "b.mcap"),
        ("convert", root / "missing.csv", root / "b.xyz"),
        ("view", root / "missing.csv"),
        ("view", root / "not_a_log.csv", "--out", root / "folder.csv"),
        ("dataset", *v, "--out", root / "d.txt"),
        ("dataset", *v, "--out", root / "d.tlog", "--effect", "current=fast"),
        ("dataset", *v, "--out", root / "d.tlog", "--segments", "x"),
        ("identify", root / "missing.tlog", *v, "--out", root / "m.json"),
        ("identify", root / "not_a_log.csv", *v, "--out", root / "m.txt"),
        ("identify", root / "not_a_log.csv", *v, "--out", root / "m.json", "--beliefs", "a,b"),
        ("evaluate", *v, root / "missing.tlog"),
        ("evaluate", *v, root / "not_a_log.csv", "--json", root / "folder.csv"),
        ("iso", *v, "--dof", "sway"),
        ("iso", *v, "--amplitudes", "x"),
        ("dp", *v, "--run", "circle"),
        ("dp", *v, "--target", "abc"),
        ("dp", *v, "--target", "5,5"),
        ("identify", root / "not_a_log.csv", *v, "--out", root / "m.json", "--greybox", "--repeats", "0"),
        ("diagnose", root / "missing.csv", *v),
        ("diagnose", root / "not_a_log.csv", *v, "--report", root / "r.pdf"),
        ("sitl", *v, "--port", "99999"),
        ("sitl", *v, "--record", root / "s.txt"),
        ("sitl", *v, "--sea", "0.3,-3,45"),
        ("sitl", *v, "--sea", "0.3,3,45", "--seed", "-1"),
        ("nosuchcommand",),
    ]


def test_every_command_answers_bad_input_with_one_line(monkeypatch, capsys, paths):
    for args in cases(paths):
        code, err = run(monkeypatch, capsys, args)
        assert code == 2, (args, code, err)
        assert err.startswith("error:") and len(err.strip().splitlines()) == 1, (args, err)
        assert "Traceback" not in err
    leftovers = sorted(p.name for p in paths.iterdir() if p.name not in ("folder.csv", "not_a_log.csv",
                                                                          "vessel.json"))
    assert leftovers == [], leftovers


def test_a_bare_twin_prints_its_help_and_is_not_an_error(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["twin"])
    with pytest.raises(SystemExit) as exit_info:
        cli.main()
    assert exit_info.value.code == 0 and "Usage" in capsys.readouterr().out



def test_the_list_of_commands_reads_as_sentences_not_as_docstring_lines():
    # rich prints a help's line breaks as they stand: the docstrings' wrapping made the list ragged
    from twin.cli.app import app

    helps = {info.name or info.callback.__name__: info.help for info in app.registered_commands}
    assert len(helps) >= 18 and all(helps.values())
    assert all("\n" not in h.replace("\n\n", "") for h in helps.values()), [n for n, h in helps.items() if "\n" in h]
    assert "each log's compass calibration, a fit by simulation with the prior's beliefs" in helps["identify"]

# ---------------------------------------------------------------- refused before any work, nothing replaced

def tiny_log(path):
    """A 5-s recording in the generic CSV layout: GNSS, heading and PWM at 10 Hz."""
    rows = [f"{k / 10:.1f},63.4013904,{10.3149425 + k * 1e-6:.7f},220.98,58.86,1510,1512,1511,1511" for k in range(51)]
    path.write_text("t,lat,lon,alt,heading_deg,pwm_left,pwm_right,pwm_neutral_left,pwm_neutral_right\n"
                    + "\n".join(rows) + "\n")
    return path


@pytest.fixture
def kept(tmp_path):
    """Files a refused run must leave byte-identical: a recording, an inputs CSV, a JSON."""
    log = tiny_log(tmp_path / "log.csv")
    inputs = tmp_path / "inputs.csv"
    inputs.write_text("t,thrust_left,thrust_right\n0,1,1\n5,1,1\n")
    out = tmp_path / "same.json"
    out.write_text('{"kept": true}\n')
    return tmp_path, log, inputs, out


def refused(monkeypatch, capsys, args, files=()) -> str:
    """Run `twin ARGS`, assert exit 2 with one `error:` line and every file in `files` unchanged."""
    before = {p: p.read_bytes() for p in files}
    code, err = run(monkeypatch, capsys, args)
    assert code == 2, (args, code, err)
    assert err.startswith("error:") and len(err.strip().splitlines()) == 1 and "Traceback" not in err, (args, err)
    assert {p: p.read_bytes() for p in files} == before, args
    return err


def test_an_output_that_is_an_input_or_another_output_is_refused(monkeypatch, capsys, kept):
    root, log, inputs, same = kept
    v = ["--vessel", "yellowfish"]
    cases = [
        (("convert", log, log), "is the input"),
        (("convert", log, root / "." / "log.csv"), "is the input"),
        (("simulate", *v, "--inputs", inputs, "--out", inputs), "is the input"),
        (("simulate", *v, "--duration", "1", "--out", root / "a.csv", "--out", root / "a.csv"), "same file"),
        (("identify", log, *v, "--out", same, "--json", same), "same file"),
        (("diagnose", log, *v, "--json", same, "--write-model", same), "same file"),
        (("diagnose", log, *v, "--json", same, "--report", root / "r.html", "--write-model", root / "same.json"),
         "same file"),
        (("evaluate", log, *v, "--json", same, "--rrd", root / "e.rrd", "--stride", "0"), "--stride"),
        (("montecarlo", "--model", same, "--out", same), "is the input"),
        (("iso", "--model", same, "--json", same), "is the input"),
        (("dp", "--model", same, "--png", root / "same.png", "--json", same), "is the input"),
        (("dataset", *v, "--out", root / "d.csv", "--out", root / "d.csv"), "same file"),
    ]
    for args, message in cases:
        err = refused(monkeypatch, capsys, args, [log, inputs, same])
        assert message in err, (args, err)
    assert sorted(p.name for p in root.iterdir()) == ["inputs.csv", "log.csv", "same.json"]


def test_a_read_only_output_is_kept_even_for_a_user_who_could_replace_it(monkeypatch, capsys, kept):
    """A file marked read-only is refused as an output before any work, whoever runs the command
    (a superuser's os.access says yes; the rename would need only the folder's permission)."""
    import stat

    from twin.errors import TwinError
    from twin.files import write_text_atomic

    root, log, inputs, same = kept
    log.chmod(stat.S_IRUSR | stat.S_IRGRP | stat.S_IROTH)
    same.chmod(stat.S_IRUSR)
    try:
        for args in (("simulate", "--vessel", "yellowfish", "--duration", "1", "--out", log),
                     ("identify", inputs, "--vessel", "yellowfish", "--out", same)):
            assert "is read-only: it is kept" in refused(monkeypatch, capsys, args, [log, same])
        with pytest.raises(TwinError, match="read-only"):
            write_text_atomic(same, "replaced")
        assert same.read_text() == '{"kept": true}\n' and stat.S_IMODE(same.stat().st_mode) == stat.S_IRUSR
    finally:
        log.chmod(0o644)
        same.chmod(0o644)


def test_json_figures_write_a_non_finite_number_as_null():
    """Strict JSON has no inf: a result holding one (a yaw that never decays) is written, not refused."""
    import json

    import numpy as np

    from twin.cli.app import json_text

    text = json_text({"time_constant_s": float("inf"), "rows": [np.float64(np.nan), 1.5], "a": np.array([np.inf, 2.0])})
    assert json.loads(text) == {"time_constant_s": None, "rows": [None, 1.5], "a": [None, 2.0]}


@pytest.mark.parametrize("args, message", [
    (("simulate", "--duration", "inf"), "--duration must be a positive finite number"),
    (("simulate", "--duration", "0"), "--duration must be a positive finite number"),
    (("simulate", "--duration", "1e12"), "samples, more than this machine's memory"),
    (("simulate", "--sample-dt", "nan"), "--sample-dt must be a positive finite number"),
    (("simulate", "--seed", "-1"), "--seed must be a whole number ≥ 0"),
    (("crosscheck", "--duration", "inf"), "--duration must be a positive finite number"),
    (("crosscheck", "--duration", "1e12"), "samples, more than this machine's memory"),
    (("iso", "--duration", "1e12"), "samples, more than this machine's memory"),
    (("iso", "--duration", "-1"), "--duration must be a positive finite number"),
    (("dp", "--duration", "nan"), "--duration must be a positive finite number"),
    (("dp", "--duration", "1e12"), "samples, more than this machine's memory"),
    (("dp", "--rps", "-5"), "--rps applies to a propeller-and-rudder ship only"),
    (("dp", "--omega-surge", "-1"), "model-function frequencies must be positive and finite, got -1 rad/s"),
    (("dataset", "--effect", "thrust_gain=0.8", "--effect", "thrust_gain=0.9"),
     "effect thrust_gain given twice"),
    (("montecarlo", "--duration", "inf"), "--duration must be a positive finite number"),
    (("montecarlo", "--sample-dt", "nan"), "--sample-dt must be a positive finite number"),
    (("montecarlo", "--draws", "1"), "--draws must be a whole number of 2 or more"),
    (("montecarlo", "--level", "1.5"), "--level must lie between 0 and 1"),
    (("dataset", "--noise", "1e9,1e9"), "--noise 1e9,1e9: a GNSS noise above 100 m or a heading noise above 90°"),
    (("montecarlo", "--vessel", "blueboat", "--no-covariance", "--vary", "Xu=0.9..1.1", "--draws", "1000000000000",
      "--duration", "5"), "draws of 11 samples keep"),
    (("montecarlo", "--draws", "-5"), "--draws must be a whole number of 2 or more"),
    (("dataset", "--seed", "-1"), "--seed must be a whole number ≥ 0"),
    (("identify", "LOG", "--window", "0"), "--window must be a positive finite number"),
    (("identify", "LOG", "--window", "-1"), "--window must be a positive finite number"),
    (("identify", "LOG", "--window", "nan"), "--window must be a positive finite number"),
    (("identify", "LOG", "--max-evaluations", "0"), "--max-evaluations must be at least 1"),
    (("identify", "LOG", "--max-evaluations", "-5"), "--max-evaluations must be at least 1"),
    (("evaluate", "LOG", "--stride", "0"), "--stride must be a positive finite number"),
    (("evaluate", "LOG", "--stride", "-1"), "--stride must be a positive finite number"),
    (("evaluate", "LOG", "--stride", "nan"), "--stride must be a positive finite number"),
    (("evaluate", "LOG", "--stride", "inf"), "--stride must be a positive finite number"),
    (("evaluate", "LOG", "--band", "--seed", "-1"), "--seed must be a whole number ≥ 0"),
    (("diagnose", "LOG", "--window", "0"), "--window must be a positive finite number"),
    (("diagnose", "LOG", "--window", "-5"), "--window must be a positive finite number"),
    (("diagnose", "LOG", "--window", "nan"), "--window must be a positive finite number"),
    (("diagnose", "LOG", "--effects", "bogus"), "unknown effect(s) bogus"),
    (("diagnose", "LOG", "--effects", "current,thrust_gain=0.8"),
     "--effects takes effect names, got thrust_gain=0.8: an effect at given values is judged by `twin diagnose LOG "
     "--given thrust_gain=0.8`"),
    (("diagnose", "LOG", "--effects", " , "), "--effects is empty"),
    (("diagnose", "LOG", "--window", "0.05"), "--window must be at least 1 s"),
    (("identify", "LOG", "--window", "0.5"), "--window must be at least 1 s"),
    (("diagnose", "LOG", "--given", "current=0.1,90", "--given", "current=0.05,0"), "--given names current twice"),
    (("montecarlo", "--no-covariance", "--vary", "Xu=0.9..1.1", "--cpus-per-task", "0"),
     "--cpus-per-task must be at least 1"),
    (("dataset-shards", "--retries", "-5", "--out", "OUT"), "--retries must be at least 0"),
    (("convert", "LOG", "OUT.csv", "--grid-dt", "1e-9"), "samples, more than this machine's memory"),
    (("convert", "LOG", "OUT.csv", "--grid-dt", "0"), "--grid-dt must be a positive finite number"),
    (("convert", "LOG", "OUT.csv", "--out", "OUT2.csv"), "give the output once: as DST after SRC, or as --out"),
    (("convert", "LOG"), "give the output: twin convert SRC DST (or --out DST)"),
    (("dataset-shards", "--seed", "-1", "--out", "OUT"), "--seed must be a whole number ≥ 0"),
    (("montecarlo", "--no-covariance", "--vary", "Xu=0.9..1.1", "--sea", "1,1,30"), "steeper than breaking"),
    (("montecarlo", "--vessel", "cybership1", "--no-covariance", "--vary", "Xu=0.9..1.1", "--sea", "0.2,2.5,30"),
     "has no hull meshes"),
    (("dataset-shards", "--sea", "0.3,2.5", "--out", "OUT"), "sea expects HS,TP,DIR"),
    (("sitl", "--vessel", "esso_osaka"), "propeller-and-rudder ship"),
    (("params", "--model", "."), "is a folder, not a vessel file"),
    (("simulate", "--out", "."), "is a folder: give a file name"),
    (("simulate", "--out", "LOG/a.csv"), "is a file, not a folder"),
    (("simulate", "--wind", "500,40"), "wind's speed 500 m/s is beyond any a small vessel meets (at most 40 m/s)"),
    (("simulate", "--current", "20,90"), "current's speed 20 m/s is beyond any a small vessel meets"),
    (("identify", "LOG", "--vessel", "esso_osaka", "--params", "lag_s,mmg_Nr"),
     "lag_s: a PWM thruster's term, and vessel 'esso_osaka' has a propeller and rudder"),
])
def test_bad_numbers_are_refused_before_any_work(monkeypatch, capsys, kept, args, message):
    root, log, inputs, same = kept
    command, *rest = args
    rest = [str(log) if a == "LOG" else str(log) + a[3:] if a.startswith("LOG/") else str(root / a)
            if a.startswith("OUT") else a for a in rest]
    rest = [str(root) if a == "." else a for a in rest]
    outputs = {"simulate": ["--out", root / "a.csv"], "montecarlo": ["--out", root / "m.json"],
               "dataset": ["--out", root / "d.csv"], "identify": ["--out", root / "m.json"]}.get(command, [])
    vessel = [] if command == "convert" or {"--vessel", "--model"} & set(rest) else ["--vessel", "yellowfish"]
    err = refused(monkeypatch, capsys, [command, *rest, *vessel, *outputs], [log, inputs, same])
    assert message in err, err
    assert sorted(p.name for p in root.iterdir()) == ["inputs.csv", "log.csv", "same.json"]


def test_a_mission_without_sitl_says_at_once_what_it_waits_for(monkeypatch, capsys):
    import socket

    with socket.socket() as s:  # a port nothing listens on: bound, then released
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    code, err = run(monkeypatch, capsys, ["mission", "--home", "63.4366,10.3991", "--waypoints", "15,4",
                                          "--port", port, "--timeout", "0.5"])
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 2 and "Traceback" not in err
    assert lines[0].startswith(f"note: waiting up to 0.5 s for SITL's MAVLink console on tcp:127.0.0.1:{port}")
    assert lines[1] == f"error: no MAVLink console on tcp:127.0.0.1:{port} (is SITL running?)"


def test_fleet_refuses_bad_options_and_keeps_earlier_reports(monkeypatch, capsys, kept):
    root, log, inputs, same = kept
    out = root / "fleet"
    out.mkdir()
    earlier = {name: f'{{"earlier": "{name}"}}\n' for name in ("fleet.json", "fleet.md")}
    earlier["empty.json"] = '{"index": 0, "log": "empty.csv", "vessel": "yellowfish", "ok": true, "seconds": 1.0}\n'
    for name, text in earlier.items():
        (out / name).write_text(text)
    empty = root / "empty.csv"
    empty.write_text("")
    files = [out / name for name in earlier]
    base = ["fleet", empty, "--vessel", "yellowfish", "--out", out]
    assert "unknown effect(s) bogus" in refused(monkeypatch, capsys, [*base, "--effects", "bogus"], files)
    assert "--window must be" in refused(monkeypatch, capsys, [*base, "--window", "0"], files)
    assert "--window must be" in refused(monkeypatch, capsys, [*base, "--window", "nan"], files)
    assert "--effects is empty" in refused(monkeypatch, capsys, [*base, "--effects", ""], files)
    assert "--retries must be at least 0" in refused(monkeypatch, capsys, [*base, "--retries", "-1"], files)
    assert "given twice" in refused(monkeypatch, capsys, ["fleet", log, log, "--vessel", "yellowfish", "--out", out],
                                    files)
    nested = root / "by_day"
    (nested / "2020-10-14").mkdir(parents=True)
    assert "subfolders are not searched" in refused(monkeypatch, capsys, ["fleet", nested, "--vessel", "yellowfish",
                                                                          "--out", out], files)
    # an earlier run's summary is kept unless --force; every log failing (an empty file) is bad input, exit 2,
    # and replaces nothing even with --force
    assert "--out's summary" in refused(monkeypatch, capsys, base, files)
    assert "the log could not be diagnosed (" in refused(monkeypatch, capsys, [*base, "--force"], files)
    assert sorted(p.name for p in out.iterdir()) == sorted(earlier)
    assert "the log could not be diagnosed" in refused(monkeypatch, capsys, ["fleet", empty, "--vessel", "yellowfish",
                                                                            "--out", root / "new"])
    assert not (root / "new").exists()


def vessel_file(root, name: str, change) -> str:
    """The shipped blueboat's description with `change` applied to its dict, as a file."""
    import json

    import twin.vessel as vessel_mod

    data = json.loads((vessel_mod.MODEL_DIR / "blueboat.json").read_text())
    data["mjcf"] = "package:blueboat.xml"  # the shipped MJCF from any folder
    change(data)
    path = root / f"{name}.json"
    path.write_text(json.dumps(data))
    return str(path)


def _unc(**fields):
    block = {"coordinates": [{"name": "Xu", "log": True, "sign": -1.0}], "mean": [0.7], "covariance": [[0.01]]}
    return lambda d: d.update(uncertainty={**block, **fields})


@pytest.mark.parametrize("name, change, message", [
    ("pwm0", lambda d: d["thrusters"].update(pwm_scale_us=0.0), "pwm_scale_us must be positive"),
    ("pwminv", lambda d: d["thrusters"].update(pwm_min_us=1900.0, pwm_max_us=1100.0), "pwm_min_us must be below"),
    ("warp", lambda d: d["thrusters"].update(kind="warp"), "unknown thrusters.kind 'warp' (known: t200, direct"),
    ("coord5", _unc(coordinates=5), "uncertainty.coordinates must be a list"),
    ("coord1", _unc(coordinates=[1]), "uncertainty.coordinates[0] must be an object with 'name' and 'log'"),
    ("nolog", _unc(coordinates=[{"name": "Xu"}]), "uncertainty.coordinates[0] must be an object"),
    ("badname", _unc(coordinates=[{"name": 3, "log": False}]), "uncertainty.coordinates[0].name must be a string"),
    ("mean", _unc(mean=["abc"]), "uncertainty.mean[0] must be a number"),
    ("meanobj", _unc(mean={"a": 1}), "uncertainty.mean must be a list of numbers"),
    ("negvar", _unc(covariance=[[-1.0]]), "covariance[0][0] is a variance and must be ≥ 0"),
    ("noxu", lambda d: (_unc()(d), d["damping"].pop("Xu")), "the identification fitted Xu"),
])
def test_vessel_files_with_bad_fields_are_refused_at_load(monkeypatch, capsys, tmp_path, name, change, message):
    model = vessel_file(tmp_path, name, change)
    err = refused(monkeypatch, capsys, ["params", "--model", model])
    assert message in err, err


def test_one_recording_given_twice_is_refused(monkeypatch, capsys, kept):
    """Its windows would count twice, and a run "left out" of identify's choice would be a copy of one it
    fitted on (the README's scores on a new run would not be on a new run)."""
    root, log, _, same = kept
    copy = root / "copy.csv"
    copy.write_bytes(log.read_bytes())
    v = ["--vessel", "yellowfish"]
    for args, message in [(("identify", log, log, *v, "--out", root / "m.json"), "is given twice"),
                          (("identify", log, root / "." / "log.csv", *v, "--out", root / "m.json"), "is given twice"),
                          (("evaluate", log, copy, *v), "holds the same bytes as"),
                          (("diagnose", copy, log, *v), "holds the same bytes as"),
                          (("info", log, log), "is given twice"),
                          (("evaluate", root / "gone.csv", root / "gone.csv", *v), "gone.csv: no such file")]:
        err = refused(monkeypatch, capsys, args, [log, copy, same])
        assert message in err, (args, err)
    assert not (root / "m.json").exists()


def test_a_recording_cut_from_another_is_refused_beside_it(monkeypatch, capsys, kept):
    """Other bytes, the same stretch: a log cut from another (the Esso set's turn_cut_ file) would be
    fitted on and judged "left out" at once. info describes both and says so; the others refuse."""
    from twin.formats import read_recording
    from twin.recording import check_no_shared_stretch, shared_stretch_s

    root, log, _, same = kept
    cut = root / "cut.csv"
    cut.write_text("".join(log.read_text().splitlines(keepends=True)[:31]))  # the header and 3 s
    v = ["--vessel", "yellowfish"]
    for args in (("identify", log, cut, *v, "--out", root / "m.json"), ("evaluate", cut, log, *v),
                 ("diagnose", log, cut, *v)):
        err = refused(monkeypatch, capsys, args, [log, cut, same])
        assert "share 3 s of the same GNSS fixes" in err, (args, err)
    assert not (root / "m.json").exists()
    monkeypatch.setattr(sys, "argv", ["twin", "info", str(log), str(cut)])
    try:
        cli.main()
    except SystemExit as exc:
        assert not exc.code, exc.code
    assert "note: 'cut.csv' and 'log.csv' share 3 s" in capsys.readouterr().out
    whole, part = read_recording(log), read_recording(cut)
    assert shared_stretch_s(whole, part) == pytest.approx(2.9) and shared_stretch_s(part, whole) == pytest.approx(2.9)
    moved = log.read_text().replace("63.4013904", "63.4013905")  # another stretch of water: nothing shared
    (root / "other.csv").write_text(moved)
    assert shared_stretch_s(whole, read_recording(root / "other.csv")) == 0.0
    # two runs alike for their first 2 s of 5 (simulated runs from one start): not one cut from the other
    lines = log.read_text().splitlines(keepends=True)
    (root / "met.csv").write_text("".join(lines[:22] + [r.replace("63.4013904", "63.4013905") for r in lines[22:]]))
    met = read_recording(root / "met.csv")
    assert shared_stretch_s(whole, met) == pytest.approx(2.0)
    check_no_shared_stretch([whole, met])


def test_info_calibrates_every_log_it_can_and_refuses_another_vessels_log(monkeypatch, capsys, shared_dir,
                                                                           tmp_path):
    """A log that cannot be prepared hides no other log's calibration and is itself a finding (no
    calibration, why), not an error; a propeller-and-rudder ship's log is not calibrated as a PWM
    boat's (identify, evaluate and diagnose refuse that pairing too)."""
    good = shared_dir / "data" / "blueboat" / "fixed_00000225.csv"
    cut = tmp_path / "cut.csv"
    cut.write_text("".join(good.read_text().splitlines(keepends=True)[:5]))
    monkeypatch.setattr(sys, "argv", ["twin", "info", str(good), str(cut), "--vessel", "blueboat"])
    try:
        cli.main()
        code = 0
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    assert code in (0, None) and "error" not in err
    assert "calibration: cut.csv: no compass calibration (" in out
    assert "calibration: fixed_00000225.csv: compass offset +6.9°" in out
    code, err = run(monkeypatch, capsys, ["info", good, "--vessel", "esso_osaka"])
    assert code == 2 and "is driven by propeller speed and rudder angle; the recording holds PWM" in err


def test_an_output_that_is_a_link_is_written_through(monkeypatch, capsys, tmp_path):
    """A link given as an output stays a link: the file it names gets the run (the rename would otherwise
    replace the link with a file of its own and leave its target stale), for each kind of writer
    (files.write_bytes_atomic, MCAP's writer, rerun's)."""
    data = tmp_path / "data"
    data.mkdir()
    links = []
    earlier = {"csv": "t,x,y\n0,0,0\n", "mcap": "old", "rrd": "twin-run old"}  # runs: --force replaces them
    for ext in ("csv", "mcap", "rrd"):
        (data / f"run.{ext}").write_text(earlier[ext])
        link = tmp_path / f"link.{ext}"
        link.symlink_to(data / f"run.{ext}")
        links.append(link)
    p = twin_command.twin("simulate", "--vessel", "yellowfish", "--duration", "1", "--force",
                          *[a for link in links for a in ("--out", link)])
    assert p.returncode == 0, p.stderr
    for link in links:
        assert link.is_symlink() and link.resolve() == data / f"run.{link.suffix[1:]}"
        assert link.resolve().stat().st_size > 500
    assert (data / "run.csv").read_text().startswith("t,")
    assert sorted(p.name for p in data.iterdir()) == ["run.csv", "run.mcap", "run.rrd"]  # no temporary left


def test_a_failed_write_names_the_file_and_keeps_the_old_one(monkeypatch, capsys, tmp_path, full_disk):
    """A full disk while writing: one line naming the output, the file already there kept whole."""
    out = tmp_path / "run.csv"
    out.write_text("t,x,y\n0,0,0\n")
    full_disk(0.0)
    err = refused(monkeypatch, capsys, ["simulate", "--vessel", "yellowfish", "--duration", "1", "--out", out, "--force"],
                  [out])
    assert err == f"error: cannot write '{out}': No space left on device (the file there, if any, is kept)\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv"]


def test_the_api_refuses_an_output_into_a_missing_folder(tmp_path):
    """As the CLI does: an output into a mistyped folder is refused, not written into a new one."""
    from twin.api import simulate_run
    from twin.errors import TwinError

    sim = simulate_run("yellowfish", duration_s=1.0)
    with pytest.raises(TwinError, match=f"folder '{tmp_path / 'typo'}' does not exist"):
        sim.write(tmp_path / "typo" / "run.csv")
    assert list(tmp_path.iterdir()) == []


def test_options_that_do_not_apply_or_say_nothing_are_refused_before_any_work(monkeypatch, capsys, kept):
    """An option that would be ignored without a word, an empty list read as "all", a NaN noise level
    that would fail only while writing, a malformed effect: one line naming the option and the value."""
    root, log, inputs, same = kept
    v = ["--vessel", "yellowfish"]
    out = root / "out.csv"
    cases = [
        (("info", log, "--channels", "1,3"),
         "log.csv: --channels LEFT,RIGHT does not apply to a CSV recording: it has no servo outputs"),
        (("dataset", *v, "--out", out, "--noise", "nan,nan"),
         "--noise expects realistic, rtk, noisy, none or GNSS_M,HEADING_DEG (two finite numbers ≥ 0: m, degrees), "
         "got 'nan,nan'"),
        (("simulate", *v, "--scenario", "turn", "--inputs", inputs, "--out", out),
         "give --scenario or --inputs, not both (--scenario turn --inputs"),
        (("identify", log, *v, "--out", same, "--params", ""), "--params is empty: name at least one coefficient"),
        (("identify", log, *v, "--out", same, "--groups", " , "), "--groups is empty: name at least one group"),
        (("evaluate", log, *v, "--draws", "5"), "error: --draws applies only with --band"),
        (("evaluate", log, *v, "--level", "0.5", "--seed", "1"), "error: --level, --seed apply only with --band"),
        (("diagnose", log, *v, "--given", "current=abc"),
         "effect 'current=abc': expected current=speed_m_s,dir_deg (2 numbers), got 1 value 'abc'"),
        (("diagnose", log, *v, "--refit-weight", "-1"), "--refit-weight must be a positive finite number, got -1"),
        (("diagnose", log, *v, "--refit-weight", "5"), "--refit-weight weighs the beliefs of the coefficients --refit"),
    ]
    for args, message in cases:
        err = refused(monkeypatch, capsys, args, [log, inputs, same])
        assert message in err, (args, err)
    assert sorted(p.name for p in root.iterdir()) == ["inputs.csv", "log.csv", "same.json"]


def test_a_ctrl_c_ends_in_one_line_and_exit_code_130(monkeypatch, capsys, tmp_path):
    """typer answers a KeyboardInterrupt inside a command with its own exit 130: the user still reads
    'aborted', as for a Ctrl-C the command itself catches; `twin view --sim` without a vessel is bad
    input, not an AttributeError."""
    import twin
    import twin.replay

    twin.simulate_run("blueboat", scenario="turn", duration_s=5.0).write(tmp_path / "run.csv")
    code, err = run(monkeypatch, capsys, ["view", tmp_path / "run.csv", "--sim", "--png", tmp_path / "v.png"])
    assert code == 2 and err.strip() == "error: --sim and --smoother model need --vessel NAME or --model FILE"

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(twin.replay, "view_runs", interrupted)
    code, err = run(monkeypatch, capsys, ["view", tmp_path / "run.csv", "--vessel", "blueboat", "--png", tmp_path / "v.png"])
    assert code == 130 and err.strip().splitlines()[-1] == "aborted"


def test_a_run_too_large_for_the_machines_memory_is_refused_before_it_starts(monkeypatch, capsys, tmp_path):
    """`twin simulate --duration 1e7` would hold some 150 GB while it is made: refused at once (a
    machine of 25 GB spent 8 GB in ten minutes before), and a run that fits goes on."""
    import twin.simulation as simulation

    monkeypatch.setattr(simulation, "_physical_memory_bytes", lambda: 16 * 10 ** 9)
    code, err = run(monkeypatch, capsys, ["simulate", "--vessel", "blueboat", "--duration", "1e7",
                                          "--out", tmp_path / "big.csv"])
    assert code == 2 and "holds about 15 GB" not in err and "more than half of this machine's 16 GB" in err
    assert not (tmp_path / "big.csv").exists()
    assert simulation.simulate_run("blueboat", scenario="turn", duration_s=2.0).run.t[-1] == 2.0


def test_a_vessel_file_and_a_recording_given_for_each_other_are_told_apart(tmp_path):
    """A vessel file where an inputs CSV belongs, and a recording where a vessel file belongs, each
    get a sentence saying which is which, not only the parser's complaint."""
    from twin.drive import read_inputs_csv
    from twin.errors import TwinError
    from twin.vessel import MODEL_DIR, load

    with pytest.raises(TwinError, match="it looks like a vessel file: give that with --model"):
        read_inputs_csv(MODEL_DIR / "blueboat.json")
    log = tmp_path / "run.csv"
    log.write_text("t,lat,lon\n0,63.4,10.4\n")
    with pytest.raises(TwinError, match="not valid JSON .*this looks like a recording"):
        load(str(log))


def test_evaluate_refuses_a_log_with_nothing_to_score(monkeypatch, capsys, tmp_path):
    """A boat lying still for a second: no velocity varies, so no R² exists at any horizon; said in
    one line with exit 2, as identify and diagnose refuse it, and no JSON is written."""
    log = tmp_path / "still.csv"
    log.write_text("t,lat,lon,heading_deg,pwm_left,pwm_right\n0,37.4,-5.9,10,1500,1500\n1,37.4,-5.9,10,1500,1500\n")
    err = refused(monkeypatch, capsys, ("evaluate", log, "--vessel", "blueboat", "--json", tmp_path / "e.json"),
                  [log])
    assert "nothing to score" in err and not (tmp_path / "e.json").exists()


def test_a_wind_on_a_vessel_without_a_wind_load_is_refused_and_thrust_inputs_say_the_gains(tmp_path):
    """--wind on a vessel with no wind load did nothing without a word; thrust inputs are commands the
    vessel's gains scale (the BlueBoat's 1.605: 20 N asked, 32.1 N applied), which is said."""
    twin = twin_command.twin
    done = twin("simulate", "--vessel", "cybership1", "--duration", "2", "--wind", "5,0", "--out", tmp_path / "w.csv")
    assert done.returncode == 2 and "has no wind load model" in done.stderr and not (tmp_path / "w.csv").exists()
    inputs = tmp_path / "thrust.csv"
    inputs.write_text("t,thrust_left,thrust_right\n0,20,20\n")
    done = twin("simulate", "--vessel", "blueboat", "--inputs", inputs, "--duration", "1", "--out", tmp_path / "t.csv")
    assert done.returncode == 0 and "10 N commanded gives 16.1 N (left) at rest" in done.stderr
    row = (tmp_path / "t.csv").read_text().splitlines()[1].split(",")
    assert float(row[-2]) == pytest.approx(20 * 1.605, abs=0.05)


def test_dp_dead_ahead_a_short_run_and_an_infinite_frequency_end_in_one_line(tmp_path):
    """A point dead ahead asks the heading loop no step (its IAE ratio would divide by zero), a run
    shorter than the turn before the surge has no surge samples, ω = inf divides by zero: each is one
    line, not exit 3."""
    twin = twin_command.twin
    done = twin("dp", "--vessel", "blueboat", "--run", "point", "--target", "10,0", "--json", tmp_path / "dp.json")
    assert done.returncode == 0 and "IAE ratio – (no step asked of it)" in done.stdout
    surge, yaw = json.loads((tmp_path / "dp.json").read_text())["loops"]
    assert yaw["iae_ratio"] is None and 0.9 < surge["iae_ratio"] < 1.2
    for args, said in ((("--run", "point", "--duration", "5"), "ends before the point move's surge starts"),
                       (("--omega-heading", "inf"), "must be positive and finite, got inf")):
        done = twin("dp", "--vessel", "blueboat", *args)
        assert done.returncode == 2 and said in done.stderr and len(done.stderr.strip().splitlines()) == 1


def test_an_inputs_csv_says_a_ragged_row_a_nan_cell_and_how_to_replay_a_run(tmp_path):
    twin = twin_command.twin
    for text, said in (("t,pwm_left,pwm_right\n0,1600,1600,1700\n", "line 2 has 4 cells under a header of 3 columns"),
                       ("t,pwm_left,pwm_right\n0,nan,1600\n", "line 2: NaN or infinite value"),
                       ("t,x,pwm_left,pwm_right,thrust_left,thrust_right\n0,0,1500,1500,0,0\n",
                        "a twin run's CSV has both")):
        inputs = tmp_path / "in.csv"
        inputs.write_text(text)
        done = twin("simulate", "--vessel", "blueboat", "--inputs", inputs, "--duration", "1", "--out",
                    tmp_path / "o.csv")
        assert done.returncode == 2 and said in done.stderr and not (tmp_path / "o.csv").exists()
    done = twin("mission", "--home", "0,0", "--waypoints", "1,1", "--port", "99999")
    assert done.returncode == 2 and "a TCP port number is 1..65535" in done.stderr


def _mjcf_changed(root, name: str, old: str, new: str) -> str:
    """The shipped blueboat with `old` replaced by `new` in a copy of its MJCF (meshes from the package)."""
    import twin.vessel as vessel_mod

    text = (vessel_mod.MODEL_DIR / "blueboat.xml").read_text()
    assert old in text
    mjcf = root / f"{name}.xml"
    mjcf.write_text(text.replace(old, new).replace('meshdir="../assets"', f'meshdir="{vessel_mod.MODEL_DIR.parent / "assets"}"'))
    return vessel_file(root, name, lambda d: d.update(mjcf=str(mjcf)))


@pytest.mark.parametrize("args, message", [
    (("identify", "{log}", "--vessel", "yellowfish", "--out", "{root}/m.json", "--thruster", "dynamic", "--seed", "3"),
     "--thruster, --seed apply only with --greybox"),
    (("identify", "{log}", "--vessel", "yellowfish", "--out", "{root}/m.json", "--params", "Xu", "--groups", "surge"),
     "--groups does not apply with it"),
    (("identify", "{log}", "--vessel", "yellowfish", "--out", "{root}/m.json", "--greybox", "--repeats", "100000"),
     "--repeats 100000: at most 1000"),
    (("iso", "--vessel", "blueboat", "--amplitudes", "5,,6"), "an empty item in the list"),
    (("identify", "{log}", "--vessel", "yellowfish", "--out", "{root}/m.json", "--params", "Xu,,Nr"),
     "an empty item in the list"),
    (("dp", "--vessel", "blueboat", "--run", "point", "--target", "1e9,1e9"), "0.5 to 1000 m away"),
    (("dp", "--vessel", "blueboat", "--omega-heading", "1e9"), "at most 25 rad/s"),
    (("mission", "--timeout", "1", "--home", "37,-5", "--waypoints", "nan,0"), "is not a waypoint within 50 km"),
    (("mission", "--timeout", "1", "--home", "37,-5", "--waypoints", "nosuch.waypoints"),
     "--waypoints nosuch.waypoints: no such mission file (give a QGC WPL 110 file"),
    (("mission", "--timeout", "1", "--home", "37,-5", "--waypoints", "{log}"),
     "not a mission file (its first line is not 'QGC WPL 110'"),
    (("dataset-shards", "--vessel", "blueboat", "--out", "{root}/shards", "--effect-share", "0.5"),
     "--effect-share applies only with --effect"),
])
def test_options_that_would_do_nothing_or_nonsense_are_refused(monkeypatch, capsys, kept, args, message):
    root, log, _, same = kept
    err = refused(monkeypatch, capsys, [str(a).format(log=log, root=root) for a in args], [log, same])
    assert message in err, err


def test_a_vessel_whose_mjcf_holds_no_number_or_no_step_is_refused(monkeypatch, capsys, tmp_path):
    nan = _mjcf_changed(tmp_path, "nan", 'mass="3.5"', 'mass="nan"')
    assert 'mass="nan" is not a finite number' in refused(monkeypatch, capsys, ["params", "--model", nan])
    step = _mjcf_changed(tmp_path, "step", 'timestep="0.02"', 'timestep="0"')
    assert "option timestep must lie between 0 and 1 s" in refused(
        monkeypatch, capsys, ["simulate", "--model", step, "--duration", "1", "--out", tmp_path / "o.csv"])
    for fine in (_mjcf_changed(tmp_path, "named", 'name="battery"', 'name="nan"'),  # a name is not a number
                 _mjcf_changed(tmp_path, "noted", "<worldbody>", '<!-- <geom mass="nan"/> --><worldbody>')):
        monkeypatch.setattr(sys, "argv", ["twin", "params", "--model", fine])
        cli.main()
        assert "m = 15.000 kg" in capsys.readouterr().out


def test_inputs_and_logs_cut_short_or_stamped_in_another_unit_are_refused(monkeypatch, capsys, kept):
    root, log, _, same = kept
    cut = root / "cut_inputs.csv"
    cut.write_text("t,pwm_left,pwm_right\n0,1500,1500\n5,16")
    assert "line 3 has 2 cells under a header of 3 columns (cut short?)" in refused(
        monkeypatch, capsys, ["simulate", "--vessel", "blueboat", "--inputs", cut, "--out", root / "o.csv"])
    rows = log.read_text().splitlines()
    nanos = root / "nanos.csv"
    nanos.write_text("\n".join([rows[0]] + [f"{float(r.split(',')[0]) * 1e9:.1f}," + r.split(",", 1)[1]
                                            for r in rows[1:]]) + "\n")
    assert "are the time stamps in another unit" in refused(
        monkeypatch, capsys, ["evaluate", nanos, "--vessel", "yellowfish"], [log, same])


def test_an_option_of_one_value_given_twice_is_refused_not_taken_at_its_last(monkeypatch, capsys, tmp_path):
    """`--png a.png --png b.png` wrote b.png alone without a word; a repeatable option still repeats."""
    out = tmp_path / "run.csv"
    err = refused(monkeypatch, capsys, ["simulate", "--vessel", "yellowfish", "--duration", "1", "--duration", "2",
                                        "--out", out], [])
    assert err == "error: --duration given 2 times: it takes one value\n" and not out.exists()
    err = refused(monkeypatch, capsys, ["view", out, "--png", tmp_path / "a.png", f"--png={tmp_path / 'b.png'}"], [])
    assert err == "error: --png given 2 times: it takes one value\n"
    assert list(tmp_path.iterdir()) == []


def test_a_file_named_with_a_trailing_slash_is_refused_not_written_without_it(monkeypatch, capsys, tmp_path):
    """`--out run.csv/` wrote a file run.csv (the path parser drops the slash); a folder of such a name
    that exists is still taken as the folder it is."""
    err = refused(monkeypatch, capsys, ["simulate", "--vessel", "yellowfish", "--duration", "1",
                                        "--out", f"{tmp_path / 'run.csv'}/"], [])
    assert err == f"error: '{tmp_path / 'run.csv'}/' ends with a slash, as a folder does: give the file's name without it\n"
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "logs.csv").mkdir()
    err = refused(monkeypatch, capsys, ["info", f"{tmp_path / 'logs.csv'}/"], [])
    assert "ends with a slash" not in err
