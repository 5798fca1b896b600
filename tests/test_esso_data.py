"""The Esso Osaka tests' CSV layout (formats/esso_csv.py): its conventions checked on the data itself, its
streams through `twin info/convert/view`, and bad input. Tests reading ../shared skip without it; the
synthetic ones build their own files (no data row of the dataset is copied here)."""
import csv
import math
from pathlib import Path

import numpy as np
import pytest

from twin.errors import TwinError
from twin.recording import TRACKED_ORIGIN
from twin.formats import read_recording, write_recording
from twin.prepare import prepare
from twin.prepare.convert import for_conversion
import twin_command

TURNS = ["turn_14-Sep-2020_13_39_32", "turn_14-Oct-2020_14_56_07", "turn_14-Sep-2020_15_47_33",
         "turn_14-Oct-2020_14_29_49"]
HEADER = ("t [s],x_position_mid [m],u_velo [m/s],y_position_mid [m],vm_velo [m/s],psi_hat [rad],r_angvelo [rad/s],"
          "n_prop [rps],delta_rudder [rad],wind_velo_relative_mid [m/s],wind_dir_relative_mid [rad],"
          "wind_velo_true [m/s],wind_dir_true [rad]")


@pytest.fixture
def esso_dir(shared_dir):
    folder = shared_dir / "data" / "esso"
    if not folder.is_dir():
        pytest.skip("../shared/data/esso is not present")
    return folder


def _raw(path: Path) -> dict[str, np.ndarray]:
    with open(path) as fh:
        rows = list(csv.reader(fh))
    return {name.split(" ")[0]: np.array([float(r[i]) for r in rows[1:]]) for i, name in enumerate(rows[0])}


def test_reader_streams_and_notes(esso_dir):
    rec = read_recording(esso_dir / f"{TURNS[0]}.csv")
    assert rec.kind == "esso-csv" and rec.meta["positions"] == TRACKED_ORIGIN
    for name in ("gnss", "heading", "imu", "prop_rudder", "wind"):
        assert getattr(rec, name).median_rate_hz() == pytest.approx(10.0)
    assert set(rec.wind.columns) == {"speed_m_s", "from_deg", "relative_speed_m_s", "relative_from_deg"}
    assert not len(rec.pwm) and set(rec.summary()["streams"]) >= {"prop_rudder", "wind"}
    raw = _raw(esso_dir / f"{TURNS[0]}.csv")
    np.testing.assert_array_equal(rec.prop_rudder["delta_rad"], raw["delta_rudder"])
    np.testing.assert_allclose(rec.wind["from_deg"], np.degrees(raw["wind_dir_true"]) % 360)


def test_a_point_tracked_off_midship_is_moved_back_by_the_sensors_offset(esso_dir):
    """The files' positions are midship's by their own account, so no antenna site applies; a tracked
    point found off it (the sensors' antenna_offset_m, as the diagnosis's gnss_lever_arm sets it) is
    moved back: the track moved by R(ψ)·(0.3, −0.2) m and read with that offset gives the velocities of
    the file as it is to 0.3-0.5 mm/s rms (read without, 8-12 mm/s off). Guards against the offset being
    ignored on a tracked track."""
    from dataclasses import replace

    import twin.vessel as vessel_mod
    from twin.engine.mjcf import compile_vessel
    from twin.fit.calibrate import prepare_for
    from twin.recording import Stream

    rec = read_recording(esso_dir / f"{TURNS[0]}.csv")
    plain = compile_vessel(vessel_mod.load("esso_osaka"))
    psi = np.interp(rec.gnss.t, rec.heading.t, np.unwrap(rec.heading["psi_rad"]))
    dx, dy = 0.3, -0.2
    moved = replace(rec, gnss=Stream(rec.gnss.t, {"north_m": rec.gnss["north_m"] + np.cos(psi) * dx - np.sin(psi) * dy,
                                                  "east_m": rec.gnss["east_m"] + np.sin(psi) * dx + np.cos(psi) * dy}))
    offset = replace(plain.vessel, sensors=replace(plain.vessel.sensors, antenna_offset_m=(dx, dy)))
    told = compile_vessel(offset)
    base, back, kept = prepare_for(rec, plain), prepare_for(moved, told), prepare_for(moved, plain)
    assert base.settings.lever_arm_OP_m is None and back.settings.lever_arm_OP_m == (-dx, -dy)
    def rms(p, name):
        return float(np.sqrt(np.mean((getattr(p, name) - getattr(base, name)) ** 2)))

    # the file's yaw rate (its gyro) against the smoothed slope of the moved track: not exact, 25× smaller
    assert rms(back, "u") < 0.001 and rms(back, "v") < 0.001
    assert rms(kept, "u") > 0.005 and rms(kept, "v") > 0.008


