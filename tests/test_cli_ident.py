"""The identification commands end to end: dataset → identify → evaluate, and their errors."""
import json
import sys
from dataclasses import replace

import pytest

import twin.vessel as vessel_mod
import twin_command
from twin.fit.evaluate import state_display


def twin(*args, timeout=300):
    return twin_command.twin(*args)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    d = tmp_path_factory.mktemp("ident")
    done = twin("dataset", "--vessel", "yellowfish", "--segments", "3", "--seed", "4", "--noise", "none",
                "--manoeuvres", "rc,circle_varying,forward_varying", "--effect", "thrust_gain=1.15",
                "--out", d / "train.tlog", "--out", d / "train.csv")
    assert done.returncode == 0, done.stderr
    return d


def test_dataset_writes_recordings_and_a_separate_truth(dataset):
    truth = json.loads((dataset / "train.truth.json").read_text())
    assert truth["effects"][0]["text"] == "thrust_gain=1.15" and len(truth["segments"]) == 3
    assert truth["vessel"]["thrusters"]["gain_left"] == pytest.approx(1.15)
    assert (dataset / "train.csv").stat().st_size > 10_000


def test_identify_then_evaluate(dataset):
    model = dataset / "model.json"
    done = twin("identify", dataset / "train.tlog", "--vessel", "yellowfish", "--out", model, "--repeats", "2",
                "--params", "Xuu,thrust_gain", "--window", "5", "--json", dataset / "report.json", "--greybox")
    assert done.returncode == 0, done.stderr
    assert "[Morel-2024] grey-box" in done.stdout and "identification by simulation" in done.stdout
    assert "judged on left-out runs" in done.stdout and "on a new run expect" in done.stdout
    assert "fitted on: u " in done.stdout and "the twin extrapolates" in done.stdout
    # one log: its left-out groups are time blocks of it, said as parts; --params judges no groups
    assert "R² on left-out parts" in done.stdout and "left-out runs, all together" not in done.stdout
    assert "no group is needed" not in done.stdout and "a group goes back to its prior" not in done.stdout
    v = vessel_mod.load(str(model))
    assert v.thrusters.gain_left == pytest.approx(1.15, rel=0.03)
    assert "identification" in v.sources
    report = json.loads((dataset / "report.json").read_text())
    assert {e["name"] for e in report["fit"]["estimates"]} == {"Xuu", "thrust_gain"}
    # one log: its time blocks stand in for left-out runs, and every choice carries their scores
    assert report["chosen"] and all(len(c["runs"]) >= 3 for c in report["choices"])
    done = twin("evaluate", "--model", model, dataset / "train.csv", "--json", dataset / "eval.json",
                "--rrd", dataset / "eval.rrd")
    assert done.returncode == 0, done.stderr
    assert "stand_ins" not in v.uncertainty and "stands in" not in done.stderr  # none moved past its belief
    assert (dataset / "eval.rrd").stat().st_size > 1000
    report = json.loads((dataset / "eval.json").read_text())
    metrics = report["metrics"]
    assert set(metrics) == {"one_step", "free_run_10s", "free_run_30s", "full"}
    assert metrics["free_run_10s"]["u"]["r2"] > 0.95 and set(metrics["full"]["r"]) >= {"r2", "mae"}
    # where the 10-s free runs miss: the groups' shares add up to 1 − R² of the 10-s free runs
    split = report["by_manoeuvre"]
    assert "where the 10-s free runs miss" in done.stdout and split["groups"]
    for d in ("u", "v", "r"):
        total = sum(g["share"][d] for g in split["groups"].values())
        assert total == pytest.approx(1.0 - metrics["free_run_10s"][d]["r2"], rel=1e-6, abs=1e-9)
    # judged on the very log it was fitted on: the fit saw every window, and only the extreme
    # samples beyond its own 1st-99th percentiles lie outside its span
    seen = split["fitted_on"]
    assert seen["logs"] == 1 and {**seen, "wind": "none"} == v.uncertainty["fitted_on"]
    assert seen["windows"] == {name: g["windows"] for name, g in split["groups"].items()}
    assert 0.0 < split["beyond_fit"]["share_of_samples"] <= 0.06 and "beyond that span" in done.stdout
    assert "of the 1 log the twin was fitted on" in done.stdout
    # its own log is said to be the fit's own, and no run is asked for to reach where it already is
    said = " ".join(done.stdout.split())  # the identified tlog judged as its CSV: the same log
    assert seen["sources"] == ["train.tlog"] and "train.csv bears the name of a log the twin was fitted on" in said
    assert "record runs that reach there" not in done.stdout
    # a vessel file whose record of the fit is damaged is refused in one line, before any work
    broken = json.loads(model.read_text())
    broken["uncertainty"]["fitted_on"] = {"ranges": {"u": [1.0, 0.0]}}
    (dataset / "broken.json").write_text(json.dumps(broken))
    done = twin("evaluate", "--model", dataset / "broken.json", dataset / "train.csv")
    assert done.returncode == 2 and "fitted_on" in done.stderr and "Traceback" not in done.stderr
    # a coefficient identify flagged as moved past its belief is named; a damaged entry is refused
    flagged = json.loads(model.read_text())
    flagged["uncertainty"]["stand_ins"] = [{"name": "Xuu", "unit": "N s2/m2", "value": -40.0, "prior": -8.0,
                                            "from_prior_sigmas": 1.5}]
    (dataset / "flagged.json").write_text(json.dumps(flagged))
    done = twin("evaluate", "--model", dataset / "flagged.json", dataset / "train.csv")
    assert done.returncode == 0 and "(Xuu ×5 of its prior): each stands in for something its form lacks" in done.stderr
    flagged["uncertainty"]["stand_ins"] = [{"name": "Xuu", "value": "large"}]
    (dataset / "flagged.json").write_text(json.dumps(flagged))
    done = twin("evaluate", "--model", dataset / "flagged.json", dataset / "train.csv")
    assert done.returncode == 2 and "uncertainty.stand_ins needs" in done.stderr and "Traceback" not in done.stderr


