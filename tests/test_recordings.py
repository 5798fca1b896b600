"""Readers and [Morel-2024 §5.1] preparation of real recordings (twin.formats, twin.prepare).

The fixtures are generated here from a known trajectory (a constant-speed circle),
so a fresh clone tests the readers: a MAVLink telemetry log written with
pymavlink's encoder, a generic CSV, a BlueBoat-like CSV and a project MCAP file.
Tests on ../shared/data skip when ../shared is absent.
"""
from __future__ import annotations

import csv
import math
import re
import struct
import sys
from pathlib import Path

import numpy as np
import pytest

import twin.cli as cli
from twin.errors import TwinError
from twin.recording import format_summary
from twin.prepare import geodetic_to_ned, prepare
from twin.formats import read_recording, write_recording, write_run
from twin.prepare.prepared import hold
from twin.recording import increasing_subsequence

import twin_command

SHARED = Path(__file__).resolve().parents[2] / "shared"
OP = (0.275, -0.2625)  # Yellowfish lever arm, [Yellowfish-TR eq. 29]: antenna O → body origin CO
LAT0, LON0, H0 = 37.3456, -5.9312, 12.0
U, R, PSI0 = 1.5, 0.2, 2.5  # m/s, rad/s, rad: a circle of radius 7.5 m, crossing ψ = ±π
T_END = 40.0
BOOT0 = 100.0  # s, vehicle boot time at the start of the log
UNIX0 = 1.7e9  # s, ground-station clock at boot time 0
GPS_GAP = (24.0, 26.0)  # s, a GNSS dropout
NO_FIX_UNTIL = 1.0  # s, GPS_RAW_INT without a 3-D fix before this


# ---------------------------------------------------------------- truth and geodesy

def truth(t):
    """Body-origin (CO) north, east (m), heading ψ (rad) on the circle u = U, v = 0, r = R."""
    t = np.asarray(t, float)
    psi = PSI0 + R * t
    north = U / R * (np.sin(psi) - np.sin(PSI0))
    east = -U / R * (np.cos(psi) - np.cos(PSI0))
    return north, east, psi


def antenna(t):
    """Antenna O position: x_O = x_CO − R2(ψ)·OP ([Yellowfish-TR eq. 32] solved for O)."""
    n, e, psi = truth(t)
    c, s = np.cos(psi), np.sin(psi)
    return n - (c * OP[0] - s * OP[1]), e - (s * OP[0] + c * OP[1]), psi


def ned_to_geodetic(north, east, lat0=LAT0, lon0=LON0, h0=H0):
    """Exact inverse through ECEF (independent of the reader's flat-earth formula)."""
    a, f = 6378137.0, 1 / 298.257223563
    e2 = f * (2 - f)
    phi, lam = math.radians(lat0), math.radians(lon0)
    n0 = a / math.sqrt(1 - e2 * math.sin(phi) ** 2)
    x0 = (n0 + h0) * math.cos(phi) * math.cos(lam)
    y0 = (n0 + h0) * math.cos(phi) * math.sin(lam)
    z0 = (n0 * (1 - e2) + h0) * math.sin(phi)
    north, east = np.asarray(north, float), np.asarray(east, float)
    x = x0 - math.sin(lam) * east - math.sin(phi) * math.cos(lam) * north
    y = y0 + math.cos(lam) * east - math.sin(phi) * math.sin(lam) * north
    z = z0 + math.cos(phi) * north
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1 - e2))
    for _ in range(10):
        n = a / np.sqrt(1 - e2 * np.sin(lat) ** 2)
        h = p / np.cos(lat) - n
        lat = np.arctan2(z, p * (1 - e2 * n / (n + h)))
    return np.degrees(lat), np.degrees(np.arctan2(y, x))


def pwm_truth(t):
    """(left, right) µs with forward = higher: ff, then rf after 20 s; right in the dead band 30-35 s."""
    t = np.asarray(t, float)
    left = np.where(t < 20.0, 1700.0, 1400.0)
    right = np.where((t >= 30.0) & (t < 35.0), 1520.0, 1650.0)
    return left, right


# ---------------------------------------------------------------- fixture writers

