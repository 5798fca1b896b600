"""What a user is told about partial input and existing files: convert keeps an existing file, a CSV
with half a column pair or without inputs, GNSS or heading is told which columns it needs, identify
says whether it applied the compass offset (with info's caveat), and `twin info` counts gaps in
good English."""
from pathlib import Path

import numpy as np
import pytest
from twin_command import twin

from twin.cli.ident import calibration_line
from twin.errors import TwinError
from twin.fit.calibrate import LogCalibration
from twin.formats import read_recording
from twin.prepare import prepare
from twin.recording import format_summary

ONE_LEG = "one straight leg: no drift fitted (a current across it reads as offset)"


def write_csv(path: Path, columns: dict[str, np.ndarray], t: np.ndarray) -> Path:
    """A generic CSV with a t column and `columns`, one row per time."""
    rows = [",".join(["t", *columns])]
    rows += [",".join([f"{t[k]:.2f}", *(f"{v[k]:.8f}" for v in columns.values())]) for k in range(len(t))]
    path.write_text("\n".join(rows) + "\n")
    return path


def straight(n: int = 300, dt: float = 0.1) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A boat going north at 1 m/s, heading 0°, both thrusters at 1600 µs."""
    t = np.arange(n) * dt
    return t, {"lat": 59.0 + t / 111_000.0, "lon": np.full(n, 10.0), "heading_deg": np.zeros(n),
               "pwm_left": np.full(n, 1600.0), "pwm_right": np.full(n, 1600.0)}


# -------------------------------------------------------------------------------- 1. convert keeps a file


def test_convert_refuses_to_replace_an_existing_file_without_force(tmp_path):
    t, cols = straight()
    original = write_csv(tmp_path / "a.csv", cols, t)
    text = original.read_text()
    assert twin("convert", original, tmp_path / "b.mcap").returncode == 0
    done = twin("convert", tmp_path / "b.mcap", original)
    assert done.returncode == 2
    assert done.stderr.strip() == f"error: output '{original}' exists: it is kept (--force replaces it)"
    assert original.read_text() == text  # the 10 Hz original, not the grid's copy
    forced = twin("convert", tmp_path / "b.mcap", original, "--force")
    assert forced.returncode == 0 and f"wrote {original}" in forced.stdout


def test_convert_force_never_replaces_its_input(tmp_path):
    t, cols = straight()
    original = write_csv(tmp_path / "a.csv", cols, t)
    text = original.read_text()
    done = twin("convert", original, original, "--force")
    assert done.returncode == 2 and "is the input" in done.stderr and len(done.stderr.strip().splitlines()) == 1
    assert original.read_text() == text


# ------------------------------------------------------------------------------ 2. half a pair of columns


@pytest.mark.parametrize("kept, dropped", [("pwm_left", "pwm_right"), ("pwm_right", "pwm_left"), ("lat", "lon"),
                                           ("north", "east"), ("prop_rps", "rudder_deg"),
                                           ("wind_speed", "wind_from_deg")])
def test_csv_with_half_a_column_pair_is_refused_by_name(tmp_path, kept, dropped):
    t, cols = straight()
    cols.pop(dropped, None)
    cols.setdefault(kept, np.ones(len(t)))
    if kept == "north":  # positions from north alone, not lat/lon
        cols.pop("lat"), cols.pop("lon")
    path = write_csv(tmp_path / "x.csv", cols, t)
    with pytest.raises(TwinError) as err:
        read_recording(path)
    assert str(err.value) == f"{path}: has {kept} but no {dropped} column"  # the path as given
    done = twin("info", path)
    assert done.returncode == 2 and done.stderr.strip() == f"error: {path}: has {kept} but no {dropped} column"


def test_csv_with_both_columns_of_each_pair_reads(tmp_path):
    t, cols = straight()
    rec = read_recording(write_csv(tmp_path / "x.csv", cols, t))
    assert len(rec.pwm) == len(t) and len(rec.gnss) == len(t)


@pytest.mark.parametrize("dropped, message", [
    (("lat", "lon"), "x.csv: no GNSS samples, from which the track and the velocities are read (a CSV gives GNSS in columns lat,lon or north,east)"),
    (("heading_deg",), "x.csv: no heading samples, from which the track and the velocities are read (a CSV gives the heading in a column "
                       "heading_deg or psi)"),
    (("lat", "lon", "heading_deg"), "x.csv: no GNSS and heading samples, from which the track and the velocities are read (a CSV gives GNSS in "
                                    "columns lat,lon or north,east and the heading in a column heading_deg or psi)"),
])
def test_csv_without_gnss_or_heading_names_the_columns_it_needs(tmp_path, dropped, message):
    t, cols = straight()
    for name in dropped:
        cols.pop(name)
    path = write_csv(tmp_path / "x.csv", cols, t)
    with pytest.raises(TwinError) as err:
        prepare(read_recording(path))
    assert str(err.value) == message
    done = twin("view", path, "--out", tmp_path / "x.rrd")
    assert done.returncode == 2 and done.stderr.strip() == f"error: {message}"


def test_a_csv_whose_every_fix_was_dropped_says_why_not_which_columns(tmp_path):
    """The columns are there; every value in them was refused: the reason and count, not a column hint."""
    t, cols = straight()
    cols["lat"] = np.full(len(t), 91.0)
    path = write_csv(tmp_path / "x.csv", cols, t)
    with pytest.raises(TwinError) as err:
        prepare(read_recording(path))
    assert str(err.value) == ("x.csv: no GNSS samples, from which the track and the velocities are read (every sample read was dropped: "
                              f"latitude outside ±90°: {len(t)})")


# ---------------------------------------------------------------- 3. identify's compass calibration line


def test_calibration_line_says_whether_applied_with_info_caveat():
    one_leg = LogCalibration("x.csv", -10.6, 1.0, 1, 10.0, None, ONE_LEG)
    head = "x.csv: compass offset -10.6° ± 1.0° from 1 straight stretch (10 s under way)"
    assert calibration_line(one_leg, applied=True) == f"{head}; offset applied [{ONE_LEG}]"
    assert calibration_line(one_leg, applied=False) == f"{head}; offset not applied (--no-calibration) [{ONE_LEG}]"
    assert calibration_line(one_leg) == f"{head} [{ONE_LEG}]"  # twin info: it applies none
    legs = LogCalibration("x.csv", -10.6, 1.0, 3, 10.0, (0.1, -0.2), "")
    assert calibration_line(legs, applied=True).endswith("E -0.200 m/s; offset applied")
    none = LogCalibration("x.csv", None, None, 0, 0.0, None, "no straight running under way")
    assert calibration_line(none, applied=True) == "x.csv: compass offset not applied (no straight running under way)"
    # stretches that disagree more than their pieces say: told beside the pieces' σ (which decides)
    apart = LogCalibration("x.csv", 7.0, 0.6, 2, 31.0, None, "", stretch_sigma_deg=4.4)
    assert "± 0.6° from 2 straight stretches (31 s under way); its stretches alone give ± 4.4°" in apart.text()
    assert "alone" not in LogCalibration("x.csv", 7.0, 0.6, 2, 31.0, None, "", stretch_sigma_deg=0.3).text()
    # an offset only a turned mount or a misread track gives: said with both
    swapped = calibration_line(LogCalibration("x.csv", 72.4, 2.3, 1, 10.0, None, ""), applied=True)
    assert swapped.endswith("offset applied (an offset this large is a compass mounted turned, or a track read "
                            "wrongly: lat and lon swapped, or a heading in another convention)")


def test_calibration_line_names_the_offset_a_twin_was_identified_under():
    from dataclasses import replace

    from twin.vessel import load as load_vessel

    boat = load_vessel("blueboat")
    twin_of = replace(boat, sensors=replace(boat.sensors, heading_bias_by_log_deg=(("x.csv", 7.0),)))
    read_now = LogCalibration("x.csv", 4.8, 0.2, 2, 6.0, None, "")
    line = calibration_line(read_now, applied=True, twin=twin_of)
    assert line.endswith("the twin was identified with +7.0° for this log (its straight stretches are chosen by "
                         "the sway balance of the twin that reads them); offset applied")
    assert "identified with" not in calibration_line(LogCalibration("x.csv", 7.0, 0.2, 2, 6.0, None, ""),
                                                     applied=True, twin=twin_of)  # the same: nothing to say
    assert "identified with" not in calibration_line(read_now, applied=True, twin=boat)  # no entry for it
    none = LogCalibration("x.csv", None, None, 0, 0.0, None, "no straight running under way")
    assert calibration_line(none, twin=twin_of).endswith("identified with +7.0° for this log (its straight "
                                                         "stretches are chosen by the sway balance of the twin that "
                                                         "reads them)")


def test_a_logs_compass_offset_says_how_far_its_straight_stretches_disagree(shared_dir):
    """Run 225's two straight stretches give offsets apart by more than the spread of their 2-s
    pieces: the σ between stretches is told (the offset read with another twin, whose stretches are
    others, lands inside it)."""
    from twin.fit.calibrate import kinematic_calibrations
    from twin.engine.mjcf import compile_vessel
    from twin.formats import read_recording
    import twin.vessel as vessel_mod

    rec = read_recording(shared_dir / "data" / "blueboat" / "fixed_00000225.csv")
    c = kinematic_calibrations([rec], compile_vessel(vessel_mod.load("blueboat")))[0]
    assert c.stretches == 2 and c.stretch_sigma_deg is not None and c.stretch_sigma_deg > 3 * c.sigma_deg


# ------------------------------------------------------------------------------ 4. gaps, in good English


def gappy(tmp_path, gaps: int) -> Path:
    """A straight run with `gaps` silences of 3 s in every stream."""
    t, cols = straight(600)
    keep = np.ones(len(t), bool)
    for k in range(gaps):
        keep[100 + 200 * k:130 + 200 * k] = False
    return write_csv(tmp_path / "g.csv", {k: v[keep] for k, v in cols.items()}, t[keep])


def test_info_says_one_gap_and_does_not_call_gaps_dropped(tmp_path):
    text = format_summary(read_recording(gappy(tmp_path, 1)).summary())
    assert "1 gap > 1 s (longest 3.1 s)" in text and "1 gaps" not in text
    assert "dropped" not in text and "dropouts" not in text  # nothing was discarded: the gap is on its stream's line
    assert "2 gaps > 1 s" in format_summary(read_recording(gappy(tmp_path, 2)).summary())


def test_a_gap_is_counted_in_the_recording_dropped_list(tmp_path):
    rec = read_recording(gappy(tmp_path, 2))
    assert dict(rec.dropped)["gnss: dropouts > 1 s"] == 2


def test_a_csv_without_inputs_is_told_the_columns_not_an_ardupilot_option(tmp_path):
    t, cols = straight()
    del cols["pwm_left"], cols["pwm_right"]
    done = twin("identify", write_csv(tmp_path / "no_inputs.csv", cols, t), "--vessel", "blueboat",
                "--out", tmp_path / "twin.json")
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert "columns pwm_left,pwm_right (or prop_rps,rudder_deg)" in done.stderr and "--channels" not in done.stderr


def test_dataset_says_the_log_span_twin_info_reports(tmp_path):
    """`twin dataset` counts its manoeuvres' seconds and the log's whole span, gaps between segments
    included, which is what `twin info` calls the recording's length."""
    import re

    out = tmp_path / "two.csv"
    made = twin("dataset", "--vessel", "blueboat", "--segments", "2", "--seed", "1", "--out", out)
    assert made.returncode == 0, made.stderr
    manoeuvres, span = map(float, re.search(r"(\d+) s of manoeuvres in a log of (\d+) s", made.stdout).groups())
    info = twin("info", out)
    length = float(re.search(r"\(csv\): ([0-9.]+) s", info.stdout).group(1))
    assert manoeuvres < span and span == pytest.approx(length, abs=0.5)


