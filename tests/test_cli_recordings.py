"""`twin info`, `twin convert`, `twin view` on recordings the twin writes itself (fresh clone)."""
import sys

import numpy as np
import pytest

from twin.prepare import prepare
from twin.formats import read_recording
import twin_command


def twin(*args):
    return twin_command.twin(*args)


@pytest.fixture(scope="module")
def sim_tlog(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    p = twin("simulate", "--vessel", "yellowfish", "--scenario", "zigzag", "--duration", "40", "--out", d / "z.tlog",
             "--out", d / "z.csv", "--out", d / "z.bin", "--out", d / "z.mcap")
    assert p.returncode == 0, p.stderr
    return d


def test_info_summarises_a_simulated_tlog(sim_tlog):
    p = twin("info", sim_tlog / "z.tlog")
    assert p.returncode == 0, p.stderr
    assert "gnss" in p.stdout and "5.00 Hz" in p.stdout and "50.00 Hz" in p.stdout


def test_tlog_round_trip_recovers_the_twin_state(sim_tlog):
    """The .tlog carries GNSS at the antenna; preparing it with the lever arm gives back CO."""
    from twin.run import read_csv

    truth = read_csv(sim_tlog / "z.csv")
    prep = prepare(read_recording(sim_tlog / "z.tlog"), lever_arm_OP_m=(0.275, -0.2625))
    k = np.searchsorted(truth.t, prep.t - 1e-6)
    ok = (k < len(truth.t)) & (prep.t > 2) & (prep.t < truth.t[-1] - 2)
    # causal sync holds the last 5 Hz fix: compare where a fresh fix lands on the grid
    fresh = ok & (np.abs(np.round(prep.t / 0.2) * 0.2 - prep.t) < 1e-6)
    # the local origin is the antenna's first fix: CO starts at OP = (0.275, -0.2625) m from it
    north_err = prep.north[fresh] - 0.275 - (truth.eta[k[fresh], 0] - truth.eta[0, 0])
    east_err = prep.east[fresh] + 0.2625 - (truth.eta[k[fresh], 1] - truth.eta[0, 1])
    assert np.max(np.abs(north_err)) < 0.02 and np.max(np.abs(east_err)) < 0.02
    assert np.corrcoef(prep.r[ok], truth.nu[k[ok], 2])[0, 1] > 0.98
    np.testing.assert_allclose(prep.pwm[ok], truth.pwm_us[k[ok]], atol=1.0)


def test_convert_and_view(sim_tlog, tmp_path):
    p = twin("convert", sim_tlog / "z.tlog", tmp_path / "z.mcap")
    assert p.returncode == 0, p.stderr
    assert "every stream at its own times, as read" in p.stdout
    # every sample where the reader put it: no fix held on a grid (its rows up to 0.2 s late), no heading thinned
    a, b = read_recording(sim_tlog / "z.tlog"), read_recording(tmp_path / "z.mcap")
    for name in ("gnss", "heading", "pwm", "imu"):
        np.testing.assert_allclose(getattr(b, name).t, getattr(a, name).t, atol=1e-6, err_msg=name)
    np.testing.assert_array_equal(b.pwm["left_us"], a.pwm["left_us"])
    np.testing.assert_allclose(b.gnss["lat_deg"], a.gnss["lat_deg"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.heading["psi_rad"], a.heading["psi_rad"], atol=1e-9)
    # synchronised on request (as it says): each 5-Hz fix held on the 0.1-s grid, the 50-Hz heading thinned
    p = twin("convert", sim_tlog / "z.tlog", tmp_path / "g.mcap", "--grid-dt", "0.1")
    assert p.returncode == 0, p.stderr
    assert "gnss recorded at 5 Hz, each sample held until the next (rows up to 0.2 s after it was taken)" in p.stdout
    g = read_recording(tmp_path / "g.mcap")
    at_fix = np.searchsorted(g.gnss.t, a.gnss.t - 1e-6)
    np.testing.assert_allclose(g.gnss.t[at_fix], a.gnss.t, atol=1e-6)
    np.testing.assert_allclose(g.gnss["lat_deg"][at_fix], a.gnss["lat_deg"], rtol=0, atol=1e-7)
    thinned = np.searchsorted(a.heading.t, g.heading.t - 1e-6)
    np.testing.assert_allclose(g.heading["psi_rad"], a.heading["psi_rad"][thinned], atol=1e-6)
    # the output named as every other command names it: the same file
    p = twin("convert", sim_tlog / "z.tlog", "--out", tmp_path / "z2.mcap")
    assert p.returncode == 0, p.stderr
    np.testing.assert_array_equal(read_recording(tmp_path / "z2.mcap").gnss["lat_deg"], b.gnss["lat_deg"])
    p = twin("view", tmp_path / "z.mcap", "--sim", "--vessel", "yellowfish", "--out", tmp_path / "v.rrd",
             "--png", tmp_path / "v.png")
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "v.rrd").stat().st_size > 1000
    assert (tmp_path / "v.png").read_bytes()[:4] == b"\x89PNG"


def test_bad_recordings_exit_2(tmp_path):
    junk = tmp_path / "junk.tlog"
    junk.write_bytes(bytes(range(256)) * 10)
    p = twin("info", junk)
    assert p.returncode == 2 and "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1
    p = twin("convert", junk, tmp_path / "x.bin")
    assert p.returncode == 2 and "junk.tlog" in p.stderr
    assert not (tmp_path / "x.bin").exists()


def test_convert_refuses_a_grid_that_would_write_an_unreasonable_number_of_rows(sim_tlog, tmp_path, monkeypatch):
    """--grid-dt 1e-6 on a 30-s log wrote 30 million rows (1.5 GB) in over 90 s: refused before any is
    written, with the rows it would have and the finest grid this log allows (a tenth of its 10 Hz streams'
    period, or the row cap on a long log); that finest grid itself is converted."""
    import twin.cli.recordings as recordings

    out = tmp_path / "fine.csv"
    p = twin("convert", sim_tlog / "z.csv", out, "--grid-dt", "1e-6")
    assert p.returncode == 2 and not out.exists()
    assert p.stderr == ("error: --grid-dt 1e-06 on z.csv: 40,000,001 rows for its 40.0 s; the finest grid for this "
                        "log is 0.01 s (a tenth of the 0.1 s sample period of its fastest synchronised stream: on a "
                        "finer grid each sample fills more than ten rows)\n")
    assert twin("convert", sim_tlog / "z.csv", out, "--grid-dt", "0.01").returncode == 0
    monkeypatch.setattr(recordings, "MAX_GRID_ROWS", 1000)  # a long log: the row cap is the tighter bound
    p = twin("convert", sim_tlog / "z.csv", tmp_path / "long.csv", "--grid-dt", "0.01")
    assert p.returncode == 2 and "4,001 rows for its 40.0 s; the finest grid for this log is 0.04 s (1,000 rows " \
        "at most)" in p.stderr and not (tmp_path / "long.csv").exists()


def test_a_device_or_a_pipe_is_said_not_a_regular_file_not_missing(sim_tlog, tmp_path):
    """/dev/null, /dev/zero and a FIFO exist: "no such file" sent the user looking for a typo. A FIFO is
    never opened (reading it would wait for a writer)."""
    import os

    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    for path in ("/dev/null", "/dev/zero", fifo):
        p = twin("info", path)
        assert p.returncode == 2 and p.stderr == (f"error: {path}: not a regular file (a device, a pipe or a socket): "
                                                  "give a recording file\n"), p.stderr
    p = twin("info", sim_tlog / "z.csv", fifo)  # the good log is still summarised
    assert p.returncode == 2 and "== " in p.stdout and "pipe.csv: not a regular file" in p.stderr
    for command in (("convert", fifo, tmp_path / "c.csv"), ("view", fifo, "--out", tmp_path / "v.rrd")):
        p = twin(*command)
        assert p.returncode == 2 and "pipe.csv: not a regular file" in p.stderr, p.stderr
    assert twin("info", tmp_path / "absent.csv").stderr == f"error: {tmp_path / 'absent.csv'}: no such file\n"
    assert not (tmp_path / "c.csv").exists() and not (tmp_path / "v.rrd").exists()


def test_view_refuses_one_recording_given_twice_as_identify_does(sim_tlog, tmp_path):
    import shutil

    copy = tmp_path / "copy.csv"
    shutil.copy(sim_tlog / "z.csv", copy)
    out = tmp_path / "v.rrd"
    p = twin("view", sim_tlog / "z.csv", sim_tlog / "z.csv", "--out", out)
    assert p.returncode == 2 and p.stderr == f"error: '{sim_tlog / 'z.csv'}' is given twice: give each recording once\n"
    p = twin("view", sim_tlog / "z.csv", copy, "--out", out)
    assert p.returncode == 2 and "holds the same bytes as" in p.stderr and not out.exists()


def test_convert_tlog_to_dataflash_and_back(sim_tlog, tmp_path):
    p = twin("convert", sim_tlog / "z.tlog", tmp_path / "z.bin")
    assert p.returncode == 0, p.stderr
    a = prepare(read_recording(sim_tlog / "z.tlog"))
    b = prepare(read_recording(tmp_path / "z.bin"))
    n = min(len(a.t), len(b.t)) - 5
    np.testing.assert_allclose(b.pwm[:n], a.pwm[:n], atol=1.0)
    assert np.corrcoef(a.r[5:n], b.r[5:n])[0, 1] > 0.99


def test_model_smoother_beats_savitzky_golay_on_noisy_gnss():
    """With the vessel's own model and 0.3 m GNSS noise, velocities are far closer to the truth."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "scripts" / "validate_smoother.py"
    spec = importlib.util.spec_from_file_location("validate_smoother", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    row = mod.compare("yellowfish", seed=3, sigma_gnss_m=0.3, model_error=1.0)
    for k in "uvr":
        assert row[f"{k}_rmse_model"] < 0.6 * row[f"{k}_rmse_savgol"], k
    assert row["u_rmse_model"] < 0.06


def test_the_twins_own_csv_is_a_recording(sim_tlog, tmp_path):
    """`twin simulate --out z.csv` (t,x,y,psi,u,v,r,...) is read by info/view/convert, though it has no GNSS."""
    p = twin("info", sim_tlog / "z.csv")
    assert p.returncode == 0, p.stderr
    assert "gnss         401 samples at 10.00 Hz" in p.stdout and "body origin" in p.stdout
    p = twin("convert", sim_tlog / "z.csv", tmp_path / "z.mcap")
    assert p.returncode == 0, p.stderr
    p = twin("view", sim_tlog / "z.csv", "--out", tmp_path / "z.rrd")
    assert p.returncode == 0 and (tmp_path / "z.rrd").stat().st_size > 1000, p.stderr
    # by default beside a simulation's own z.rrd in the working folder, never over it
    kept = (tmp_path / "z.rrd").read_bytes()
    p = twin_command.twin("view", sim_tlog / "z.csv", cwd=tmp_path)
    assert p.returncode == 0 and (tmp_path / "z.view.rrd").stat().st_size > 1000, p.stderr
    assert (tmp_path / "z.rrd").read_bytes() == kept


def _no_gnss_recording():
    """Heading 20 Hz, PWM 10 Hz, gyro 20 Hz, battery 1 Hz and parameters, no GNSS: an ROV or bench log."""
    from twin.recording import Recording, Stream

    th, tp, tb = np.arange(400) * 0.05, 0.013 + np.arange(200) * 0.1, np.arange(20) * 1.0
    rec = Recording(source="bench", kind="synthetic")
    rec.heading = Stream(th, {"psi_rad": np.angle(np.exp(1j * (2.5 + 0.2 * th)))})
    rec.imu = Stream(th, {"yaw_rate_rads": 0.2 + 0.01 * np.sin(th)})
    rec.pwm = Stream(tp, {"left_us": 1500.0 + np.round(200 * np.sin(tp)), "right_us": np.full(200, 1650.0)})
    rec.battery = Stream(tb, {"voltage_v": 16.2 - 0.01 * tb})
    rec.parameters = {"FRAME_CLASS": 2.0, "CRUISE_SPEED": 1.5}
    return rec


@pytest.mark.parametrize("suffix", [".csv", ".mcap", ".tlog", ".bin"])
def test_convert_a_log_without_gnss(tmp_path, suffix):
    """Convert must not need GNSS and heading, or 3 of the 5 shared ArduPilot logs could not be
    converted; a log without GNSS is written with its streams at their own times."""
    from twin.formats import write_recording

    rec = _no_gnss_recording()
    write_recording(rec, tmp_path / "in.bin")
    p = twin("convert", tmp_path / "in.bin", tmp_path / f"out{suffix}", "--grid-dt", "0.1")
    assert p.returncode == 2 and not (tmp_path / f"out{suffix}").exists()
    assert p.stderr == ("error: --grid-dt 0.1: in.bin cannot be put on a grid (no GNSS samples, from which the track "
                        "and the velocities are read); without --grid-dt every stream keeps its own times\n")
    p = twin("convert", tmp_path / "in.bin", tmp_path / f"out{suffix}")
    assert p.returncode == 0, p.stderr
    assert "every stream at its own times, as read" in p.stdout
    back = read_recording(tmp_path / f"out{suffix}")
    assert len(back.gnss) == 0 and len(back.heading) == len(rec.heading) and len(back.pwm) == len(rec.pwm)
    np.testing.assert_allclose(back.pwm.t - back.pwm.t[0], rec.pwm.t - rec.pwm.t[0], atol=2e-6)
    np.testing.assert_array_equal(back.pwm["left_us"], rec.pwm["left_us"])
    np.testing.assert_allclose(back.battery["voltage_v"], rec.battery["voltage_v"], atol=1e-5)
    if suffix != ".tlog":  # a tlog's yaw rate rides in ATTITUDE, at the heading times: the same here
        np.testing.assert_allclose(back.imu["yaw_rate_rads"], rec.imu["yaw_rate_rads"], atol=1e-6)
    if suffix == ".csv":
        assert back.parameters == {} and "the CSV layout has no place for the 8 parameters" in p.stderr  # 2 + mapping
    else:
        assert back.parameters["CRUISE_SPEED"] == 1.5 and back.parameters["FRAME_CLASS"] == 2.0


def test_a_converted_real_recording_is_not_called_simulated(sim_tlog, tmp_path):
    """A tlog converted to MCAP read back with "positions are the body origin (simulated)"."""
    p = twin("convert", sim_tlog / "z.tlog", tmp_path / "real.mcap", "--grid-dt", "0.1")
    assert p.returncode == 0, p.stderr
    assert "gnss, heading, pwm synchronised on a 0.1 s grid" in p.stdout
    real = read_recording(tmp_path / "real.mcap")
    assert not any("body origin" in n or "simulated" in n for n in real.notes), real.notes
    assert real.gnss.has("lat_deg", "lon_deg") and "positions" not in real.meta
    simulated = read_recording(sim_tlog / "z.mcap")
    assert any("body origin (a simulated run)" in n for n in simulated.notes)
    # the antenna track of the conversion is the tlog's own, sample for sample on the grid
    src = prepare(read_recording(sim_tlog / "z.tlog"))
    again = prepare(real)
    n = min(len(src.t), len(again.t))
    np.testing.assert_allclose(again.north[:n], src.north[:n], atol=0.02)


def test_a_truncated_dataflash_log_says_so(sim_tlog, tmp_path):
    data = (sim_tlog / "z.bin").read_bytes()
    (tmp_path / "half.bin").write_bytes(data[: len(data) // 2 + 7])
    p = twin("info", tmp_path / "half.bin")
    assert p.returncode == 0, p.stderr
    assert "last message cut short (the log is truncated): 1" in p.stdout
    assert "truncated" not in twin("info", sim_tlog / "z.bin").stdout


def test_info_reports_every_file_and_exits_2_if_any_failed(sim_tlog, tmp_path):
    (tmp_path / "one.csv").write_text("t,lat,lon,heading_deg\n0,37.1,-5.9,10\n")
    (tmp_path / "folder").mkdir()
    p = twin("info", sim_tlog / "z.tlog", tmp_path / "one.csv", tmp_path / "folder", sim_tlog / "z.csv")
    assert p.returncode == 2
    assert p.stdout.count("== ") == 2 and "z.csv (csv)" in p.stdout  # the good file after the bad ones too
    errors = p.stderr.strip().splitlines()
    assert len(errors) == 2 and all(e.startswith("error: ") for e in errors) and "Traceback" not in p.stderr
    assert "one.csv: nothing usable" in errors[0] and "is a folder with no recordings in it" in errors[1]
    p = twin("info", sim_tlog)  # a folder stands for the recordings in it
    assert p.returncode == 0 and p.stdout.count("== ") == 4, p.stderr


def test_view_writes_into_the_working_folder_not_beside_the_input(sim_tlog, tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    (data / "z.tlog").write_bytes((sim_tlog / "z.tlog").read_bytes())
    work = tmp_path / "work"
    work.mkdir()
    p = twin_command.twin("view", data / "z.tlog", cwd=work)
    assert p.returncode == 0, p.stderr
    assert sorted(x.name for x in data.iterdir()) == ["z.tlog"] and (work / "z.view.rrd").stat().st_size > 1000


def test_view_replay_without_pwm_names_the_file(tmp_path):
    (tmp_path / "nopwm.csv").write_text("t,north,east,psi\n" + "".join(f"{0.1 * k:.1f},{0.1 * k:.2f},0,0\n"
                                                                      for k in range(50)))
    p = twin("view", tmp_path / "nopwm.csv", "--sim", "--vessel", "yellowfish", "--out", tmp_path / "v.rrd")
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1
    assert p.stderr.startswith("error: nopwm.csv: the recording has no thruster PWM to replay")


def test_view_sim_plots_the_logged_thrust_from_the_recorded_pwm(sim_tlog, tmp_path, monkeypatch):
    """Thrust is "twin against log" like u, v, r: the recording's thrust is the twin's thruster map
    on its PWM, labelled so; replaying a twin's own log, the two agree."""
    import twin.outputs
    import twin.viz.rerun_log as rerun_log
    import twin.cli as cli

    written, labels = {}, []
    real_write, real_series = twin.outputs.write, rerun_log.rr.SeriesLines

    def spy_write(runs, path, **kwargs):
        written.update(runs)
        real_write(runs, path, **kwargs)

    def spy_series(*args, names=None, **kwargs):
        labels.extend(names or [])
        return real_series(*args, names=names, **kwargs)

    monkeypatch.setattr(twin.outputs, "write", spy_write)
    monkeypatch.setattr(rerun_log.rr, "SeriesLines", spy_series)
    monkeypatch.setattr(sys, "argv", ["twin", "view", str(sim_tlog / "z.tlog"), "--sim", "--vessel", "yellowfish",
                                      "--out", str(tmp_path / "v.rrd")])
    cli.main()
    real, sim = written["recorded"], written["twin"]
    assert np.all(np.isfinite(real.thrust_n)) and np.ptp(real.thrust_n[:, 0]) > 10.0  # the zig-zag's steps
    k = np.searchsorted(sim.t, real.t - 1e-6)
    ok = k < len(sim.t)
    # the recorded PWM is the twin's at 10 Hz: the thrust agrees but where a step falls between samples
    assert np.median(np.abs(real.thrust_n[ok] - sim.thrust_n[k[ok]])) < 0.5
    assert "recorded (yellowfish thrust map on the recorded PWM)" in labels


def test_info_with_a_vessel_reports_each_logs_compass_calibration(shared_dir, tmp_path):
    """The kinematic calibration identify, evaluate and diagnose apply, shown by `twin info` (README:
    run 225 +6.9° ± 0.6° from its own legs; run 226 spins in place and has no straight running), and
    whether the compass error follows the throttle (fit/calibrate.throttle_dependence); a log
    without GNSS is named, not fatal; an unknown vessel is refused before any work."""
    runs = shared_dir / "data" / "blueboat"
    p = twin("info", runs / "fixed_00000225.csv", runs / "fixed_00000226.csv", "--vessel", "blueboat")
    assert p.returncode == 0, p.stderr
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("calibration:")]
    assert len(lines) == 3
    assert "fixed_00000225.csv: compass offset +6.9° ± 0.6°" in lines[0]
    assert "fixed_00000226.csv: compass offset not applied" in lines[1] and "straight running" in lines[1]
    # two straight stretches ahead: too few to tell whether the compass error follows the throttle
    assert lines[2].startswith("calibration: compass error following the throttle: not told (fewer than 10")
    p = twin("info", shared_dir / "data" / "ardupilot" / "ardusub_small.BIN", "--vessel", "yellowfish")
    assert p.returncode == 0 and "ardusub_small.BIN: no compass calibration (it needs GNSS and heading)" in p.stdout
    p = twin("info", runs / "fixed_00000225.csv", "--vessel", "nosuch")
    assert p.returncode == 2 and p.stderr.startswith("error: unknown vessel") and "==" not in p.stdout