@pytest.mark.parametrize("name", TURNS)
def test_a_turning_tests_steady_yaw_rate_has_the_sign_of_its_rudder(esso_dir, name):
    prep = prepare(read_recording(esso_dir / f"{name}.csv"))
    assert prep.input_kind == "propeller_rudder"
    half = slice(len(prep.t) // 2, int(0.95 * len(prep.t)))  # the rudder held, before the end's stop
    delta, r = np.mean(prep.pwm[half, 1]), np.mean(prep.r[half])
    assert abs(delta) > math.radians(15) and np.sign(r) == np.sign(delta) and abs(math.degrees(r)) > 1.5


@pytest.mark.parametrize("name", [TURNS[0], "random_06-Aug-2020_16_24_25_3"])
def test_body_velocities_from_positions_match_the_files_own(esso_dir, name):
    """x0, y0 are north, east with v to starboard: the twin's velocities from positions match u_velo, vm_velo;
    with y0 to port (the mirrored reading) the sway would not."""
    path = esso_dir / f"{name}.csv"
    prep, raw = prepare(read_recording(path)), _raw(path)
    t = raw["t"] - raw["t"][0]
    u, v = (np.interp(prep.t, t, raw[k]) for k in ("u_velo", "vm_velo"))
    inner = slice(20, -20)
    assert np.sqrt(np.mean((prep.u - u)[inner] ** 2)) < 0.05 and np.sqrt(np.mean((prep.v - v)[inner] ** 2)) < 0.02
    mirrored = -np.sin(-prep.psi) * np.gradient(prep.north, 0.1) + np.cos(-prep.psi) * np.gradient(-prep.east, 0.1)
    assert np.sqrt(np.mean((mirrored - v)[inner] ** 2)) > 2 * np.sqrt(np.mean((prep.v - v)[inner] ** 2))
    r = np.interp(prep.t, t, raw["r_angvelo"])
    assert np.sqrt(np.mean((prep.r - r)[inner] ** 2)) < 0.02  # r = +dψ/dt


def test_true_wind_is_the_apparent_wind_plus_the_ships_velocity(esso_dir):
    """Both wind angles are FROM directions, clockwise: true from north (x0), relative from the bow."""
    path = esso_dir / f"{TURNS[1]}.csv"
    rec, raw = read_recording(path), _raw(path)
    w = rec.wind
    psi, u, v = raw["psi_hat"], raw["u_velo"], raw["vm_velo"]
    rel = np.radians(w["relative_from_deg"])
    air_body = -w["relative_speed_m_s"][:, None] * np.column_stack([np.cos(rel), np.sin(rel)])  # air rel. to ship
    gx, gy = air_body[:, 0] + u, air_body[:, 1] + v  # air over ground, body axes
    north, east = np.cos(psi) * gx - np.sin(psi) * gy, np.sin(psi) * gx + np.cos(psi) * gy
    true = np.radians(w["from_deg"])
    err = np.hypot(north + w["speed_m_s"] * np.cos(true), east + w["speed_m_s"] * np.sin(true))
    assert np.sqrt(np.mean(err**2)) < 0.01


def test_convert_keeps_inputs_and_wind_in_csv_and_mcap(esso_dir, tmp_path):
    rec = read_recording(esso_dir / f"{TURNS[0]}.csv")
    conv = for_conversion(rec).recording
    for suffix in (".csv", ".mcap"):
        write_recording(conv, tmp_path / f"e{suffix}")
        back = read_recording(tmp_path / f"e{suffix}")
        np.testing.assert_allclose(back.prop_rudder["delta_rad"], conv.prop_rudder["delta_rad"], atol=1e-9)
        np.testing.assert_allclose(back.wind["speed_m_s"], rec.wind["speed_m_s"], atol=1e-6)
        np.testing.assert_allclose(back.wind["relative_from_deg"], rec.wind["relative_from_deg"], atol=1e-6)
        assert prepare(back).input_kind == "propeller_rudder"
    assert back.meta["positions"] == TRACKED_ORIGIN  # the MCAP keeps the track measured
    conv.meta["positions"] = "body origin"  # as older files give it
    write_recording(conv, tmp_path / "older.mcap")
    assert read_recording(tmp_path / "older.mcap").meta["positions"] == TRACKED_ORIGIN


def _write(path: Path, rows: list[str], header: str = HEADER) -> Path:
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    return path


def _rows(n: int = 40) -> list[str]:
    out = []
    for k in range(n):  # a synthetic straight run north at 0.2 m/s, wind from the east
        t = 0.1 * k
        out.append(f"{t:.1f},{0.2 * t:.4f},0.2,0.0,0.0,0.0,0.0,10,0.05,1.5,1.4,1.52,1.57")
    return out


def test_bad_input_is_one_line_and_bad_rows_are_counted(tmp_path):
    good = read_recording(_write(tmp_path / "ok.csv", _rows()))
    assert good.kind == "esso-csv" and len(good.prop_rudder) == 40
    rows = _rows()
    rows[5] = rows[5].replace(",10,", ",nan,")
    rows[6] = "0.0,1,2"  # wrong number of fields
    rows[7] = rows[7].replace(",0.05,", ",3.5,")  # a rudder angle beyond 90°
    rec = read_recording(_write(tmp_path / "bad.csv", rows))
    reasons = dict(rec.dropped)
    assert reasons["csv: rows with the wrong number of fields"] == 1
    assert reasons["prop_rudder: samples with NaN or missing values"] == 1
    assert reasons["prop_rudder: rudder angle beyond ±90°"] == 1
    no_wind = HEADER.rsplit(",", 4)[0]
    rec = read_recording(_write(tmp_path / "nowind.csv", [r.rsplit(",", 4)[0] for r in _rows()], no_wind))
    assert not len(rec.wind) and any("no wind" in n for n in rec.notes)
    with pytest.raises(TwinError, match="CSV layout not recognised"):
        read_recording(_write(tmp_path / "x.csv", ["1,2"], "x_position_mid [m],psi_hat [rad]"))
    with pytest.raises(TwinError, match="no usable rows|nothing usable"):
        read_recording(_write(tmp_path / "empty.csv", ["nan,nan,nan,nan,nan,nan,nan,nan,nan,nan,nan,nan,nan"]))


def test_twin_info_convert_view_on_an_esso_layout(tmp_path):
    src = _write(tmp_path / "run.csv", _rows(60))

    def twin(*args):
        return twin_command.twin(*args, cwd=tmp_path)

    info = twin("info", src)
    assert info.returncode == 0 and "prop_rudder" in info.stdout and "wind" in info.stdout
    rec = read_recording(src)
    for suffix in (".tlog", ".bin"):  # a ship's inputs and its measured wind survive ArduPilot's formats
        out = twin("convert", src, tmp_path / f"run{suffix}")
        assert out.returncode == 0 and "no place" not in out.stdout + out.stderr, out.stderr
        back = read_recording(tmp_path / f"run{suffix}")
        for stream, cols in (("prop_rudder", ("n_rps", "delta_rad")), ("wind", ("speed_m_s", "from_deg"))):
            a, b = getattr(rec, stream), getattr(back, stream)
            assert len(b) == len(a) and np.max(np.abs((b.t - b.t[0]) - (a.t - a.t[0]))) <= 1e-3
            for c in cols:
                assert np.allclose(b[c], a[c], rtol=1e-6, atol=1e-6), (suffix, stream, c)
    view = twin("view", src, "--sim", "--vessel", "esso_osaka", "--out", tmp_path / "v.rrd")
    assert view.returncode == 0 and (tmp_path / "v.rrd").is_file(), view.stderr


def test_the_ships_yaw_rate_window_takes_the_noise_out_not_the_turn(esso_dir):
    """The Esso's heading comes at 10 Hz with about 0.08° of noise: its vessel file takes the yaw rate over
    1 s (`sensors.heading_rate_window_s`), which identify and diagnose prepare with. Checked against the
    files' own yaw-rate stream (r_angvelo, which prepare() does not use): the 1-s derivative is much closer
    to it than the 0.5-s one of a 50-Hz AHRS, and a 4-s one closer still, so 1 s is short of where a window
    starts to smooth the ship's own yaw away (16 s is past it on the random tests)."""
    import twin.vessel as vessel_mod
    from twin.diagnose.doctor import _prepared
    from twin.engine.mjcf import compile_vessel
    from twin.fit.calibrate import prepare_for
    from twin.ident.identify import prepared

    ship = vessel_mod.load("esso_osaka")
    cv = compile_vessel(ship)
    for name in (TURNS[0], "random_31-Jul-2020_12_29_58"):
        rec = read_recording(esso_dir / f"{name}.csv")
        assert prepared([rec], ship)[0].settings.yaw_rate_window_s == 1.0
        assert _prepared([rec], ship, 10.0, False)[3][0].settings.yaw_rate_window_s == 1.0
        rms = {}
        for w in (0.5, 1.0, 4.0, 16.0):
            prep = prepare_for(rec, cv, window_s=1.0, heading_window_s=w)
            gyro = np.interp(prep.t, rec.imu.t, rec.imu["yaw_rate_rads"])
            rms[w] = float(np.sqrt(np.mean((prep.r - gyro)[20:-20] ** 2)))
        assert rms[1.0] < 0.65 * rms[0.5] and rms[4.0] < rms[1.0], (name, rms)
    assert rms[16.0] > 1.3 * rms[4.0], rms  # on the random test a long window smooths its turns away


def test_view_shows_a_ships_inputs_as_propeller_and_rudder_and_replays_with_its_measured_wind(tmp_path):
    import twin.vessel as vessel_mod
    from twin.replay import view_runs

    rows = []
    for k in range(300):  # 30 s north at 0.2 m/s, the rudder at 0.05 rad, a 6-m/s wind from the east
        t = 0.1 * k
        rows.append(f"{t:.1f},{0.2 * t:.4f},0.2,0.0,0.0,0.0,0.0,10,0.05,6.0,1.57,6.0,1.57")
    rec = read_recording(_write(tmp_path / "run.csv", rows))
    ship = vessel_mod.load("esso_osaka")
    calm = view_runs([rec], ship, sim=True)
    windy = view_runs([rec], ship, sim=True, wind="measured")
    real = calm["recorded"]
    assert np.all(np.isnan(real.pwm_us))  # no 10-µs "PWM" line
    held = real.propeller_rudder()
    assert held[:, 0] == pytest.approx(10.0) and held[:, 1] == pytest.approx(0.05)
    # a beam wind from the east pushes the ship west: its replay drifts further that way with it
    assert windy["twin"].eta[-1, 1] < calm["twin"].eta[-1, 1] - 0.05
    out = twin_command.twin("view", tmp_path / "run.csv", "--vessel", "esso_osaka", "--wind-measured",
                            "--out", tmp_path / "v.rrd", cwd=tmp_path)
    assert out.returncode == 2 and "--sim" in out.stderr and not (tmp_path / "v.rrd").exists()
    with pytest.raises(TwinError, match="driven by PWM; the recording holds propeller speed and rudder angle"):
        view_runs([rec], vessel_mod.load("blueboat"))


def test_the_yaw_rate_is_read_from_the_gyro_less_its_bias_where_the_vessel_says_so(tmp_path):
    from twin.fit.windows import as_measured, make_windows

    rows = []
    for k in range(600):  # a weave: heading 0.3·sin(0.5 t) rad, the gyro 0.01 rad/s high
        t = 0.1 * k
        psi, r = 0.3 * math.sin(0.5 * t), 0.15 * math.cos(0.5 * t)
        rows.append(f"{t:.1f},{0.2 * t:.4f},0.2,0.0,0.0,{psi:.6f},{r + 0.01:.6f},10,0.05,1.5,1.4,1.52,1.57")
    rec = read_recording(_write(tmp_path / "weave.csv", rows))
    heading = prepare(rec, heading_window_s=1.0)
    gyro = prepare(rec, heading_window_s=1.0, yaw_rate_source="gyro")
    truth = 0.15 * np.cos(0.5 * gyro.t)
    assert heading.settings.yaw_rate_source == "heading" and gyro.settings.yaw_rate_source == "gyro"
    assert np.max(np.abs(gyro.r - truth)) < 1e-3  # the gyro's 0.01-rad/s offset taken out
    from twin.replay import view_runs
    import twin.vessel as vessel_mod
    shown = view_runs([rec], vessel_mod.load("esso_osaka"))["recorded"]  # `twin view` reads it as identify does
    assert np.max(np.abs(shown.nu[:, 2] - 0.15 * np.cos(0.5 * shown.t))) < 1e-3
    rec.imu = rec.imu.__class__.empty("yaw_rate_rads")
    assert prepare(rec, yaw_rate_source="gyro").settings.yaw_rate_source == "heading"  # no gyro: the heading
    # the fit sees a gyro's r as it is, a heading's slope smoothed
    wins = make_windows([gyro, heading], 5.0, 5.0, min_length_s=5.0)
    nu = np.zeros((len(wins), wins[0].n + 1, 3))
    nu[..., 2] = np.sin(np.arange(wins[0].n + 1))  # a rate the 1-s window would smooth away
    seen = as_measured(nu, [gyro, heading], wins)
    own = np.array([w.rec == 0 for w in wins])
    assert np.array_equal(seen[own, :, 2], nu[own, :, 2])
    assert np.max(np.abs(seen[~own, 5:-5, 2])) < 0.5
    with pytest.raises(TwinError, match="yaw_rate_source"):
        prepare(rec, yaw_rate_source="compass")


def test_a_measured_wind_is_refused_for_a_vessel_it_cannot_act_on(tmp_path):
    from dataclasses import replace

    import twin.vessel as vessel_mod
    from twin.ident.identify import check_wind
    from twin.physics.environment import WindLoad

    rec = read_recording(_write(tmp_path / "run.csv", _rows()))
    ship = vessel_mod.load("esso_osaka")
    check_wind([rec], "measured", ship)  # the Esso has Fujiwara's regression
    bare = replace(ship, wind_load=WindLoad(), wind_regression=None)
    with pytest.raises(TwinError, match="no wind load model"):
        check_wind([rec], "measured", bare)
    check_wind([rec], None, bare)


def test_a_measured_wind_with_long_gaps_is_noted(tmp_path):
    from twin.ident.identify import wind_gaps

    rows = _rows(100)
    patchy = [r if k < 20 else r.rsplit(",", 4)[0] + ",nan,nan,nan,nan" for k, r in enumerate(rows)]
    full, gappy = (read_recording(_write(tmp_path / f"{n}.csv", r)) for n, r in (("full", rows), ("gappy", patchy)))
    assert wind_gaps([full]) == []
    notes = wind_gaps([gappy])
    assert len(notes) == 1 and "gappy.csv: the measured wind covers 19 % of the log" in notes[0]
    out = twin_command.twin("view", tmp_path / "gappy.csv", "--vessel", "esso_osaka", "--sim", "--wind-measured",
                            "--out", tmp_path / "v.rrd", cwd=tmp_path)
    assert out.returncode == 0 and "covers 19 %" in out.stdout + out.stderr, out.stderr