def test_a_coefficient_its_heavy_belief_holds_is_not_said_to_be_pinned_by_the_recordings(dataset, tmp_path):
    """A thrust gain of 1.15: believed as 10000 windows' worth of data, the belief holds it near 1 and
    the report does not call it pinned by the recordings; believed lightly, the recordings pin it near
    the truth. (Each velocity scaled by its own misfit, a window of these nearly exact logs is worth
    much: at 10 windows the recordings already pin it at 1.14.)"""
    lines = {}
    for beliefs in ("10000", "0.01"):
        done = twin("identify", dataset / "train.csv", "--vessel", "yellowfish", "--out", tmp_path / f"m{beliefs}.json",
                    "--params", "Xuu,thrust_gain", "--beliefs", beliefs, "--window", "5")
        assert done.returncode == 0, done.stderr
        lines[beliefs] = next(line for line in done.stdout.splitlines() if line.startswith("thrust_gain"))
    assert float(lines["10000"].split()[3]) == pytest.approx(1.0, abs=0.01)
    assert "pinned by the recordings" not in lines["10000"] and "belief" in lines["10000"]
    assert float(lines["0.01"].split()[3]) == pytest.approx(1.15, abs=0.02)
    assert "pinned by the recordings" in lines["0.01"]
    sources = vessel_mod.load(str(tmp_path / "m10000.json")).sources["identification"]
    pinned = sources.split("pinned by the recordings: ")[1].split(";")[0].split(".")[0]
    assert "thrust_gain" not in pinned and "thrust_gain" in sources

