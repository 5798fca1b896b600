"""What a new user meets: a run, a dataset or a fit never replaces a file that exists unless asked
(--force) and a report never replaces a log or a twin, a fleet with a log it cannot diagnose (not one
too short) ends in exit code 2 after writing the others, a
log whose every input sample was dropped says so, a dataset too large for the machine is refused
before any work, and a coefficient whose windows disagree is not said to be held by its belief."""
import json
from dataclasses import dataclass

import numpy as np
import pytest
from twin_command import twin

from twin.cli import ident as cli_ident
from twin.errors import TwinError
from twin.fit import simfit
from twin.effects.coefficients import Belief
from twin.prepare.timing import GyroLag


def test_simulate_refuses_to_replace_an_existing_file_without_force(tmp_path):
    log = tmp_path / "my_log.csv"
    log.write_text("t,lat,lon\n0,59,10\n")
    done = twin("simulate", "--vessel", "blueboat", "--duration", "2", "--out", log)
    assert done.returncode == 2
    assert done.stderr.strip() == f"error: --out '{log}' exists: it is kept (--force replaces it)"
    assert log.read_text() == "t,lat,lon\n0,59,10\n"
    forced = twin("simulate", "--vessel", "blueboat", "--duration", "2", "--out", log, "--force")
    assert forced.returncode == 0 and log.read_text().startswith("t,x,y,psi")


def test_a_report_never_replaces_a_log_or_a_twin_and_a_session_or_a_band_needs_force(tmp_path):
    """A report (--json of evaluate or mission) written over a vessel file or a recording would lose
    it: refused by what the file holds, before any work, --force or not; --force replaces data only
    with data of its kind (a session's recording over a recording, a twin over a twin, never a band
    over a log or a truth over a twin); a report over an earlier report is written."""
    log, twin_file = tmp_path / "my_log.csv", tmp_path / "my_boat.json"
    log.write_text("t,lat,lon,heading_deg,pwm_left,pwm_right\n0,59,10,0,1500,1500\n")
    twin_file.write_text('{"name": "mine", "mjcf": "blueboat.xml", "thrusters": {}}\n')
    truth = tmp_path / "d.truth.json"
    truth.write_text('{"vessel": {}, "effects": [], "segments": []}\n')
    band = tmp_path / "band.json"
    made = twin("montecarlo", "--vessel", "blueboat", "--no-covariance", "--vary", "Nr=0.8..1.2", "--draws", "2",
                "--duration", "2", "--out", band)
    assert made.returncode == 0, made.stderr
    kept = {p: p.read_text() for p in (log, twin_file, truth, band)}
    refusals = [
        (("evaluate", "--vessel", "blueboat", log, "--json", band), "--json", band, "Monte Carlo band"),
        (("identify", log, "--vessel", "blueboat", "--params", "thrust_gain", "--out", band, "--force"), "--out", band,
         "Monte Carlo band"),
        (("params", "--vessel", "blueboat", "--first-principles", "--write-model", band, "--force"), "--write-model",
         band, "Monte Carlo band"),
        (("diagnose", log, "--vessel", "blueboat", "--json", truth), "--json", truth, "dataset's truth"),
        (("evaluate", "--vessel", "blueboat", log, "--json", twin_file), "--json", twin_file, "vessel file"),
        (("mission", "--home", "59,10", "--waypoints", "5,0", "--json", twin_file), "--json", twin_file, "vessel file"),
        (("sitl", "--vessel", "blueboat", "--record", log), "--record", log, None),
        (("montecarlo", "--vessel", "blueboat", "--no-covariance", "--vary", "Nr=0.8..1.2", "--draws", "2",
          "--duration", "2", "--out", log, "--force"), "--out", log, "recording"),
        (("identify", log, "--vessel", "blueboat", "--out", tmp_path / "x.json", "--json", twin_file, "--force"),
         "--json", twin_file, "vessel file"),
        (("diagnose", log, "--vessel", "blueboat", "--write-model", truth, "--force"), "--write-model", truth,
         "dataset's truth"),
        (("dataset", "--vessel", "blueboat", "--segments", "1", "--out", tmp_path / "d.csv", "--truth", twin_file,
          "--force"), "--truth", twin_file, "vessel file"),
    ]
    for args, option, path, kind in refusals:
        done = twin(*args)
        assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, (args, done.stderr)
        said = (f"exists and is a {kind}: it is kept, --force or not (give another name, or remove it first)" if kind
                else "exists: it is kept (--force replaces it)")
        assert done.stderr.strip() == f"error: {option} '{path}' {said}", (args, done.stderr)
    assert all(p.read_text() == text for p, text in kept.items())
    again = twin("montecarlo", "--vessel", "blueboat", "--no-covariance", "--vary", "Nr=0.8..1.2", "--draws", "3",
                 "--duration", "2", "--out", band, "--force")  # a band over a band, with --force
    assert again.returncode == 0 and json.loads(band.read_text())["draws"] == 3, again.stderr
    report = tmp_path / "report.json"
    report.write_text('{"earlier": "report"}\n')
    made = twin("simulate", "--vessel", "blueboat", "--duration", "20", "--scenario", "random", "--out", tmp_path / "r.csv")
    assert made.returncode == 0, made.stderr
    done = twin("evaluate", "--vessel", "blueboat", tmp_path / "r.csv", "--json", report)
    assert done.returncode == 0 and '"earlier"' not in report.read_text()