def write_tlog(path: Path, *, gps=True, corrupt_one=True, gcs_noise=True) -> Path:
    """A telemetry log of the circle: GPS_RAW_INT 10 Hz (no fix for the first second,
    a dropout GPS_GAP), ATTITUDE 20 Hz, SERVO_OUTPUT_RAW 10 Hz (left on servo 1,
    reversed; right on servo 3), PARAM_VALUE, SYS_STATUS; receive times jitter by
    up to 30 ms; one packet's CRC broken."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    gcs = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    rng = np.random.default_rng(7)
    records = []

    def add(t, msg, sender=mav):
        recv = UNIX0 + BOOT0 + t + rng.uniform(0.0, 0.03)
        records.append((recv, msg.pack(sender), msg.get_type()))

    params = {"SERVO1_FUNCTION": 73, "SERVO3_FUNCTION": 74, "SERVO1_REVERSED": 1, "SERVO3_REVERSED": 0,
              "SERVO1_TRIM": 1500, "SERVO3_TRIM": 1500}
    for i, (name, value) in enumerate(params.items()):
        add(0.0, mav.param_value_encode(name.encode(), float(value), 9, len(params), i))
    for k in range(int(T_END / 0.05) + 1):
        t = k * 0.05
        boot_ms = int(round((BOOT0 + t) * 1000))
        _, _, psi = truth(t)
        yaw = (psi + np.pi) % (2 * np.pi) - np.pi
        add(t, mav.attitude_encode(boot_ms, 0.0, 0.0, float(yaw), 0.0, 0.0, R))
        if k % 2:
            continue
        if gps and not (GPS_GAP[0] < t < GPS_GAP[1]):
            n, e, _ = antenna(t)
            lat, lon = ned_to_geodetic(n, e)
            fix = 1 if t < NO_FIX_UNTIL else 3
            add(t, mav.gps_raw_int_encode(boot_ms * 1000, fix, int(round(float(lat) * 1e7)),
                                          int(round(float(lon) * 1e7)), int(H0 * 1000), 80, 120, 150, 0, 12))
        left, right = pwm_truth(t)
        raw_left = int(round(2 * 1500 - float(left)))  # SERVO1_REVERSED: the autopilot mirrors it
        add(t, mav.servo_output_raw_encode(boot_ms * 1000, 0, raw_left, 1500, int(right), 1500, 0, 0, 0, 0))
        add(t, mav.sys_status_encode(0, 0, 0, 100, 15800, 300, 80, 0, 0, 0, 0, 0, 0))
        if gcs_noise and k % 20 == 0:
            add(t, gcs.heartbeat_encode(6, 8, 0, 0, 4))
    broken = next(i for i in range(len(records) // 2, len(records)) if records[i][2] == "SYS_STATUS")
    blob = bytearray()
    for i, (recv, packet, _) in enumerate(records):
        packet = bytearray(packet)
        if corrupt_one and i == broken:
            packet[-3] ^= 0xFF  # break the CRC of one packet in the middle (not a GNSS fix)
        blob += struct.pack(">Q", int(recv * 1e6)) + packet
    path.write_bytes(bytes(blob))
    return path


def grid_times():
    return np.round(np.arange(0.0, T_END + 1e-9, 0.1), 10)


def write_generic_csv(path: Path, *, latlon=True) -> Path:
    """Generic layout at 10 Hz (antenna positions), with one NaN row and one
    backwards timestamp."""
    t = grid_times()
    n, e, psi = antenna(t)
    left, right = pwm_truth(t)
    rows = []
    for i, ti in enumerate(t):
        if latlon:
            lat, lon = ned_to_geodetic(n[i], e[i])
            pos = [f"{float(lat):.9f}", f"{float(lon):.9f}"]
        else:
            pos = [f"{n[i]:.6f}", f"{e[i]:.6f}"]
        rows.append([f"{ti:.3f}", *pos, f"{math.degrees(psi[i]) % 360:.6f}", f"{left[i]:.0f}", f"{right[i]:.0f}"])
    rows[50][1] = "nan"  # a NaN position
    rows[120][0] = f"{t[120] - 5:.3f}"  # time going backwards
    head = ["t", "lat", "lon"] if latlon else ["t", "north", "east"]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(head + ["heading_deg", "pwm_left", "pwm_right"])
        w.writerows(rows)
    return path


BLUEBOAT_HEADER = ["", "original_timestamp", "lat", "lon", "alt", "x_ned", "y_ned", "yaw", "surge", "sway",
                   "yaw_rate", "surge_dot", "surge_dot_bias", "sway_dot", "sway_dot_bias", "yaw_acc", "thr_left",
                   "thr_right", "right_force", "left_force", "thr_left_pwm_zero_point", "thr_right_pwm_zero_point"]


def write_blueboat_csv(path: Path) -> Path:
    """BlueBoat layout: ms timestamps, yaw in degrees, the column thr_left driving the
    starboard thruster and reversed around 1511 µs, thr_right the port one; one row with
    empty GNSS cells, one backwards timestamp."""
    t = grid_times()
    n, e, psi = antenna(t)
    lat, lon = ned_to_geodetic(n, e)
    left, right = pwm_truth(t)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(BLUEBOAT_HEADER)
        for i, ti in enumerate(t):
            ms = 1_444_000.0 + ti * 1000 if i != 200 else 1_444_000.0 + (ti - 3) * 1000
            row = {"": i, "original_timestamp": f"{ms:.3f}", "lat": f"{lat[i]:.9f}", "lon": f"{lon[i]:.9f}",
                   "alt": "220.0", "x_ned": n[i], "y_ned": e[i], "yaw": math.degrees(psi[i]) % 360,
                   "surge": "", "sway": "", "yaw_rate": 0.0, "thr_left": 2 * 1511 - (right[i] + 11),
                   "thr_right": left[i] + 11, "thr_left_pwm_zero_point": 1511.0, "thr_right_pwm_zero_point": 1511.0}
            if i == 80:
                row["lat"] = row["lon"] = ""
            w.writerow([row.get(c, 0.0) for c in BLUEBOAT_HEADER])
    return path


@pytest.fixture(scope="module")
def tlog(tmp_path_factory):
    return write_tlog(tmp_path_factory.mktemp("rec") / "circle.tlog")


# ---------------------------------------------------------------- checks

def position_error(p) -> np.ndarray:
    """|CO position − truth| (m); positions from lat/lon are relative to the first
    fix, so they are moved to the truth's origin (LAT0, LON0) first."""
    dn, de = geodetic_to_ned(p.origin["lat_deg"], p.origin["lon_deg"], LAT0, LON0, H0) if p.origin else (0, 0)
    n, e, _ = truth(p.t)
    return np.hypot(p.north + dn - n, p.east + de - e)


def assert_recovers_circle(p, *, pos_tol=0.01, vel_tol=0.03, r_tol=0.002, skip=()):
    """Positions, heading and body velocities of `p` match the circle's truth,
    except within 0.6 s of the times in `skip` (where the fixture broke a row).
    vel_tol: GPS_RAW_INT quantises to 1e-7° (about 1 cm), which the Savitzky-Golay
    derivative turns into ≈ 0.01 m/s inside a segment and ≈ 0.03 m/s at its ends."""
    ok = np.ones(len(p.t), bool)
    for ts in skip:
        ok &= np.abs(p.t - ts) > 0.6
    n, e, psi = truth(p.t)
    assert np.max(position_error(p)[ok]) < pos_tol
    assert np.max(np.abs(np.angle(np.exp(1j * (p.psi - psi))))[ok]) < 1e-4
    assert np.max(np.abs(p.u - U)[ok]) < vel_tol
    assert np.max(np.abs(p.v)[ok]) < vel_tol
    assert np.max(np.abs(p.r - R)[ok]) < r_tol


def test_tlog_reader_summary(tlog):
    rec = read_recording(tlog)
    s = rec.summary()
    assert rec.kind == "tlog" and s["streams"]["gnss"]["rate_hz"] == pytest.approx(10, rel=1e-3)
    assert s["streams"]["heading"]["rate_hz"] == pytest.approx(20, rel=1e-3)
    assert s["streams"]["gnss"]["gaps"] == 1 and s["streams"]["gnss"]["longest_gap_s"] == pytest.approx(2.0, abs=0.11)
    dropped = dict(rec.dropped)
    assert dropped["gnss: GPS_RAW_INT without a 3-D fix"] == int(NO_FIX_UNTIL / 0.1)
    assert dropped["tlog: packets with bad CRC"] == 1
    assert rec.channels["left"] == 1 and rec.channels["right"] == 3 and rec.channels["reversed"]["left"]
    # the vehicle's boot clock, not the jittery receive clock, is the time base
    assert rec.origin_s == pytest.approx(BOOT0, abs=1e-6)
    assert np.allclose(np.diff(rec.heading.t), 0.05, atol=1e-6)
    assert "gnss" in format_summary(s)