def test_evaluate_by_a_state_adds_up_to_one_minus_r2_and_refuses_a_state_that_does_not_vary(dataset, tmp_path):
    slow = tmp_path / "slow.json"  # a drag twice too strong: the twin misses most where it runs fast
    base = vessel_mod.load("yellowfish")
    vessel_mod.save(replace(base, damping=replace(base.damping, Xuu=2.0 * base.damping.Xuu)), slow)
    done = twin("evaluate", "--model", slow, dataset / "train.csv", "--by", "speed", "--json", tmp_path / "e.json")
    assert done.returncode == 0, done.stderr
    report = json.loads((tmp_path / "e.json").read_text())
    bands = report["by_state"]["bands"]
    assert report["by_state"]["state"] == "speed_m_s" and len(bands) == 4 and "by speed over ground" in done.stdout
    assert bands[0]["label"].startswith("< ") and bands[1]["label"].endswith(" m/s") and " to " in bands[1]["label"]
    assert sum(b["samples"] for b in bands) == pytest.approx(1.0)
    assert sum(b["share"]["u"] for b in bands) == pytest.approx(1.0 - report["metrics"]["free_run_10s"]["u"]["r2"],
                                                                 rel=1e-6)
    per_sample = [b["share"]["u"] / b["samples"] for b in bands]
    assert per_sample[-1] > 2.0 * per_sample[0] and bands[-1]["gain"]["u"] > 1.0
    # a PWM log's first input never rests at zero: refused in one line, before any work
    done = twin("evaluate", "--vessel", "yellowfish", dataset / "train.csv", "--by", "rest")
    assert done.returncode == 2 and "--by rest" in done.stderr and len(done.stderr.strip().splitlines()) == 1
    done = twin("evaluate", "--vessel", "yellowfish", dataset / "train.csv", "--by", "heave")
    assert done.returncode == 2 and "unknown state" in done.stderr


def test_a_twin_that_follows_the_pack_says_which_logs_record_none(dataset, tmp_path):
    base = vessel_mod.load("yellowfish")
    model = vessel_mod.save(replace(base, thrusters=replace(base.thrusters, supply_exponent=2.0, supply_ref_v=16.0)),
                            tmp_path / "pack.json")
    done = twin("evaluate", "--model", model, dataset / "train.csv")
    assert done.returncode == 0, done.stderr
    assert "train.csv: no battery voltage logged" in done.stdout and "as at 16 V" in done.stdout


def run_in_process(monkeypatch, capsys, args) -> tuple[int, str]:
    from twin.cli.app import main

    monkeypatch.setattr(sys, "argv", ["twin", *map(str, args)])
    with pytest.raises(SystemExit) as exit_info:
        main()
    return exit_info.value.code, capsys.readouterr().err


def test_bad_input_is_one_line_and_exit_2(dataset, tmp_path, monkeypatch, capsys):
    cases = [
        ("dataset", "--vessel", "yellowfish", "--out", tmp_path / "x.tlog", "--manoeuvres", "loop"),
        ("identify", dataset / "train.tlog", "--vessel", "yellowfish", "--out", tmp_path / "m.json", "--params", "Xq"),
        ("identify", dataset / "train.tlog", "--vessel", "yellowfish", "--out", tmp_path / "m.json",
         "--params", "Xudot,thrust_gain"),
        ("identify", dataset / "train.tlog", "--vessel", "yellowfish", "--out", tmp_path / "m.json", "--start", "now"),
    ]  # a bad effect text, an unknown format and a missing log: test_cli_errors
    for args in cases:
        code, err = run_in_process(monkeypatch, capsys, args)
        assert code == 2, (args, err)
        assert err.startswith("error:") and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "x.tlog").exists() and not (tmp_path / "m.json").exists()