def test_force_replaces_a_table_or_a_band_only_with_its_own_kind(tmp_path):
    """--force replaces a run with a run and a band with a band; a table that is neither (notes, a
    manifest), a table of inputs or a band is kept when a run would go there, and a dataset's truth
    is not replaced under a log beside it that the run does not write."""
    notes, inputs = tmp_path / "notes.csv", tmp_path / "inputs.csv"
    notes.write_text("note,value\n1,2\n")
    inputs.write_text("t,pwm_left,pwm_right\n0,1500,1500\n")
    band = tmp_path / "band.csv"
    made = twin("montecarlo", "--vessel", "blueboat", "--no-covariance", "--vary", "Nr=0.8..1.2", "--draws", "2",
                "--duration", "2", "--out", band, "--out", tmp_path / "band.rrd")
    assert made.returncode == 0, made.stderr
    kept = {p: p.read_bytes() for p in (notes, inputs, band, tmp_path / "band.rrd")}
    own = "is not a recording or rerun recording of runs in twin's own layout (a log in another's, a table, a view)"
    for path, said in ((notes, own), (inputs, "is a table of inputs"),
                       (band, "is a Monte Carlo band"), (tmp_path / "band.rrd", "is a Monte Carlo band")):
        done = twin("simulate", "--vessel", "blueboat", "--duration", "2", "--out", path, "--force")
        assert done.returncode == 2 and done.stderr.strip() == (
            f"error: --out '{path}' exists and {said}: it is kept, --force or not (give another name, or remove it "
            "first)"), done.stderr
    assert all(p.read_bytes() == b for p, b in kept.items())
    again = twin("montecarlo", "--vessel", "blueboat", "--no-covariance", "--vary", "Nr=0.8..1.2", "--draws", "3",
                 "--duration", "2", "--out", band, "--out", tmp_path / "band.rrd", "--force")
    assert again.returncode == 0 and band.read_bytes() != kept[band], again.stderr  # a band over a band
    made = twin("dataset", "--vessel", "blueboat", "--segments", "1", "--out", tmp_path / "d.csv")
    assert made.returncode == 0, made.stderr
    truth = (tmp_path / "d.truth.json").read_text()
    done = twin("dataset", "--vessel", "blueboat", "--segments", "1", "--seed", "1", "--out", tmp_path / "d.mcap",
                "--force")
    assert done.returncode == 2 and f"describes the recording '{tmp_path / 'd.csv'}'" in done.stderr
    assert (tmp_path / "d.truth.json").read_text() == truth and not (tmp_path / "d.mcap").exists()
    again = twin("dataset", "--vessel", "blueboat", "--segments", "1", "--seed", "1", "--out", tmp_path / "d.csv",
                 "--force")  # the log and its truth anew, together
    assert again.returncode == 0 and (tmp_path / "d.truth.json").read_text() != truth, again.stderr
    named = twin("dataset", "--vessel", "blueboat", "--segments", "1", "--out", tmp_path / "q.csv", "--truth",
                 tmp_path / "answers.json")  # a truth of the user's name lists its logs
    assert named.returncode == 0 and json.loads((tmp_path / "answers.json").read_text())["logs"] == ["q.csv"]
    log = (tmp_path / "q.csv").read_bytes()
    over = twin("simulate", "--vessel", "blueboat", "--duration", "2", "--out", tmp_path / "q.csv", "--force")
    assert over.returncode == 2 and "answers.json" in over.stderr and (tmp_path / "q.csv").read_bytes() == log