def test_a_bad_file_in_a_folder_is_named_by_its_path_and_a_bad_mcap_as_not_mcap(tmp_path):
    folder = tmp_path / "logs"
    folder.mkdir()
    (folder / "wrong.csv").write_text("a;b\n1;2\n")
    (tmp_path / "g.mcap").write_bytes(bytes(range(256)))
    with pytest.raises(TwinError) as bad_csv:
        read_recording(folder / "wrong.csv")
    assert str(bad_csv.value).startswith(f"{folder / 'wrong.csv'}: not a recognised recording")
    with pytest.raises(TwinError, match="not an MCAP file: it does not begin with MCAP's magic bytes"):
        read_recording(tmp_path / "g.mcap")


def test_force_does_not_replace_a_log_under_the_dataset_truth_that_describes_it(tmp_path):
    """A recording replaced under its dataset's truth would leave the truth describing another log;
    the run that writes that truth itself may replace both."""
    import json

    from twin.files import RUNS, check_new

    t, cols = straight(20)
    log = write_csv(tmp_path / "my_log.csv", cols, t)
    truth = tmp_path / "my_log.truth.json"
    truth.write_text(json.dumps({"vessel": {}, "effects": [], "segments": []}))
    with pytest.raises(TwinError, match="is described by a dataset.s truth"):
        check_new([log], True, "--out", RUNS)
    check_new([log], True, "output", RUNS, truth=truth)  # the dataset's own run rewrites both
    link = tmp_path / "link.csv"
    link.symlink_to(log.name)
    with pytest.raises(TwinError, match="is described by a dataset.s truth"):  # a link writes the log it names
        check_new([link], True, "--out", RUNS)
    import twin

    kept = log.read_text()
    sim = twin.simulate_run("blueboat", scenario="turn", duration_s=3)
    for path in (log, link):  # the API keeps it as the command does
        with pytest.raises(TwinError, match="is described by a dataset.s truth"):
            sim.write(path, force=True)
    assert log.read_text() == kept
    truth.unlink()
    check_new([log], True, "--out", RUNS)  # no truth: --force replaces the log
    named = tmp_path / "answers.json"  # `twin dataset --truth answers.json`: the truth names its logs
    named.write_text(json.dumps({"logs": ["my_log.csv"], "vessel": {}, "effects": [], "segments": []}))
    with pytest.raises(TwinError, match="described by a dataset's truth .*answers.json"):
        check_new([log], True, "--out", RUNS)
    check_new([log], True, "output", RUNS, truth=named)
    import os

    os.mkfifo(tmp_path / "pipe.json")  # not opened (it would block): only files are read
    elsewhere = tmp_path / "day"
    elsewhere.mkdir()
    (elsewhere / "q.csv").symlink_to(log)  # a link's truth, in the link's folder, names the file it wrote
    (elsewhere / "answers.json").write_text(json.dumps({"logs": ["../my_log.csv"], "vessel": {}, "effects": [],
                                                        "segments": []}))
    with pytest.raises(TwinError, match="described by a dataset's truth .*day/answers.json"):
        check_new([elsewhere / "q.csv"], True, "--out", RUNS, truth=named)
    (elsewhere / "answers.json").unlink()
    other = tmp_path / "other.json"  # a truth of another log in the folder does not hold this one
    named.rename(other)
    other.write_text(json.dumps({"logs": ["my_log.csv.bak"], "vessel": {}, "effects": [], "segments": []}))
    check_new([log], True, "--out", RUNS)