def test_tlog_prepare_recovers_truth_with_lever_arm(tlog):
    rec = read_recording(tlog)
    p = prepare(rec, lever_arm_OP_m=OP)
    assert len(p.segments) == 2  # cut at the GNSS dropout
    assert not np.any((p.t > GPS_GAP[0] + 0.05) & (p.t < GPS_GAP[1] - 0.05))
    assert_recovers_circle(p)
    left, right = pwm_truth(p.t)
    assert np.allclose(p.pwm[:, 0], left) and np.allclose(p.pwm[:, 1], right)  # mirrored back
    assert set(p.region[p.t < 19.9]) == {"ff"} and set(p.region[p.t > 20.1]) == {"rf"}
    assert np.all(p.in_deadband[(p.t > 30.05) & (p.t < 34.95), 1]) and not np.any(p.in_deadband[:, 0])


def test_lever_arm_matters(tlog):
    p = prepare(read_recording(tlog), lever_arm_OP_m=None)
    assert np.median(position_error(p)) == pytest.approx(math.hypot(*OP), abs=0.01)
    assert np.max(np.abs(p.v)) > 0.8 * R * OP[0]  # antenna velocity ≠ CO velocity: v ≈ r·dx


def test_savgol_off_stays_close(tlog):
    p = prepare(read_recording(tlog), lever_arm_OP_m=OP, smoother="none")
    assert_recovers_circle(p, vel_tol=0.08, r_tol=0.01)  # plain differences: more quantisation noise


def test_explicit_channels_override(tlog):
    rec = read_recording(tlog, channels={"left": 3, "right": 1, "reversed": {"right": False}})
    assert rec.channels["from"] == "explicit" and rec.channels["reversed"] == {"left": False, "right": False}
    left, right = pwm_truth(rec.pwm.t)
    assert np.allclose(rec.pwm["left_us"], right) and np.allclose(rec.pwm["right_us"], 3000 - left)
    with pytest.raises(TwinError):
        read_recording(tlog, channels={"left": 1})
    # channels the log's own SERVOn_FUNCTION contradict are read as given, with a warning naming both;
    # channels whose outputs are off throughout give no PWM, and say so
    assert rec.warnings and "the log's parameters put the left throttle on output 1 and the right on 3" in \
        rec.warnings[0]
    assert read_recording(tlog).warnings == []
    off = read_recording(tlog, channels={"left": 2, "right": 6})
    # output 2 carries a signal at times, output 6 never: the one off is named
    assert not len(off.pwm) and any(w.startswith("output 6 is off (0 µs) in every sample (explicit channels 2,6)")
                                    for w in off.warnings)
    both_off = read_recording(tlog, channels={"left": 7, "right": 6})
    assert not len(both_off.pwm) and any(w.startswith("outputs 7 and 6 are off (0 µs) in every sample")
                                         for w in both_off.warnings)