def test_info_with_a_vessel_on_a_log_without_thruster_outputs_names_it(shared_dir):
    """The SITL boat's log maps no servo output to the thrusters (no SERVOn_FUNCTION 73/74): its
    calibration is told, and the throttle test names the log and --channels instead of failing."""
    p = twin("info", shared_dir / "data" / "ardupilot" / "sitl_motorboat.tlog", "--vessel", "blueboat")
    assert p.returncode == 0, p.stderr
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("calibration:")]
    assert lines[-1] == ("calibration: compass error following the throttle: not told (sitl_motorboat.tlog: no "
                         "thruster outputs logged (give --channels LEFT,RIGHT if its servo outputs drive the "
                         "thrusters))")


def test_an_inputs_csv_with_a_column_twice_is_refused_as_a_recordings_csv_is(tmp_path):
    """A CSV with a column twice is refused (which one a reader took would be a guess), as a log and as
    simulate --inputs alike, in the same words, before anything is written."""
    for header, said in (("t,pwm_left,pwm_right,t", "column t appears"),
                         ("t,pwm_left,pwm_right,pwm_left,pwm_right", "columns pwm_left, pwm_right appear")):
        inputs = tmp_path / "in.csv"
        inputs.write_text(header + "\n" + "\n".join(",".join([str(k)] + ["1600"] * (header.count(",")))
                                                    for k in range(3)) + "\n")
        p = twin("simulate", "--vessel", "blueboat", "--inputs", inputs, "--duration", "1", "--out", tmp_path / "o.csv")
        assert p.returncode == 2 and p.stderr == f"error: in.csv: {said} more than once in the header\n", p.stderr
        assert not (tmp_path / "o.csv").exists()
        p = twin("info", inputs)  # the same file read as a recording: the same words
        assert p.returncode == 2 and f"in.csv: {said} more than once in the header" in p.stderr