def test_dataset_refuses_to_replace_its_log_or_its_truth_without_force(tmp_path):
    truth = tmp_path / "d.truth.json"
    truth.write_text("{}")
    done = twin("dataset", "--vessel", "blueboat", "--segments", "1", "--out", tmp_path / "d.csv")
    assert done.returncode == 2 and f"'{truth}' exists" in done.stderr and truth.read_text() == "{}"
    assert not (tmp_path / "d.csv").exists()  # refused before any work


def test_a_dataset_larger_than_the_machine_is_refused_before_any_work(monkeypatch):
    monkeypatch.setattr(cli_ident, "memory_bytes", lambda: 8 * 2 ** 30)
    with pytest.raises(TwinError, match=r"--segments 100000: about 93.1 GiB .* \(8 GiB\)"):
        cli_ident.segments_fit(100_000)
    cli_ident.segments_fit(8)  # the default fits
    with pytest.raises(TwinError, match="--segments must be at least 1, got 0"):
        cli_ident.segments_fit(0)


def test_a_log_whose_every_input_sample_was_dropped_says_so(tmp_path):
    path = tmp_path / "bigpwm.csv"
    rows = ["t,north_m,east_m,heading_deg,pwm_left,pwm_right"] + [f"{k / 10:.1f},0,0,0,15000,15000" for k in range(30)]
    path.write_text("\n".join(rows) + "\n")
    done = twin("evaluate", "--vessel", "blueboat", path)
    assert done.returncode == 2
    assert "every input sample was dropped: pwm: PWM outside 500-2500 µs: 30" in done.stderr
    assert "columns pwm_left,pwm_right" not in done.stderr  # they are there


def test_a_fleet_with_a_log_it_cannot_diagnose_exits_2_after_writing_the_reports(tmp_path):
    logs = tmp_path / "logs"
    logs.mkdir()
    (logs / "empty.csv").write_text("")
    made = twin("simulate", "--vessel", "blueboat", "--scenario", "random", "--duration", "150", "--out",
                logs / "good.csv")
    assert made.returncode == 0, made.stderr
    out = tmp_path / "reports"
    done = twin("fleet", logs, "--vessel", "blueboat", "--effects", "thrust_gain", "--out", out)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1] == (f"error: 1 of 2 logs could not be diagnosed (their failure records "
                                                    f"are in {out}, the other reports are written)")
    assert (out / "fleet.json").is_file() and (out / "good.json").is_file()


def test_a_log_whose_pwm_never_leaves_neutral_while_the_boat_is_driven_is_warned(tmp_path):
    """Every PWM at 1500 µs while the track does 1-2 m/s: the logged outputs are not the ones that drove
    the boat, and evaluate says so (naming --channels) before scoring a twin that never moves."""
    made = twin("dataset", "--vessel", "blueboat", "--segments", "1", "--seed", "2", "--out", tmp_path / "d.csv")
    assert made.returncode == 0, made.stderr
    rows = (tmp_path / "d.csv").read_text().splitlines()
    cols = rows[0].split(",")
    left, right = cols.index("pwm_left"), cols.index("pwm_right")
    out = [rows[0]]
    for row in rows[1:]:
        cells = row.split(",")
        cells[left] = cells[right] = "1500" if cells[left] else ""
        out.append(",".join(cells))
    (tmp_path / "neutral.csv").write_text("\n".join(out) + "\n")
    done = twin("evaluate", "--vessel", "blueboat", tmp_path / "neutral.csv")
    assert "warning: neutral.csv: the thrusters' PWM stays within 35 µs of neutral (1500, 1500 µs) while the boat " \
           "goes" in done.stderr and "--channels LEFT,RIGHT" in done.stderr, done.stderr
    done = twin("evaluate", "--vessel", "blueboat", tmp_path / "d.csv")
    assert "stays within" not in done.stderr


def test_a_heading_ahead_of_its_gyro_is_said_to_be_early():
    assert "heading against the gyro: 0.22 s early ± 0.10 s" in GyroLag(-0.22, 0.95, 60.0, sigma_s=0.10).text()
    assert "heading against the gyro: +0.30 s late ± 0.05 s" in GyroLag(0.30, 0.95, 60.0, sigma_s=0.05).text()