def test_identify_writes_the_prior_where_it_predicts_the_left_out_runs_better_than_any_fit(dataset, tmp_path):
    """Given the truth that wrote the (noise-free) recording as its prior, no fit predicts the left-out
    parts better: the prior is written, every coefficient at its own value, its uncertainty the
    beliefs' alone without the lag the fit started from (the truth has none), and the report says why."""
    base = vessel_mod.load("yellowfish")
    truth = vessel_mod.save(replace(base, thrusters=replace(base.thrusters, gain_left=1.15, gain_right=1.15)),
                            tmp_path / "truth.json")
    out, report = tmp_path / "model.json", tmp_path / "report.json"
    done = twin("identify", dataset / "train.csv", "--model", truth, "--out", out, "--json", report, "--window", "5")
    assert done.returncode == 0, done.stderr
    assert "prior (no fit) *" in done.stdout and "the prior written, not the fit" in done.stdout
    assert "warning" not in done.stdout + done.stderr
    written, given = vessel_mod.load(str(out)), vessel_mod.load(str(truth))
    assert written.thrusters == given.thrusters and written.damping == given.damping
    assert written.added_mass == given.added_mass
    block = written.uncertainty
    assert "lag_s" not in [c["name"] for c in block["coordinates"]] and block["form_error"]
    assert written.sources["identification"].startswith("kept by `twin identify`")
    r = json.loads(report.read_text())
    assert r["chosen"] == "prior (no fit)" and not r["worse_than_prior"]
    assert all(not e["identifiable"] and e["value"] == e["prior"] for e in r["fit"]["estimates"])


def test_identify_refuses_a_twin_that_ran_away_on_every_left_out_run(dataset, tmp_path):
    """A prior whose thrust is a billion times too strong runs away on every window, whatever is fitted:
    nothing is written, and a model file already there is kept byte for byte."""
    base = vessel_mod.load("yellowfish")
    wild = vessel_mod.save(replace(base, thrusters=replace(base.thrusters, forward=(1e9, 1e9, -0.6),
                                                           reverse=(-1e9, 1e9, -0.3))), tmp_path / "wild.json")
    out, report = tmp_path / "model.json", tmp_path / "report.json"
    out.write_text('{"kept": true}\n')
    done = twin("identify", dataset / "train.csv", "--model", wild, "--out", out, "--json", report, "--force",
                "--params", "Xuu", "--beliefs", "1", "--max-evaluations", "1", "--window", "5")
    assert done.returncode == 2 and done.stderr.startswith("error: the identified twin ran away (diverged) on all ")
    assert "left-out runs: nothing written (check the prior" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert out.read_text() == '{"kept": true}\n' and not report.exists()


def test_identify_says_a_log_too_short_for_any_window_is_not_in_the_fit(dataset, tmp_path):
    rows = (dataset / "train.csv").read_text().splitlines(keepends=True)
    short = tmp_path / "short.csv"
    start = float(rows[1].split(",")[0])
    # its first 4 s moved 11 m north: a log of its own, not a stretch cut from the other (refused)
    kept = [r.split(",") for r in rows[1:] if float(r.split(",")[0]) < start + 4.0]
    short.write_text("".join([rows[0]] + [",".join([c[0], f"{float(c[1]) + 1e-4:.10f}" if c[1] else "", *c[2:]])
                                                 for c in kept]))
    done = twin("identify", dataset / "train.csv", short, "--vessel", "yellowfish", "--out", tmp_path / "m.json",
                "--params", "thrust_gain", "--beliefs", "1", "--max-evaluations", "2", "--window", "5")
    assert done.returncode == 0, done.stderr
    assert "short.csv: no stretch of 5 s without a dropout, so not in the fit" in done.stdout + done.stderr


def test_state_bands_are_shown_in_the_units_the_reports_use():
    assert state_display("yaw_rate_rad_s")[1:] == ("°/s", pytest.approx(57.29578))
    assert state_display("input_1", "propeller_rudder")[:2] == ("rudder angle", "°")
    assert state_display("input_1")[:2] == ("right thruster's PWM", "µs")


def test_a_folder_stands_for_the_recordings_in_it(dataset, tmp_path):
    folder = tmp_path / "logs"
    folder.mkdir()
    done = twin("evaluate", "--vessel", "yellowfish", folder)
    assert done.returncode == 2 and "is a folder with no recordings in it" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    (folder / "train.csv").write_bytes((dataset / "train.csv").read_bytes())
    (folder / "notes.txt").write_text("not a log")
    done = twin("evaluate", "--vessel", "yellowfish", folder, "--json", tmp_path / "e.json")
    assert done.returncode == 0, done.stderr
    assert json.loads((tmp_path / "e.json").read_text())["recordings"] == [str(folder / "train.csv")]