def test_truncated_tlog_reads_what_is_there(tlog, tmp_path):
    data = tlog.read_bytes()
    cut = tmp_path / "cut.tlog"
    cut.write_bytes(data[: len(data) // 2 + 5])
    rec = read_recording(cut)
    assert dict(rec.dropped)["tlog: truncated last packet"] == 1
    assert 15 < rec.duration_s() < 25
    assert_recovers_circle(prepare(rec, lever_arm_OP_m=OP))


def test_tlog_without_gps(tmp_path):
    rec = read_recording(write_tlog(tmp_path / "nogps.tlog", gps=False))
    assert len(rec.gnss) == 0 and any("no GNSS" in n for n in rec.notes)
    with pytest.raises(TwinError, match="GNSS"):
        prepare(rec)


_NOISE = np.random.default_rng(3).bytes(4000)
GARBAGE = {
    "random.tlog": _NOISE,
    "random.bin": _NOISE,
    "random.BIN": b"\xa3\x95" + _NOISE,  # DataFlash magic, then noise
    "random.dat": _NOISE,
    "image.png": b"\x89PNG\r\n\x1a\n" + _NOISE[:2000],
    "image.tlog": b"\x89PNG\r\n\x1a\n" + _NOISE[:2000],
    "empty.tlog": b"",
    "empty.csv": b"",
    "words.csv": b"a,b\n1,2\n",
    "allnan.csv": b"t,lat,lon,heading_deg\nnan,nan,nan,nan\n",
    "fake.mcap": b"\x89MCAP0\r\n" + _NOISE[:100],
}


@pytest.mark.parametrize("name", sorted(GARBAGE))
def test_garbage_raises_one_line(tmp_path, name):
    path = tmp_path / name
    path.write_bytes(GARBAGE[name])
    with pytest.raises(TwinError) as info:
        read_recording(path)
    assert "\n" not in str(info.value) and name in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(TwinError, match="no such file"):
        read_recording(tmp_path / "nope.tlog")


@pytest.mark.parametrize("latlon", [True, False])
def test_generic_csv(tmp_path, latlon):
    rec = read_recording(write_generic_csv(tmp_path / "run.csv", latlon=latlon))
    dropped = dict(rec.dropped)
    assert rec.kind == "csv"
    assert dropped["gnss: samples with NaN or missing values"] == 1
    assert dropped["gnss: samples with time going backwards"] == 1
    assert dropped["heading: samples with time going backwards"] == 1
    p = prepare(rec, lever_arm_OP_m=OP)
    assert len(p.segments) == 1
    assert_recovers_circle(p, skip=(5.0, 12.0))


def test_csv_cells_read_as_missing_are_counted_by_kind(tmp_path):
    """A text cell, an infinite cell and an empty row are each counted apart from a written NaN or a
    blank cell (a multi-rate log's "no sample"), which are not counted at all."""
    path = tmp_path / "cells.csv"
    path.write_text("t,lat,lon,heading_deg,pwm_left,pwm_right\n0,63.4,10.3,10,1500,1500\n,,,,,\n"
                    "0.1,63.4,10.3,NaN,1500,1500\n0.2,63.4,inf,10,1500,1500\n0.3,63.4,10.3,x,1500,1500\n"
                    "0.4,63.4,10.3,,1500,1500\n")
    dropped = dict(read_recording(path).dropped)
    assert dropped["csv: rows with no value in any column"] == 1
    assert dropped["csv: cells that are not numbers (text), read as missing"] == 1
    assert dropped["csv: infinite cells, read as missing"] == 1
    assert dropped["gnss: samples with NaN or missing values"] == 1  # lat without its lon


def test_blueboat_like_csv(tmp_path):
    rec = read_recording(write_blueboat_csv(tmp_path / "fixed_00000001.csv"))
    assert rec.kind == "blueboat-csv" and rec.pwm_neutral_us == (1511.0, 1511.0)
    assert dict(rec.dropped)["gnss: samples with NaN or missing values"] == 1
    assert dict(rec.dropped)["pwm: samples with time going backwards"] == 1
    left, right = pwm_truth(rec.pwm.t)
    assert np.allclose(rec.pwm["left_us"], left + 11) and np.allclose(rec.pwm["right_us"], right + 11)
    p = prepare(rec, lever_arm_OP_m=OP)
    assert_recovers_circle(p, skip=(8.0, 20.0))
    assert set(p.region[p.t < 19.9]) == {"ff"} and set(p.region[p.t > 20.1]) == {"rf"}
    assert any("swapped" in n for n in rec.notes)


def test_mcap_run_roundtrip(tmp_path, monkeypatch):
    from twin.run import Run
    from twin.formats.mcap import write_run_mcap

    t = grid_times()
    n, e, psi = truth(t)
    left, right = pwm_truth(t)
    run = Run(t, np.column_stack([n, e, psi]), np.column_stack([np.full_like(t, U), 0 * t, np.full_like(t, R)]),
              np.column_stack([left, right]), np.zeros((len(t), 2)))
    write_run_mcap(run, tmp_path / "run.mcap")
    rec = read_recording(tmp_path / "run.mcap")
    assert rec.kind == "mcap" and rec.gnss.has("north_m", "east_m")
    assert_recovers_circle(prepare(rec, lever_arm_OP_m=None))
    # written a block of samples at a time (a long SITL session): the same file byte for byte
    monkeypatch.setattr("twin.formats.mcap.MESSAGE_BLOCK", 7)
    write_run_mcap(run, tmp_path / "blocks.mcap")
    assert (tmp_path / "blocks.mcap").read_bytes() == (tmp_path / "run.mcap").read_bytes()
    # and the run's CSV too
    assert "".join(run.csv_blocks(rows=7)) == run.to_csv_text() and run.to_csv_text().count("\n") == len(t) + 1


def test_twin_run_csv_reads_as_a_recording(tmp_path):
    """`twin simulate --out run.csv` writes t,x,y,psi,u,v,r,...: x, y are north, east of the
    body origin, so the track comes back exactly and without a lever arm; r is the yaw rate."""
    from twin.run import Run

    t = grid_times()
    n, e, psi = truth(t)
    left, right = pwm_truth(t)
    run = Run(t, np.column_stack([n, e, psi]), np.column_stack([np.full_like(t, U), 0 * t, np.full_like(t, R)]),
              np.column_stack([left, right]), np.zeros((len(t), 2)))
    (tmp_path / "run.csv").write_text(run.to_csv_text())
    rec = read_recording(tmp_path / "run.csv")
    assert rec.kind == "csv" and rec.meta["positions"] == "body origin"
    assert len(rec.gnss) == len(rec.heading) == len(rec.pwm) == len(rec.imu) == len(t)
    np.testing.assert_allclose(rec.imu["yaw_rate_rads"], R)
    assert_recovers_circle(prepare(rec, lever_arm_OP_m=None))


def test_a_body_origin_track_takes_no_lever_arm(tmp_path):
    """A twin run's x, y are the body origin's: the vessel's antenna arm, which evaluate and identify
    pass for every log, must not move them (it made a sway of r·dx = 0.055 m/s on this circle)."""
    from twin.run import Run

    t = grid_times()
    n, e, psi = truth(t)
    run = Run(t, np.column_stack([n, e, psi]), np.column_stack([np.full_like(t, U), 0 * t, np.full_like(t, R)]),
              np.column_stack(pwm_truth(t)), np.zeros((len(t), 2)))
    (tmp_path / "run.csv").write_text(run.to_csv_text())
    p = prepare(read_recording(tmp_path / "run.csv"), lever_arm_OP_m=OP)
    assert p.settings.lever_arm_OP_m is None
    assert_recovers_circle(p)


def test_a_twin_run_converted_to_the_generic_csv_stays_the_body_origins_track(tmp_path):
    """Converted from its MCAP, a twin run's track is written as the run layout's x, y, so that it
    comes back as the body origin's (guards against writing it as north, east, which read as a
    receiver's fixes and take the vessel's antenna arm)."""
    from twin.recording import EXACT_ORIGIN
    from twin.run import Run

    t = grid_times()
    n, e, psi = truth(t)
    run = Run(t, np.column_stack([n, e, psi]), np.column_stack([np.full_like(t, U), 0 * t, np.full_like(t, R)]),
              np.column_stack(pwm_truth(t)), np.zeros((len(t), 2)))
    write_run(run, tmp_path / "run.mcap")
    write_recording(read_recording(tmp_path / "run.mcap"), tmp_path / "run.csv")
    back = read_recording(tmp_path / "run.csv")
    assert back.meta["positions"] == EXACT_ORIGIN
    assert_recovers_circle(prepare(back, lever_arm_OP_m=OP))


def test_the_twins_own_run_evaluates_at_r2_one(tmp_path):
    """Simulated, written and evaluated by the same vessel: every velocity predicted as it was (the
    Yellowfish's antenna is 0.38 m off its body origin; moved by it, v scored 0.69 on this run)."""
    from twin import api
    from twin.simulation import simulate_run

    path = tmp_path / "run.csv"
    simulate_run("yellowfish", scenario="random", duration_s=60.0, seed=1).write(path)
    metrics = api.evaluate("yellowfish", [path]).metrics["free_run_10s"]
    assert all(metrics[dof]["r2"] > 0.99 for dof in ("u", "v", "r")), metrics


def test_a_straight_run_scores_no_r2_for_the_sway_and_yaw_it_never_has(tmp_path, capsys):
    """Straight ahead, v and r vary by round-off only: no R² is given for them (one of −1.6e15 was), the
    table says why, and u is scored as ever."""
    from twin import api
    from twin.fit.evaluate import format_metrics
    from twin.simulation import simulate_run

    path = tmp_path / "step.csv"
    simulate_run("blueboat", scenario="step", duration_s=60.0).write(path)
    found = api.evaluate("blueboat", [path])
    for horizon in ("one_step", "free_run_10s", "full"):
        m = found.metrics[horizon]
        assert m["u"]["r2"] > 0.99 and m["v"]["r2"] is None and m["r"]["r2"] is None, m
    assert "R2 -: the measured v and r do not vary beyond" in format_metrics(found.metrics)


@pytest.mark.parametrize("text", [
    "t,lat,lon,heading_deg\n3,37.1,-5.9,10\n2,37.1,-5.9,11\n1,37.1,-5.9,12\n0,37.1,-5.9,13\n",  # time reversed
    "t,lat,lon,heading_deg,pwm_left,pwm_right\n0,37.1,-5.9,10,1500,1500\n",  # one row
])
def test_nothing_usable_is_an_error_not_an_empty_summary(tmp_path, text):
    """One sample per stream has no duration, rate or motion: `twin info` says so instead of a summary of 0.0 s at 0.00 Hz."""
    (tmp_path / "bad.csv").write_text(text)
    with pytest.raises(TwinError, match="bad.csv: nothing usable") as info:
        read_recording(tmp_path / "bad.csv")
    assert "\n" not in str(info.value)


def test_out_of_range_samples_are_dropped_and_counted(tmp_path):
    path = write_generic_csv(tmp_path / "run.csv")
    rows = path.read_text().splitlines()
    cells = rows[31].split(",")
    cells[1] = "1000.0"  # latitude 1000°
    rows[31] = ",".join(cells)
    cells = rows[61].split(",")
    cells[5] = "50000"  # PWM 50000 µs
    rows[61] = ",".join(cells)
    cells = rows[91].split(",")
    cells[2] = "-190.0"  # longitude −190°
    rows[91] = ",".join(cells)
    path.write_text("\n".join(rows) + "\n")
    rec = read_recording(path)
    dropped = dict(rec.dropped)
    assert dropped["gnss: latitude outside ±90°"] == 1 and dropped["gnss: longitude outside ±180°"] == 1
    assert dropped["pwm: PWM outside 500-2500 µs"] == 1
    assert len(rec.gnss) == len(grid_times()) - 4  # the NaN row, the backwards one and the two out of range
    assert np.all(np.abs(rec.gnss["lat_deg"]) <= 90) and rec.pwm["right_us"].max() < 2500
    assert "latitude outside ±90°: 1" in format_summary(rec.summary())


def test_an_absurd_heading_is_dropped_and_a_heading_in_radians_is_refused_for_fits(tmp_path):
    """A heading of 1e308° is no compass reading: dropped and counted. A heading_deg column holding
    radians (it spans 2π while the circle's track turns through R·T_END = 8 rad) reads as a vessel
    pointing one way: said by `twin info`, naming the column, and refused by the commands that fit or
    score a log (a twin fitted on it would be of another boat); the column in degrees is not."""
    path = write_generic_csv(tmp_path / "run.csv")
    rec = read_recording(path)
    assert rec.warnings == []
    rows = [r.split(",") for r in path.read_text().splitlines()]
    rows[31][3] = "1e308"
    path.write_text("\n".join(",".join(r) for r in rows) + "\n")
    rec = read_recording(path)
    assert dict(rec.dropped)["heading: heading beyond ±1e6°"] == 1 and np.abs(rec.heading["psi_rad"]).max() < 7
    for r in rows[1:]:
        r[3] = f"{math.radians(float(r[3])) % (2 * math.pi):.6f}" if r[3] != "1e308" else "1.0"
    path.write_text("\n".join(",".join(r) for r in rows) + "\n")
    rec = read_recording(path)
    assert rec.warnings == [] and len(rec.misread) == 1 and rec.misread[0].startswith("heading_deg spans only 6.2")
    assert "the column looks like radians (name it psi for radians, or give degrees)" in rec.misread[0]
    assert f"warning: {rec.misread[0]} (identify, evaluate and diagnose refuse" in format_summary(rec.summary())
    for command in (["identify", "--params", "thrust_gain"], ["evaluate"], ["diagnose"]):
        done = twin_command.twin(command[0], str(path), "--vessel", "yellowfish", *command[1:],
                                 "--out" if command[0] == "identify" else "--json", str(tmp_path / "out.json"))
        assert done.returncode == 2 and done.stderr.strip().splitlines() == [
            f"error: run.csv: {rec.misread[0]}"], (command, done.stderr)
        assert not (tmp_path / "out.json").exists()
    info = twin_command.twin("info", str(path), "--vessel", "yellowfish")
    assert "calibration: run.csv: none, as the log is read in a unit it is not in" in info.stdout
    # nor converted: a copy in another format would carry the error on without the word of it
    done = twin_command.twin("convert", str(path), str(tmp_path / "copy.mcap"))
    assert done.returncode == 2 and done.stderr.strip() == f"error: run.csv: {rec.misread[0]}"
    assert not (tmp_path / "copy.mcap").exists()


def test_a_directory_is_not_a_missing_file(tmp_path):
    with pytest.raises(TwinError, match="is a directory"):
        read_recording(tmp_path)


def test_hold_is_causal():
    ts = np.array([0.0, 1.0, 2.0])
    got = hold(ts, np.array([10.0, 20.0, 30.0]), np.array([-0.5, 0.0, 0.5, 0.999, 1.0, 1.5, 2.5]))
    assert np.isnan(got[0]) and list(got[1:]) == [10.0, 10.0, 10.0, 20.0, 20.0, 30.0]


def test_a_heading_logged_between_grid_times_turns_the_velocity_by_the_heading_of_that_time():
    """A boat on a circle (u 1.5 m/s, r 0.2 rad/s, no sideslip): heading at 10 Hz stamped 0.01 s
    after each GNSS and PWM sample, as an autopilot's attitude and GNSS messages are. Held on the grid, ψ
    lags the velocities by 0.09 s and v reads u·r·0.09 = 0.027 m/s; read between its samples, 0."""
    from twin.recording import Recording, Stream

    u, r, radius = 1.5, 0.2, 1.5 / 0.2
    tg = np.arange(0.0, 60.0, 0.2)
    th = np.arange(-0.09, 60.0, 0.1)  # the grid starts with the GNSS at 0: a sample 0.09 s before each grid time
    tp = np.arange(0.0, 60.0, 0.1)
    rec = Recording("circle.csv", "csv",
                    gnss=Stream(tg, {"north_m": radius * np.sin(r * tg), "east_m": radius * (1 - np.cos(r * tg))}),
                    heading=Stream(th, {"psi_rad": r * th}),
                    pwm=Stream(tp, {"left_us": np.full(len(tp), 1700.0), "right_us": np.full(len(tp), 1600.0)}))
    p = prepare(rec)
    inner = slice(20, -20)  # away from the ends, where the velocity smoother is one-sided
    assert np.abs(p.psi - r * p.t).max() < 1e-9
    assert np.abs(p.v[inner]).max() < 0.003 and np.abs(p.u[inner] - u).max() < 0.01
    psi_held = hold(th, r * th, p.t)
    assert np.abs(psi_held - r * p.t).max() == pytest.approx(r * 0.09, rel=1e-6)  # what holding it did


def test_geodetic_to_ned_matches_exact_within_a_km():
    n = np.array([0.0, 300.0, -800.0, 50.0])
    e = np.array([0.0, -200.0, 600.0, 1000.0])
    lat, lon = ned_to_geodetic(n, e)
    n2, e2 = geodetic_to_ned(lat, lon, LAT0, LON0, H0)
    assert np.max(np.hypot(n2 - n, e2 - e)) < 0.2  # flat earth over 1 km: ~0.1 m
    small = np.hypot(n, e) < 400
    assert np.max(np.hypot(n2 - n, e2 - e)[small]) < 0.02


def test_increasing_subsequence_drops_wild_stamps():
    t = np.array([0.0, 0.1, 0.2, 50.0, 0.3, 0.4, 0.25, 0.5])
    assert list(increasing_subsequence(t)) == [0, 1, 2, 4, 5, 7]
    # a stamp that jumps back is the row dropped, not the good row before it (both runs are as long)
    assert list(increasing_subsequence(np.array([0.0, -1.0, 2.0, 3.0]))) == [0, 2, 3]
    assert list(increasing_subsequence(np.array([0.0, 1.0, 5.0, 2.0, 3.0, 4.0]))) == [0, 1, 3, 4, 5]


# ---------------------------------------------------------------- ../shared data

def _shared(sub: str) -> list[Path]:
    folder = SHARED / "data" / sub
    if not folder.is_dir():
        pytest.skip("../shared is not present")
    return sorted(folder.iterdir())


def test_shared_ardupilot_logs_summaries():
    files = {p.name: p for p in _shared("ardupilot")}
    sums = {}
    for name, path in files.items():
        rec = read_recording(path)
        sums[name] = (rec, rec.summary())
        assert rec.duration_s() > 10 and sums[name][1]["streams"]["heading"]["samples"] > 100
        assert sums[name][1]["parameters"] > 50
    rec, s = sums["ardusub_corrupted.tlog"]
    assert dict(rec.dropped)["tlog: packets with bad CRC"] > 1000
    assert s["streams"]["gnss"]["samples"] == 0 and any("no GNSS" in n for n in s["notes"])
    for name in ("ardusub_small.BIN", "erle_rover_2014.BIN"):
        assert any("the log has no GPS messages" in n for n in sums[name][1]["notes"])
    assert sums["ardusub_small.tlog"][1]["streams"]["gnss"]["samples"] > 400
    assert sums["sitl_motorboat.tlog"][1]["streams"]["gnss"]["rate_hz"] == pytest.approx(5, rel=0.05)
    assert any("no thruster channels" in n for n in sums["sitl_motorboat.tlog"][1]["notes"])
    rec = read_recording(files["sitl_motorboat.tlog"], channels={"left": 1, "right": 3})
    assert len(prepare(rec).t) > 2000


def test_a_log_is_read_by_what_it_holds_whatever_it_is_named(tmp_path):
    """A telemetry log renamed .bin (its first records no MAVLink packets) and a DataFlash log renamed .tlog
    read as what they are, as the same logs under their own names."""
    files = {p.name: p for p in _shared("ardupilot")}
    for name, other in (("sitl_motorboat.tlog", "copy.bin"), ("ardusub_small.BIN", "copy.tlog")):
        copy = tmp_path / other
        copy.write_bytes(files[name].read_bytes())
        as_named, renamed = read_recording(files[name]), read_recording(copy)
        assert renamed.kind == as_named.kind and np.array_equal(renamed.heading.t, as_named.heading.t), name


def blueboat_correlations(path: Path) -> tuple[float, float]:
    """corr(u, surge), corr(r, yaw_rate) of the prepared file against its own columns."""
    rec = read_recording(path)
    p = prepare(rec)
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    ts = np.array([float(r["original_timestamp"]) for r in rows]) * 1e-3
    i = np.searchsorted(ts, p.t + rec.origin_s - 1e-6)
    surge = np.array([float(rows[k]["surge"] or "nan") for k in i])
    yaw_rate = np.array([float(rows[k]["yaw_rate"] or "nan") for k in i])
    ok = np.isfinite(surge) & np.isfinite(yaw_rate)
    return float(np.corrcoef(p.u[ok], surge[ok])[0, 1]), float(np.corrcoef(p.r[ok], yaw_rate[ok])[0, 1])


def test_shared_blueboat_velocities_match_the_authors():
    files = _shared("blueboat")
    assert len(files) == 10
    corr = {f.name: blueboat_correlations(f) for f in files}
    assert min(cu for cu, _ in corr.values()) > 0.99, corr
    assert min(cr for _, cr in corr.values()) > 0.7, corr  # fixed_00000221 barely turns: 0.75
    assert np.median([cr for _, cr in corr.values()]) > 0.97, corr


@pytest.mark.parametrize("suffix", [".mcap", ".csv", ".bin"])
def test_shared_ardupilot_logs_all_convert(tmp_path, suffix):
    """Three of the five shared logs have no GNSS; they must still convert. Every one
    converts, and reads back with its heading, IMU, battery (and parameters where kept)."""
    from twin.formats import write_recording
    from twin.prepare.convert import for_conversion

    for path in _shared("ardupilot"):
        rec = read_recording(path)
        if not len(rec.gnss):  # a grid asked for, where none can be had, is refused, not skipped
            with pytest.raises(TwinError, match=r"cannot be put on a grid \(no GNSS samples"):
                for_conversion(rec, 0.1)
        conversion = for_conversion(rec, 0.1) if len(rec.gnss) else for_conversion(rec)
        assert conversion.synchronised == (len(rec.gnss) > 0), path.name
        write_recording(conversion.recording, tmp_path / f"{path.stem}{suffix}")
        back = read_recording(tmp_path / f"{path.stem}{suffix}")
        for name in ("heading", "imu", "battery") if not conversion.synchronised else ("imu", "battery"):
            assert len(getattr(back, name)) == len(getattr(rec, name)), (path.name, name)
        assert len(back.parameters) == (0 if suffix == ".csv" else len(rec.parameters)), path.name


def test_the_summary_says_how_far_the_pack_sagged_and_preparation_holds_it():
    from twin.recording import Recording, Stream

    rec = Recording(source="pack.csv", kind="csv")
    rec.battery = Stream(np.array([2.0, 3.0, 4.0, 5.0]), {"voltage_v": np.array([16.1, 15.2, 15.6, 14.9])})
    s = rec.summary()["streams"]["battery"]
    keys = ("voltage_first_v", "voltage_last_v", "voltage_min_v", "voltage_max_v")
    assert tuple(s[k] for k in keys) == (16.1, 14.9, 14.9, 16.1)
    assert "16.10 → 14.90 V (range 14.90-16.10)" in format_summary(rec.summary())
    from twin.prepare.prepared import supply_voltage

    held = supply_voltage(rec, np.array([0.0, 2.5, 4.0, 9.0]))  # before the first reading: the first
    np.testing.assert_array_equal(held, [16.1, 16.1, 15.6, 14.9])
    assert supply_voltage(Recording(source="none.csv", kind="csv"), np.array([0.0])) is None


def test_a_log_without_a_gyro_converts_to_a_tlog_without_one(tmp_path):
    """ATTITUDE carries a yaw rate whether or not the log had one: written as 0, it would read back as a
    gyro that never turns (and `twin info` would judge the heading against it); so NaN, read as none."""
    from twin.formats import write_recording

    rec = read_recording(write_generic_csv(tmp_path / "g.csv"))
    assert len(rec.imu) == 0 and len(rec.heading) > 0
    write_recording(rec, tmp_path / "g.tlog")
    back = read_recording(tmp_path / "g.tlog")
    assert len(back.imu) == 0 and len(back.heading) == len(rec.heading)
    assert not any("imu" in what for what, _ in back.dropped)


def test_a_grid_step_longer_than_half_the_recording_is_refused(tmp_path):
    from twin.prepare.convert import for_conversion

    rec = read_recording(write_generic_csv(tmp_path / "g.csv"))
    with pytest.raises(TwinError, match=r"--grid-dt 1e\+09 s leaves fewer than two samples in this"):
        for_conversion(rec, grid_dt=1e9)
    assert for_conversion(rec, grid_dt=rec.duration_s() / 4).synchronised


def test_a_local_position_no_place_on_earth_can_have_is_dropped_and_counted(tmp_path):
    """A twin run's CSV (x, y in metres) with fixes at 1e308 m: counted as dropped, not prepared
    into overflow warnings."""
    import twin

    path = tmp_path / "run.csv"
    twin.simulate_run("blueboat", scenario="turn", duration_s=20).write(path)
    rows = path.read_text().splitlines()
    x = rows[0].split(",").index("x")
    for k in (50, 51, 120):
        cells = rows[k].split(",")
        cells[x] = "1e308"
        rows[k] = ",".join(cells)
    path.write_text("\n".join(rows) + "\n")
    rec = read_recording(path)
    assert dict(rec.dropped)["gnss: position beyond 20 000 km"] == 3
    assert np.abs(rec.gnss["north_m"]).max() < 1e3


def test_a_column_twice_is_refused_and_columns_read_in_place_of_others_or_a_time_in_ms_are_warned_of(tmp_path):
    """Which of two heading_deg columns a reader took would be a guess: refused. Positions given as
    lat, lon and as north, east, or a heading as heading_deg and psi: the one read is named. A t in
    milliseconds (10 Hz steps of 100 'seconds') is said as read in the wrong unit (Recording.misread)."""
    path = write_generic_csv(tmp_path / "run.csv")
    rows = [r.split(",") for r in path.read_text().splitlines()]
    twice = tmp_path / "twice.csv"
    twice.write_text("\n".join(",".join(r + [r[3]]) for r in rows) + "\n")
    with pytest.raises(TwinError, match=r"twice.csv: column heading_deg appears more than once in the header"):
        read_recording(twice)
    both = tmp_path / "both.csv"
    both.write_text("\n".join(",".join(r + (["north", "east", "psi"] if i == 0 else ["0", "0", "0"]))
                              for i, r in enumerate(rows)) + "\n")
    assert read_recording(both).warnings == ["both lat, lon and north, east columns: lat, lon read, north, east not",
                                             "both heading_deg and psi columns: heading_deg read, psi not"]
    ms = tmp_path / "ms.csv"
    ms.write_text("\n".join(",".join([r[0] if i == 0 else f"{float(r[0]) * 1000:.0f}"] + r[1:])
                            for i, r in enumerate(rows)) + "\n")
    assert any(w.startswith("t steps by 100 s (median): the generic CSV's t is in seconds")
               for w in read_recording(ms).misread)


@pytest.mark.parametrize("data,why", [
    (b"t,lat,lon,heading_deg\n0,1,2,caf\xe9\n1,1,2,3\n", "not UTF-8 text: byte 0xe9 on line 2 (save it as UTF-8)"),
    (b"t;lat;lon;heading_deg\n0;1;2;3\n", "its columns are separated by ';' or tabs"),
    (b"\x1f\x8b\x08\x00\x00\x00", "gzip-compressed: uncompress it first"),
])
def test_a_csv_that_cannot_be_read_says_why(tmp_path, data, why):
    path = tmp_path / "log.csv"
    path.write_bytes(data)
    with pytest.raises(TwinError, match=rf"log.csv: not a recognised recording \({re.escape(why)}"):
        read_recording(path)


def test_a_rerun_recording_given_as_a_log_is_sent_to_rerun(tmp_path):
    path = tmp_path / "run.rrd"
    path.write_bytes(b"RRF2\x00\x00\x00\x00")
    with pytest.raises(TwinError, match=re.escape("run.rrd: not a recognised recording (a rerun recording is shown "
                                                  "by rerun itself: `rerun run.rrd`)")):
        read_recording(path)


def test_a_dataset_layout_short_of_a_column_is_told_which(tmp_path):
    from twin.formats import read_recording

    blueboat = tmp_path / "bb.csv"
    blueboat.write_text("original_timestamp,lat,lon,yaw,thr_right\n0,63.4,10.4,0.1,1500\n100,63.4,10.4,0.1,1500\n")
    with pytest.raises(TwinError, match="looks like the BlueBoat dataset's layout but lacks the column thr_left"):
        read_recording(blueboat)
    esso = tmp_path / "esso.csv"
    header = ["t [s]", "x_position_mid [m]", "y_position_mid [m]", "psi_hat [rad]", "delta_rudder [rad]"]
    esso.write_text(",".join(header) + "\n" + "\n".join(f"{0.1 * k},{0.01 * k},0,0,0" for k in range(50)) + "\n")
    with pytest.raises(TwinError, match=re.escape("lacks the column n_prop [rps]")):
        read_recording(esso)
    unknown = tmp_path / "other.csv"
    unknown.write_text("a,b\n1,2\n")
    with pytest.raises(TwinError, match="CSV layout not recognised"):
        read_recording(unknown)
    # an Esso file without its wind columns says so once, and does not also describe a wind it lacks
    esso.write_text(",".join([*header, "n_prop [rps]"]) + "\n"
                    + "\n".join(f"{0.1 * k},{0.01 * k},0,0,0,5" for k in range(50)) + "\n")
    notes = read_recording(esso).notes
    assert any(n.startswith("no wind") for n in notes) and not any(n.startswith("wind: measured") for n in notes)


def test_a_conversion_says_which_streams_it_held_or_thinned_to_the_grid():
    """A 5-Hz GNSS on a 0.1-s grid repeats each fix: the file would show it at 10 Hz, so the
    conversion says so; a stream at the grid's own rate is not mentioned."""
    from twin.prepare.convert import for_conversion
    from twin.recording import Recording, Stream

    t = np.arange(0.0, 30.0, 0.02)
    rec = Recording(source="rates.csv", kind="csv")
    gnss_t = t[::10]  # 5 Hz
    rec.gnss = Stream(gnss_t, {"north_m": 0.5 * gnss_t, "east_m": 0.0 * gnss_t})
    rec.heading = Stream(t, {"psi_rad": np.zeros(len(t))})  # 50 Hz
    pwm_t = t[::5]  # 10 Hz, the grid's
    rec.pwm = Stream(pwm_t, {"left_us": np.full(len(pwm_t), 1600.0), "right_us": np.full(len(pwm_t), 1600.0)})
    timing = for_conversion(rec, 0.1).timing
    assert "gnss recorded at 5 Hz, each sample held until the next (rows up to 0.2 s after it was taken)" in timing
    assert "heading recorded at 50 Hz, interpolated at the grid's times" in timing
    assert "pwm recorded" not in timing and "the grid covers" not in timing
    # a heading that starts 5 s before the GNSS: the grid's span, and what lies outside it, are said
    rec.heading = Stream(np.r_[np.arange(-5.0, 0.0, 0.02), t], {"psi_rad": np.zeros(len(t) + 250)})
    timing = for_conversion(rec, 0.1).timing
    assert "the grid covers 29.8 s where the GNSS and the heading both run, of the recording's 35.0 s" in timing


def test_a_stream_that_lost_a_share_of_its_samples_is_named_by_the_commands_using_it(tmp_path, monkeypatch, capsys):
    """One backwards stamp in 401 rows costs one row, under LOST_SHARE: nothing said. Sixty rows
    stamped 20 s back (15 % of the rows) are dropped from every stream, and `twin evaluate`, which
    scores the rest, and `twin view` say so per stream, as `twin info` does."""
    few = read_recording(write_generic_csv(tmp_path / "few.csv", latlon=False))
    assert few.heavy_losses() == []
    path = write_generic_csv(tmp_path / "many.csv", latlon=False)
    lines = path.read_text().splitlines()
    rows = [line.split(",") for line in lines[1:]]
    for row in rows:  # a wobble on the steady circle: velocities that vary, for evaluate to score
        if row[1] != "nan":
            row[1] = f"{float(row[1]) + 0.5 * math.sin(0.3 * float(row[0])):.6f}"
    for row in rows[200:260]:
        row[0] = f"{float(row[0]) - 20.0:.3f}"
    path.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    losses = read_recording(path).heavy_losses()
    assert [line.split(":")[0] for line in losses] == ["gnss", "heading", "pwm"]
    # the one backwards stamp write_generic_csv puts in, and the sixty
    assert all("samples with time going backwards 61" in line and " of 401 samples" in line for line in losses)
    assert all(line.endswith("; the rest is used") for line in losses)
    # a reader's own count (a tlog's bytes outside packets) is no stream's samples: not said as one
    few.dropped.append(("tlog: bytes outside valid MAVLink packets", 5000))
    assert few.heavy_losses() == []
    monkeypatch.setattr(sys, "argv", ["twin", "evaluate", str(path), "--vessel", "yellowfish"])
    try:
        cli.main()
    except SystemExit as exit_info:
        assert exit_info.code in (0, None)
    err = capsys.readouterr().err
    assert sum("many.csv: " in line and "samples dropped" in line for line in err.splitlines()) == 3
    monkeypatch.setattr(sys, "argv", ["twin", "view", str(path), "--out", str(tmp_path / "many.rrd")])
    try:  # the view of the log says it too
        cli.main()
    except SystemExit as exit_info:
        assert exit_info.code in (0, None)
    err = capsys.readouterr().err
    assert sum("many.csv: " in line and "samples dropped" in line for line in err.splitlines()) == 3


def test_a_dataflash_log_with_a_damaged_format_is_read_without_that_messages_type(tmp_path):
    """A card's damage in one FMT record (a format character no DataFlash field type has) made
    pymavlink refuse the whole log: the other types are read, the damaged one is left out and counted."""
    from twin.recording import Recording, Stream

    th = np.arange(0, 500) * 0.02
    tg = th[::10]
    rec = Recording(source="x", kind="synthetic", heading=Stream(th, {"psi_rad": 0.1 * th}),
                    gnss=Stream(tg, {"lat_deg": 63.4 + 1e-6 * tg, "lon_deg": np.full(len(tg), 10.3),
                                     "alt_m": np.zeros(len(tg))}), parameters={"FRAME_CLASS": 2.0})
    write_recording(rec, tmp_path / "ok.bin")
    data = bytearray((tmp_path / "ok.bin").read_bytes())
    parm = data.find(b"\xa3\x95\x80\x40")  # the FMT record of type 64, PARM
    assert parm >= 0 and bytes(data[parm + 5:parm + 9]) == b"PARM"
    data[parm + 9] = ord("?")
    (tmp_path / "damaged.bin").write_bytes(bytes(data))
    back = read_recording(tmp_path / "damaged.bin")
    assert len(back.heading) == len(th) and len(back.gnss) == len(tg) and back.parameters == {}
    assert ("dataflash: a damaged FMT record, its PARM messages left out", 1) in back.dropped
    data[:3] = b"xyz"  # beyond its formats: still refused in one line
    (tmp_path / "worse.bin").write_bytes(bytes(data[:200]))
    with pytest.raises(TwinError, match="worse.bin"):
        read_recording(tmp_path / "worse.bin")


def test_a_conversion_says_what_its_format_reads_at_other_times_or_leaves_out():
    """A .tlog carries the gyro in ATTITUDE: a 25-Hz gyro beside a 10-Hz heading is read at the
    heading's times, and said; one at the heading's times less its filter's stated delay is written
    back as ArduPilot stamped it, so nothing is said. A .csv has no roll and pitch: said."""
    from twin.prepare.convert import not_kept
    from twin.recording import Recording, Stream

    th, tg = np.arange(0, 100) * 0.1, np.arange(0, 250) * 0.04
    rec = Recording(source="g", kind="csv", heading=Stream(th, {"psi_rad": 0.1 * th}),
                    imu=Stream(tg, {"yaw_rate_rads": np.full(len(tg), 0.1)}),
                    attitude=Stream(th, {"roll_rad": 0 * th, "pitch_rad": 0 * th}))
    said = not_kept(rec, ".tlog")
    assert any("the 250 gyro samples are read at the heading's 100 times" in line for line in said), said
    delay = np.sqrt(2) / (2 * np.pi * 4.0)
    rec.imu, rec.parameters = Stream(th - delay, {"yaw_rate_rads": 0.1 + 0 * th}), {"INS_GYRO_FILTER": 4.0}
    assert not any("gyro samples" in line for line in not_kept(rec, ".tlog"))
    assert any("the 100 attitude samples are left out" in line for line in not_kept(rec, ".csv"))