@dataclass
class _Objective:
    """What _map_estimates reads of an objective: the coordinates' scales and bounds, and the σ each
    belief alone leaves at its weight."""

    held: np.ndarray

    scale = np.ones(3)

    def bounds(self):
        return np.full(3, -1e3), np.full(3, 1e3)

    def belief_sigma(self):
        return self.held


def test_a_coefficient_is_pinned_held_or_disputed_by_its_sigma_against_its_belief_alone():
    """σ belief 1, its weight leaving 0.1: a posterior σ of 0.05 is the recordings' (pinned), 0.1 the
    belief's (held), 0.6 the windows' scatter about the fit, which no belief narrows (disputed)."""
    belief = Belief(False, 1.0, "test")
    coords = [simfit.Coordinate(n, None, belief, False, 0.0, "-", 0.0) for n in ("a", "b", "c")]
    cov = np.diag([0.05, 0.1, 0.6]) ** 2
    est = simfit._map_estimates(_Objective(np.full(3, 0.1)), coords, np.zeros(3), cov, np.ones(3, bool))
    assert [(e.held_by_belief, e.disputed) for e in est] == [(False, False), (True, False), (False, True)]
    assert est[0].note.startswith("pinned by the recordings")
    assert "the recordings add little" in est[1].note
    assert "pull it different ways" in est[2].note and "6.0 times what the belief alone leaves" in est[2].note
    assert "add little" not in est[2].note


# -------------------------------------------------------------------------------- the Python API


def test_the_api_refuses_bad_arguments_in_one_sentence(tmp_path):
    """What a user types wrong in Python is a TwinError naming it, not a TypeError from deep inside."""
    import twin

    with pytest.raises(TwinError, match="expected a vessel .* got int"):
        twin.simulate_run(5, duration_s=5)
    for bad in (-1, 0, float("nan")):
        with pytest.raises(TwinError, match="window_s must be a positive finite number of seconds"):
            twin.diagnose_recordings(["unused.csv"], "blueboat", window_s=bad)
    with pytest.raises(TwinError, match="identify: unknown option foo .*known: .*params"):
        twin.identify(["unused.csv"], "blueboat", foo=1)
    with pytest.raises(TwinError, match="judge: unknown option foo"):
        twin.judge(["unused.csv"], "blueboat", ["current=0.15,90"], foo=1)
    with pytest.raises(TwinError, match="unknown effect"):  # before the recordings are read
        twin.judge(["unused.csv"], "blueboat", ["warp_drive=3"])
    with pytest.raises(TwinError, match=r"only=\['heavy'\]: unknown crosscheck case .*damping"):
        twin.crosscheck("yellowfish", duration_s=5, only=["heavy"])
    path = twin.save_vessel("blueboat", tmp_path / "bb.json")  # a name, as every other function takes
    assert twin.load_vessel(str(path)).name == "blueboat"


def test_the_api_keeps_a_file_its_outputs_would_replace_and_refuses_one_log_given_twice(tmp_path):
    """As the commands do: a run or a vessel file written over an existing file only with force=True,
    a vessel file only as .json, and one log given twice refused by name (not judged against itself)."""
    import twin

    log = tmp_path / "my_log.csv"
    log.write_text("t,lat,lon\n0,59,10\n")
    sim = twin.simulate_run("blueboat", scenario="turn", duration_s=5)
    for write, words in ((lambda: sim.write(log), "exists: it is kept (force=True replaces it)"),
                         (lambda: twin.save_vessel("blueboat", log), "unknown format '.csv'"),
                         (lambda: twin.save_vessel("blueboat", tmp_path / "a.txt"), "unknown format '.txt'")):
        with pytest.raises(TwinError, match=__import__("re").escape(words)):
            write()
    assert log.read_text() == "t,lat,lon\n0,59,10\n"
    boat = twin.save_vessel("blueboat", tmp_path / "boat.json")
    with pytest.raises(TwinError, match="exists: it is kept"):
        twin.save_vessel("yellowfish", boat)
    assert twin.load_vessel(str(twin.save_vessel("yellowfish", boat, force=True))).name == "yellowfish"
    truth = tmp_path / "answers.json"  # data of another kind is kept even with force, as the command keeps it
    truth.write_text(json.dumps({"vessel": {}, "effects": [], "segments": []}))
    with pytest.raises(TwinError, match="exists and is a dataset's truth: it is kept, force=True or not"):
        twin.save_vessel("blueboat", truth, force=True)
    assert json.loads(truth.read_text()) == {"vessel": {}, "effects": [], "segments": []}
    sim.write(log, force=True)
    with pytest.raises(TwinError, match="is given twice: give each recording once"):
        twin.evaluate("blueboat", [log, tmp_path / "." / "my_log.csv"])