def test_a_column_named_in_another_case_is_said_to_be_unread(tmp_path):
    path = tmp_path / "cased.csv"
    path.write_text("t,lat,lon,Heading_Deg,PWM_left,pwm_right,Notes\n0,59,10,5,1500,1500,1\n0.1,59.00001,10,5,1500,1500,2\n")
    with pytest.raises(TwinError, match="has pwm_right but no pwm_left"):
        read_recording(path)
    path.write_text("t,lat,lon,Heading_Deg,Notes\n0,59,10,5,1\n0.1,59.00001,10,5,2\n")
    notes = read_recording(path).notes
    assert "columns not read, names being case-sensitive: Heading_Deg (read as heading_deg only when named so)" in notes
    assert not any("Notes" in n for n in notes)  # a column of the user's own is no mistake


def test_a_named_file_is_read_by_its_content_and_a_folder_by_its_names(tmp_path):
    """One rule for every command: a CSV log saved as .txt is a recording wherever it is named, as the
    readers read it; a folder gives only its files named as recordings; a named file that is none is
    refused before any work."""
    from twin.cli.app import recordings_in

    t, cols = straight(20)
    log = write_csv(tmp_path / "run.csv", cols, t)
    as_text = tmp_path / "run.txt"
    as_text.write_bytes(log.read_bytes())
    folder = tmp_path / "day"
    folder.mkdir()
    (folder / "a.csv").write_bytes(log.read_bytes())
    (folder / "notes.txt").write_bytes(log.read_bytes())
    assert recordings_in([as_text, folder]) == [as_text, folder / "a.csv"]
    for text in ("rode out at ten and back at noon\n", "# Notes, day one\n"):  # a comma is no log yet
        (tmp_path / "notes.txt").write_text(text)
        with pytest.raises(TwinError, match="notes.txt': not a recognised recording"):
            recordings_in([folder, tmp_path / "notes.txt"])