def test_a_conversion_says_what_a_log_format_resamples():
    """A .bin or .tlog carries roll and pitch in the heading's message: a conversion says it reads
    them at the heading's times; .mcap, which keeps every stream, says nothing of it."""
    from twin.prepare.convert import not_kept
    from twin.recording import Recording, Stream

    rec = Recording("x.csv", "csv")
    rec.heading = Stream(np.arange(0.0, 10.0, 0.1), {"psi_rad": np.zeros(100)})
    rec.attitude = Stream(np.arange(0.0, 10.0, 0.02), {"roll_rad": np.zeros(500), "pitch_rad": np.zeros(500)})
    assert not_kept(rec, ".bin") == ["a .bin carries roll and pitch with the heading (ATT, ATTITUDE): the 500 attitude "
                                      "samples are read at the heading's 100 times (.mcap keeps them all)"]
    assert not_kept(rec, ".mcap") == []


def test_a_copy_without_parameters_says_which_streams_it_holds_read_earlier(tmp_path):
    """An ArduPilot log stating its gyro filter and GPS lag, converted to .csv (which has no place
    for them): the copy holds both streams as read, and the conversion says so; to .bin, where the
    parameters go too, it reads back the same and says nothing of it."""
    from twin.formats import write_recording
    from twin.recording import Recording, Stream

    t = np.arange(0, 1000) * 0.02
    tg = np.arange(0, 100) * 0.2
    rec = Recording(source="ap", kind="synthetic", heading=Stream(t, {"psi_rad": 0.1 * t}),
                    imu=Stream(t.copy(), {"yaw_rate_rads": np.full(len(t), 0.1)}),
                    gnss=Stream(tg, {"lat_deg": 63.4 + 1e-6 * tg, "lon_deg": np.full(len(tg), 10.3),
                                     "alt_m": np.zeros(len(tg))}),
                    parameters={"INS_GYRO_FILTER": 4.0, "SIM_GPS1_LAG_MS": 100.0})
    write_recording(rec, tmp_path / "ap.bin")
    p = twin("convert", tmp_path / "ap.bin", tmp_path / "ap.csv")
    assert p.returncode == 0, p.stderr
    lines = p.stderr.splitlines()
    assert "note: ap.bin: gyro: logged after ArduPilot's 4-Hz low-pass (INS_GYRO_FILTER), which delays a turn by " \
           "0.056 s: read 0.056 s earlier" in lines, lines
    assert "note: ap.bin: gnss: each fix read 0.100 s before it was logged, as the log's SIM_GPS1_LAG_MS says" in lines
    assert "note: the copy holds the gyro and gnss as read (above), at the times they measured" in lines
    a, b = read_recording(tmp_path / "ap.bin"), read_recording(tmp_path / "ap.csv")
    for name in ("gnss", "imu", "heading"):
        np.testing.assert_allclose(getattr(b, name).t, getattr(a, name).t, atol=1e-6, err_msg=name)
    p = twin("convert", tmp_path / "ap.bin", tmp_path / "again.bin")
    assert p.returncode == 0 and "the copy holds" not in p.stderr, p.stderr
    c = read_recording(tmp_path / "again.bin")
    for name in ("gnss", "imu", "heading"):
        np.testing.assert_allclose(getattr(c, name).t, getattr(a, name).t, atol=1.5e-6, err_msg=name)