def test_validation_and_identification_are_tables_too():
    import twin

    val = twin.validate("yellowfish")
    table = val.table()
    assert len(table) == len(val.quantities) and {"quantity", "unit", "rel_diff", "flag"} <= set(table[0])
    assert val.to_dict()["quantities"][0]["quantity"] == val.quantities[0].name
    assert "yellowfish" in str(table).splitlines()[0]


def test_an_identified_twin_says_so_and_its_coefficients_are_a_table(tmp_path):
    import twin

    sim = twin.simulate_run("blueboat", scenario="random", duration_s=60, seed=3)
    sim.write(tmp_path / "run.csv")
    found = twin.identify([tmp_path / "run.csv"], "blueboat", params="thrust_gain", max_evaluations=1, window_s=5.0)
    assert "blueboat, identified (not saved)" in repr(found.vessel)
    twin.save_vessel(found.vessel, tmp_path / "mine.json")
    assert "blueboat, identified from mine.json" in repr(twin.load_vessel(tmp_path / "mine.json"))
    rows = found.table()
    assert [r["coefficient"] for r in rows] == ["thrust_gain"] and rows[0]["prior"] == pytest.approx(1.605, abs=1e-3)


def test_a_coefficient_started_away_from_its_prior_shows_the_prior_and_says_where_it_started():
    """The shipped BlueBoat has no thrust lag: the fit starts its log-normal lag at 0.1 s, and the
    table's prior column shows the vessel's 0, not the start."""
    import twin

    v = twin.load_vessel("blueboat")
    assert v.thrusters.lag_s == 0.0
    est = simfit._started([simfit.Estimate("lag_s", "s", 0.1, 0.05, 0.003, True, "pinned by the recordings")], v,
                          simfit.map_start(v, ["lag_s"]))
    assert est[0].prior == 0.0 and est[0].value == 0.05
    assert est[0].note.startswith("the prior's 0 s started at 0.1 (a log-normal belief needs a magnitude); pinned")


def test_a_log_whose_rows_repeat_the_fix_says_so_and_a_twin_run_does_not(tmp_path):
    """A converted log holds 5-Hz fixes on a 10-Hz grid: `twin info` says half its rows (30 of 59 steps) repeat the
    previous fix; a receiver's own rows (noise on every fix) and a twin run's exact track at rest are
    not said to."""
    from twin.formats import read_recording

    n = 60
    t = np.arange(n) * 0.1
    held_lat = 59.0 + np.repeat(np.arange(n // 2), 2) * 1e-6  # a new fix every other row
    path = tmp_path / "held.csv"
    path.write_text("t,lat,lon,heading_deg\n" + "".join(f"{t[k]:.1f},{held_lat[k]:.8f},10,0\n" for k in range(n)))
    assert "GNSS: 51% of the rows repeat the previous fix (a slower receiver held on the rows)" in \
        read_recording(path).notes
    rng = np.random.default_rng(0)
    fresh = tmp_path / "fresh.csv"
    lat = 59.0 + rng.normal(0, 1e-7, n)
    fresh.write_text("t,lat,lon,heading_deg\n" + "".join(f"{t[k]:.1f},{lat[k]:.9f},10,0\n" for k in range(n)))
    assert not any("repeat the previous fix" in x for x in read_recording(fresh).notes)
    still = tmp_path / "still.csv"  # a twin run at rest: x, y exact and constant
    still.write_text("t,x,y,psi\n" + "".join(f"{t[k]:.1f},0,0,0\n" for k in range(n)))
    assert not any("repeat the previous fix" in x for x in read_recording(still).notes)


def test_a_report_view_never_replaces_runs_recorded_in_rerun_but_replaces_an_earlier_view(tmp_path):
    """An .rrd of runs (`twin simulate --out`, a SITL session's --record) is data; a report's --rrd
    (crosscheck, evaluate, diagnose, view) is a view and replaces an earlier view."""
    runs, view = tmp_path / "run.rrd", tmp_path / "check.rrd"
    assert twin("simulate", "--vessel", "blueboat", "--duration", "2", "--out", runs).returncode == 0
    kept = runs.read_bytes()
    done = twin("crosscheck", "--vessel", "blueboat", "--duration", "2", "--rrd", runs)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert "is a rerun recording of runs: it is kept" in done.stderr and runs.read_bytes() == kept
    view.write_bytes(b"an earlier view")
    done = twin("crosscheck", "--vessel", "blueboat", "--duration", "2", "--rrd", view)
    assert done.returncode == 0 and view.read_bytes()[:4] == b"RRF2"


def test_a_fleet_never_writes_a_report_over_a_twin_kept_beside_its_log(tmp_path):
    logs, out = tmp_path / "logs", tmp_path / "out"
    logs.mkdir(), out.mkdir()
    made = twin("simulate", "--vessel", "blueboat", "--duration", "20", "--scenario", "random", "--out", logs / "boat.csv")
    assert made.returncode == 0, made.stderr
    twin_file = out / "boat.json"
    twin_file.write_text('{"name": "mine", "mjcf": "blueboat.xml", "thrusters": {}}\n')
    done = twin("fleet", logs, "--vessel", "blueboat", "--out", out)
    assert done.returncode == 2 and "the report 'boat.json' would replace a vessel file kept there" in done.stderr
    assert twin_file.read_text() == '{"name": "mine", "mjcf": "blueboat.xml", "thrusters": {}}\n'


def test_a_command_that_fails_at_its_second_output_writes_none_and_replaces_none(monkeypatch, capsys, tmp_path):
    """A full disk at the second file: the first (written fine) does not land either, the file there
    before is kept whole, no temporary is left and no "wrote" line is said."""
    import os
    import sys

    from twin import cli
    from twin.formats import mcap

    first, second = tmp_path / "a.csv", tmp_path / "b.mcap"
    first.write_text("t,x,y\n0,0,0\n")

    def full(fh, *args):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(mcap, "_write", full)
    monkeypatch.setattr(sys, "argv", ["twin", "simulate", "--vessel", "blueboat", "--duration", "2", "--out",
                                      str(first), "--out", str(second), "--force"])
    with pytest.raises(SystemExit) as done:
        cli.main()
    out = capsys.readouterr()
    assert done.value.code == 2 and "No space left on device" in out.err and "wrote" not in out.out
    assert first.read_text() == "t,x,y\n0,0,0\n" and sorted(os.listdir(tmp_path)) == ["a.csv"]


def test_files_land_together_at_the_end_of_a_block_and_never_over_a_device(tmp_path):
    import os

    from twin.files import after_writes, all_or_nothing, write_text_atomic

    said = []
    with all_or_nothing():
        write_text_atomic(tmp_path / "x.txt", "1")
        after_writes(lambda: said.append(sorted(os.listdir(tmp_path))))
        assert not (tmp_path / "x.txt").exists() and not said  # held until the block ends
    assert (tmp_path / "x.txt").read_text() == "1" and said == [["x.txt"]]
    with pytest.raises(KeyError), all_or_nothing():
        write_text_atomic(tmp_path / "x.txt", "2")
        raise KeyError("a failure after the write")
    assert (tmp_path / "x.txt").read_text() == "1" and os.listdir(tmp_path) == ["x.txt"]
    with pytest.raises(SystemExit), all_or_nothing(keep_on=(SystemExit,)):  # a chosen exit code keeps them
        write_text_atomic(tmp_path / "x.txt", "3")
        raise SystemExit(1)
    assert (tmp_path / "x.txt").read_text() == "3"
    pipe, link = tmp_path / "pipe", tmp_path / "link.csv"
    os.mkfifo(pipe)
    link.symlink_to(pipe)
    with pytest.raises(TwinError, match="is not a regular file"):
        write_text_atomic(link, "data")
    assert not pipe.is_file() and pipe.exists()


def test_a_reader_that_leaves_early_loses_no_output(tmp_path):
    """`twin params --vessel blueboat --write-model FILE | head -1`: params prints before its file lands;
    once the pipe's reader has gone its prints go nowhere and the file is still written, with exit code
    0 (as for identify and diagnose, which print before they write)."""
    import os
    import subprocess
    import sys

    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader has gone before the first line
    try:
        done = subprocess.run([sys.executable, "-m", "twin", "params", "--vessel", "blueboat", "--write-model",
                               str(tmp_path / "mine.json")], stdout=write_end, stderr=write_end, cwd=tmp_path,
                              timeout=300)
    finally:
        os.close(write_end)
    assert done.returncode == 0
    assert json.loads((tmp_path / "mine.json").read_text())["name"] == "blueboat"
