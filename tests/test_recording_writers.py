"""write_recording: synthetic sensor recordings → .csv / .tlog / .mcap → read_recording
gives back the same streams (times, values, gaps) to each format's resolution."""
import json
import re
from collections import Counter
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest
from mcap.reader import make_reader
from twin_command import twin

from twin.errors import TwinError
from twin.geodesy import geodetic_from_ned, ned_from_geodetic
from twin.recording import Recording, Stream
from twin.prepare import prepare
from twin.formats import read_recording, write_recording
from twin.formats.tlog import iter_tlog

ORIGIN = (37.4136, -5.9786)
SEGMENTS_S = ((0.0, 30.0), (38.0, 60.0))  # two trajectory segments, an 8 s silence between them
GAP_S = 8.0
PWM_OFFSET_S = 0.0371234  # the PWM clock runs late against the others, off the ms grid


class Resolution(NamedTuple):
    t_s: float  # GNSS, PWM, IMU times
    heading_t_s: float
    latlon_deg: float
    psi_rad: float
    alt_m: float


RESOLUTION = {
    ".csv": Resolution(1e-6, 1e-6, 1e-9, 1e-8, 1e-4),
    ".tlog": Resolution(1e-6, 5e-4 + 1e-9, 1e-7, 3e-7, 1e-3),  # ATTITUDE ms, float32 yaw, 1e-7 deg ints
    ".mcap": Resolution(1e-9, 1e-9, 1e-12, 1e-12, 1e-12),
    ".bin": Resolution(1e-6, 1e-6, 1e-7, np.radians(0.005) + 1e-9, 0.005 + 1e-9),  # ATT centidegrees, alt cm
}


def times(rate_hz: float, offset_s: float = 0.0) -> np.ndarray:
    return np.concatenate([a + offset_s + np.arange(round((b - a) * rate_hz)) / rate_hz for a, b in SEGMENTS_S])


def synthetic(seed: int = 7, *, pwm_offset_s: float = PWM_OFFSET_S, north_east: bool = False,
              extras: bool = False) -> Recording:
    """A boat circling at 0.2 rad/s (ψ crosses ±180° several times): GNSS 5 Hz with
    0.3 m noise, heading 50 Hz with 0.5° noise and a 2° bias, integer PWM 10 Hz."""
    rng = np.random.default_rng(seed)
    psi = lambda t: 2.5 + 0.2 * t  # noqa: E731
    tg = times(5)
    north = 5 * np.sin(psi(tg)) + rng.normal(0, 0.3, len(tg))
    east = 5 * (1 - np.cos(psi(tg))) + rng.normal(0, 0.3, len(tg))
    if north_east:
        gnss = Stream(tg, {"north_m": north, "east_m": east})
    else:
        lat, lon = geodetic_from_ned(north, east, *ORIGIN)
        gnss = Stream(tg, {"lat_deg": lat, "lon_deg": lon, "alt_m": rng.normal(0, 0.5, len(tg))})
    th = times(50)
    heading = Stream(th, {"psi_rad": np.angle(np.exp(1j * (psi(th) + np.radians(2 + rng.normal(0, 0.5, len(th))))))})
    tp = times(10, pwm_offset_s)
    pwm = Stream(tp, {"left_us": rng.integers(1100, 1901, len(tp)).astype(float),
                      "right_us": rng.integers(1100, 1901, len(tp)).astype(float)})
    rec = Recording(source="synthetic", kind="synthetic", gnss=gnss, heading=heading, pwm=pwm, origin_s=1000.0)
    if extras:
        rec.imu = Stream(th, {"yaw_rate_rads": 0.2 + rng.normal(0, 0.01, len(th))})
        tb = times(1)
        rec.battery = Stream(tb, {"voltage_v": np.round(16.4 - 0.01 * tb, 3)})
    return rec


def listing(d: Path) -> list[str]:
    return sorted(p.name for p in d.iterdir())


def wrapped(a: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * a))


@pytest.fixture(scope="module")
def rec() -> Recording:
    return synthetic()


@pytest.mark.parametrize("suffix", [".csv", ".tlog", ".mcap", ".bin"])
def test_round_trip(rec, tmp_path, suffix):
    res = RESOLUTION[suffix]
    out = tmp_path / f"synthetic{suffix}"
    write_recording(rec, out)
    assert listing(tmp_path) == [out.name]  # no temporary file left
    back = read_recording(out)

    for name, t_res in (("gnss", res.t_s), ("heading", res.heading_t_s), ("pwm", res.t_s)):
        assert len(getattr(back, name)) == len(getattr(rec, name)), name
        np.testing.assert_allclose(getattr(back, name).t, getattr(rec, name).t, rtol=0, atol=t_res, err_msg=name)
    for col in ("lat_deg", "lon_deg"):
        np.testing.assert_allclose(back.gnss[col], rec.gnss[col], rtol=0, atol=res.latlon_deg)
    np.testing.assert_allclose(back.gnss["alt_m"], rec.gnss["alt_m"], rtol=0, atol=res.alt_m)
    assert np.max(np.abs(wrapped(back.heading["psi_rad"] - rec.heading["psi_rad"]))) <= res.psi_rad
    np.testing.assert_array_equal(back.pwm["left_us"], rec.pwm["left_us"])
    np.testing.assert_array_equal(back.pwm["right_us"], rec.pwm["right_us"])
    assert tuple(back.pwm_neutral_us) == (1500.0, 1500.0)

    for name, dt in (("gnss", 0.2), ("heading", 0.02), ("pwm", 0.1)):
        np.testing.assert_allclose(getattr(back, name).gaps(), [GAP_S + dt], atol=1e-3, err_msg=name)
    if suffix != ".csv":  # the CSV reader counts a row's empty cells as missing samples
        assert back.dropped and all("dropouts" in reason for reason, _ in back.dropped), back.dropped
    prep = prepare(back)
    assert len(prep.segments) == 2
    assert prep.segments[0].t1 < SEGMENTS_S[0][1] <= SEGMENTS_S[1][0] <= prep.segments[1].t0


def test_tlog_maps_the_thrusters_back(rec, tmp_path):
    write_recording(rec, tmp_path / "r.tlog")
    back = read_recording(tmp_path / "r.tlog")
    assert (back.channels["left"], back.channels["right"]) == (1, 3)
    assert back.channels["from"] == "SERVOn_FUNCTION"
    counts: Counter = Counter()
    msgs = list(iter_tlog((tmp_path / "r.tlog").read_bytes(), ("HEARTBEAT", "GPS_RAW_INT"), counts))
    beats = [t for t, m in msgs if m.get_type() == "HEARTBEAT"]
    assert all(m.type == 11 for _, m in msgs if m.get_type() == "HEARTBEAT")  # MAV_TYPE_SURFACE_BOAT
    np.testing.assert_allclose(np.diff(beats), 1.0)
    assert len(beats) == int(rec.pwm.t[-1]) + 1
    assert {m.fix_type for _, m in msgs if m.get_type() == "GPS_RAW_INT"} == {3}
    assert counts["bad_crc"] == counts["skipped_bytes"] == counts["truncated"] == 0


def test_mcap_topics_are_foxglove_readable(rec, tmp_path):
    out = tmp_path / "r.mcap"
    write_recording(rec, out)
    with open(out, "rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        schemas = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
        log_times = [m.log_time for _, _, m in reader.iter_messages(log_time_order=False)]
        fixes = [(m.log_time, json.loads(m.data)) for _, _, m in reader.iter_messages(topics=["/sensors/gnss"])]
        heading = [json.loads(m.data) for _, _, m in reader.iter_messages(topics=["/sensors/heading"])]
    assert {t: s.name for t, s in schemas.items()} == {
        "/sensors/gnss": "foxglove.LocationFix", "/sensors/heading": "twin.Heading", "/sensors/pwm": "twin.ThrusterPwm"}
    assert all(s.encoding == "jsonschema" for s in schemas.values())
    assert log_times == sorted(log_times)  # written in time order across topics
    required = json.loads(schemas["/sensors/gnss"].data)["required"]
    log_time, fix = fixes[3]
    assert set(required) <= set(fix) and fix["position_covariance_type"] == 0
    assert fix["timestamp"]["sec"] * 10**9 + fix["timestamp"]["nsec"] == log_time == round(rec.gnss.t[3] * 1e9)
    assert 0 <= min(h["heading_deg"] for h in heading) and max(h["heading_deg"] for h in heading) < 360


def test_optional_streams(tmp_path):
    rec = synthetic(3, extras=True)
    for suffix in (".csv", ".tlog", ".mcap", ".bin"):
        write_recording(rec, tmp_path / f"r{suffix}")
        back = read_recording(tmp_path / f"r{suffix}")
        np.testing.assert_allclose(back.imu.t, rec.imu.t, atol=RESOLUTION[suffix].heading_t_s)
        np.testing.assert_allclose(back.imu["yaw_rate_rads"], rec.imu["yaw_rate_rads"], atol=1e-7)
        volt_res = 1e-6 if suffix == ".bin" else 1e-9  # DataFlash float32
        np.testing.assert_allclose(back.battery["voltage_v"], rec.battery["voltage_v"], atol=volt_res)
        # SYS_STATUS has no time of its own: the reader maps its receive time through ATTITUDE's ms clock
        np.testing.assert_allclose(back.battery.t, rec.battery.t, atol=1e-3 if suffix == ".tlog" else 1e-6)


@pytest.mark.parametrize("suffix", [".tlog", ".mcap", ".bin"])
def test_parameters_are_kept_where_the_format_has_room(tmp_path, suffix):
    """A log's parameters survive conversion; in an autopilot log the source's own throttle channels
    give way to the mapping the file's PWM is written with, or the reader would pick the wrong
    channels (MCAP stores left/right PWM by name and keeps every parameter as it was)."""
    rec = synthetic(4)
    rec.parameters = {"FRAME_CLASS": 2.0, "CRUISE_SPEED": 1.25, "SERVO5_FUNCTION": 74.0, "SERVO7_FUNCTION": 33.0}
    rec.pwm_neutral_us = (1511.0, 1490.0)
    write_recording(rec, tmp_path / f"r{suffix}")
    back = read_recording(tmp_path / f"r{suffix}")
    assert back.parameters["FRAME_CLASS"] == 2.0 and back.parameters["SERVO7_FUNCTION"] == 33.0
    assert back.parameters["CRUISE_SPEED"] == pytest.approx(1.25, rel=1e-7)  # float32 in the logs
    if suffix == ".mcap":
        assert back.parameters == rec.parameters
    else:
        assert back.parameters.get("SERVO5_FUNCTION") != 74.0
    assert tuple(back.pwm_neutral_us) == (1511.0, 1490.0)
    np.testing.assert_array_equal(back.pwm["left_us"], rec.pwm["left_us"])


def test_csv_header_and_empty_cells(rec, tmp_path):
    write_recording(rec, tmp_path / "r.csv")
    lines = (tmp_path / "r.csv").read_text().splitlines()
    assert lines[0] == "t,lat,lon,alt,heading_deg,pwm_left,pwm_right"
    assert lines[1].startswith("0.000000,37.")  # t = 0: GNSS and heading together, PWM comes later
    assert lines[1].endswith(",,")
    assert len(lines) - 1 == len(np.unique(np.round(np.concatenate([rec.gnss.t, rec.heading.t, rec.pwm.t]) * 1e6)))


def test_north_east(tmp_path):
    rec = synthetic(5, north_east=True)
    write_recording(rec, tmp_path / "r.csv")
    assert (tmp_path / "r.csv").read_text().startswith("t,north,east,heading_deg,")
    back = read_recording(tmp_path / "r.csv")
    np.testing.assert_allclose(back.gnss["north_m"], rec.gnss["north_m"], atol=1e-6)
    # .tlog stores latitude/longitude: the local frame is placed at `origin`
    write_recording(rec, tmp_path / "r.tlog", origin=ORIGIN)
    back = read_recording(tmp_path / "r.tlog")
    north, east = ned_from_geodetic(back.gnss["lat_deg"], back.gnss["lon_deg"], *ORIGIN)
    np.testing.assert_allclose(north, rec.gnss["north_m"], atol=0.01)
    np.testing.assert_allclose(east, rec.gnss["east_m"], atol=0.01)


def test_samples_before_the_origin_shift_every_stream_together(tmp_path):
    rec = synthetic(9, pwm_offset_s=-0.05)  # the first PWM sample is 50 ms before the origin
    write_recording(rec, tmp_path / "r.mcap")
    back = read_recording(tmp_path / "r.mcap")
    assert back.pwm.t[0] == 0.0
    for name in ("gnss", "heading", "pwm"):  # absolute times (origin + t) are kept
        np.testing.assert_allclose(getattr(back, name).t + back.origin_s, getattr(rec, name).t + rec.origin_s,
                                   rtol=0, atol=1e-9)


def test_bad_paths_raise_and_leave_nothing(rec, tmp_path):
    with pytest.raises(TwinError, match="unknown recording format"):
        write_recording(rec, tmp_path / "r.txt")
    with pytest.raises(TwinError, match="does not exist"):
        write_recording(rec, tmp_path / "missing" / "r.tlog")
    assert listing(tmp_path) == []


def test_bad_recordings_raise_and_keep_the_old_file(rec, tmp_path):
    out = tmp_path / "r.mcap"
    out.write_bytes(b"old")
    bad = synthetic(1)
    bad.heading.columns["psi_rad"][5] = np.nan
    with pytest.raises(TwinError, match="heading.psi_rad"):
        write_recording(bad, out)
    with pytest.raises(TwinError, match="no samples"):
        write_recording(Recording(source="empty", kind="synthetic"), out)
    assert listing(tmp_path) == ["r.mcap"] and out.read_bytes() == b"old"


def test_csv_keeps_a_pwm_neutral_other_than_1500(tmp_path):
    """The BlueBoat's thrusters stop at 1511 µs: the generic CSV says so in two columns."""
    odd = synthetic(1)
    odd.pwm_neutral_us = (1511.0, 1509.0)
    write_recording(odd, tmp_path / "r.csv")
    assert (tmp_path / "r.csv").read_text().splitlines()[0].endswith("pwm_right,pwm_neutral_left,pwm_neutral_right")
    back = read_recording(tmp_path / "r.csv")
    assert tuple(back.pwm_neutral_us) == (1511.0, 1509.0)
    np.testing.assert_array_equal(back.pwm["right_us"], odd.pwm["right_us"])
    # a neutral no ESC has (a unit slip), or a column of no number, is refused naming it, not taken as 1500
    text = (tmp_path / "r.csv").read_text()
    for value, said in (("1e9", "is 1e+09 µs: a PWM of zero thrust lies between 1000 and 2000 µs"),
                        ("abc", "holds no number")):
        (tmp_path / "bad.csv").write_text(text.replace(",1511,", f",{value},"))
        with pytest.raises(TwinError, match=re.escape(f"bad.csv: column pwm_neutral_left {said}")):
            read_recording(tmp_path / "bad.csv")


def test_failed_rename_leaves_no_temporary(rec, tmp_path, monkeypatch):
    import twin.files as files

    def refuse(src, dst):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(files.os, "replace", refuse)
    with pytest.raises(TwinError, match="cannot write"):
        write_recording(rec, tmp_path / "r.tlog")
    assert listing(tmp_path) == []


def test_run_mcap_reads_as_states(tmp_path):
    from twin.run import Run
    from twin.formats.mcap import write_run_mcap

    t = np.arange(50) * 0.1
    run = Run(t, np.column_stack([t, 2 * t, 0.1 * t]), np.zeros((50, 3)), np.full((50, 2), 1600.0),
              np.zeros((50, 2)))
    write_run_mcap(run, tmp_path / "run.mcap")
    back = read_recording(tmp_path / "run.mcap")
    assert back.gnss.has("north_m", "east_m") and not back.gnss.has("lat_deg")
    np.testing.assert_allclose(back.gnss["east_m"], 2 * t)


def test_mcap_cut_short_reads_its_complete_part(tmp_path):
    """A recording MCAP cut in half (full disk, killed logger) gives every sample of its complete
    chunks, with its origin and neutral (the metadata comes first) and a note of the loss."""
    rec = synthetic(6, extras=True)
    rec.pwm_neutral_us = (1511.0, 1511.0)
    write_recording(rec, tmp_path / "r.mcap")
    data = (tmp_path / "r.mcap").read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[: len(data) // 2])
    back = read_recording(tmp_path / "cut.mcap")
    assert any("truncated" in n and "the rest is lost" in n for n in back.notes), back.notes
    assert tuple(back.pwm_neutral_us) == (1511.0, 1511.0)
    for name in ("gnss", "heading", "pwm", "imu"):
        whole, part = getattr(rec, name), getattr(back, name)
        assert 0.2 * len(whole) < len(part) < 0.6 * len(whole), name
        np.testing.assert_allclose(part.t + back.origin_s, whole.t[: len(part)] + rec.origin_s, atol=1e-9)
    # a copy says what it lost, as info does
    done = twin("convert", tmp_path / "cut.mcap", tmp_path / "cut.csv")
    assert done.returncode == 0 and "note: not in the copy: MCAP file truncated or damaged" in done.stderr
    # bytes flipped inside its compressed chunks: the decompressor's own error is the file's damage, said so
    # (where a flip lands depends on the compressor's output, which its versions change: a chunk that
    # still decompresses may hold a message no longer JSON, said as such, or none)
    flipped = bytearray(data)
    for k in range(200, len(data) - 200, max(1, (len(data) - 400) // 50)):
        flipped[k] ^= 0xFF
    (tmp_path / "flip.mcap").write_bytes(bytes(flipped))
    done = twin("info", tmp_path / "flip.mcap")
    assert done.returncode == 0 and not done.stderr, done.stderr
    assert "MCAP file truncated or damaged" in done.stdout and "the rest is lost" in done.stdout
    np.testing.assert_array_equal(back.pwm["left_us"], rec.pwm["left_us"][: len(back.pwm)])


@pytest.mark.parametrize("ext", [".tlog", ".bin"])
def test_a_run_written_as_telemetry_has_samples_over_its_own_span_and_none_in_its_gaps(tmp_path, ext):
    """A run that starts at 5 s, or two joined with a 4-s gap, is logged where it has states: no
    fixes or PWM before its start (a still boat under thrust), none drawn across the gap."""
    from twin.formats import write_run
    from twin.run import Run

    def run(t):
        n = len(t)
        return Run(t, np.column_stack([t - t[0], np.zeros(n), np.zeros(n)]),
                   np.column_stack([np.ones(n), np.zeros(n), np.zeros(n)]), np.full((n, 2), 1600.0), np.zeros((n, 2)))

    late = run(np.arange(50, 151) * 0.1)
    write_run(late, tmp_path / f"late{ext}")
    got = read_recording(tmp_path / f"late{ext}")
    for stream in (got.gnss, got.heading, got.pwm):
        assert stream.t[-1] - stream.t[0] == pytest.approx(10.0, abs=0.02)
    joined = run(np.r_[np.arange(0, 51), np.arange(90, 141)] * 0.1)  # 0-5 s, then 9-14 s
    write_run(joined, tmp_path / f"joined{ext}")
    got = read_recording(tmp_path / f"joined{ext}")
    for stream in (got.gnss, got.heading, got.pwm):
        t = stream.t - stream.t[0]
        assert not np.any((t > 5.0 + 1e-6) & (t < 9.0 - 1e-6)) and t[-1] == pytest.approx(14.0, abs=0.02)


@pytest.mark.parametrize("ext", [".tlog", ".bin", ".mcap", ".csv"])
def test_a_gyro_with_gaps_and_the_wind_on_board_come_back_as_written(tmp_path, ext):
    """A gyro covering 10-20 s of a 30-s heading comes back over 10-20 s (a .tlog carries it at the
    heading's times: none drawn where it had none), and the relative wind beside the true one."""
    th, ti, tw = np.arange(0, 1500) * 0.02, np.arange(500, 1000) * 0.02, np.arange(0, 300) * 0.1
    rec = Recording(source="g", kind="synthetic", heading=Stream(th, {"psi_rad": 0.1 * th}),
                    imu=Stream(ti, {"yaw_rate_rads": np.full(len(ti), 0.1)}),
                    wind=Stream(tw, {"speed_m_s": np.full(300, 3.0), "from_deg": np.full(300, 90.0),
                                     "relative_speed_m_s": np.full(300, 4.0), "relative_from_deg": np.full(300, 20.0)}))
    write_recording(rec, tmp_path / f"g{ext}")
    back = read_recording(tmp_path / f"g{ext}")
    assert len(back.imu) == 500 and back.imu.t[0] == pytest.approx(10.0) and back.imu.t[-1] == pytest.approx(19.98)
    assert not any(reason.startswith("imu") for reason, _ in back.dropped)
    np.testing.assert_allclose(back.wind["relative_speed_m_s"], 4.0)
    np.testing.assert_allclose(back.wind["relative_from_deg"], 20.0)


@pytest.mark.parametrize("ext", [".tlog", ".bin"])
def test_a_log_without_roll_and_pitch_is_not_written_as_a_level_one(rec, tmp_path, ext):
    """ATTITUDE and ATT carry roll and pitch beside the heading: a recording without them comes back
    without them, not level throughout; one with them keeps them."""
    write_recording(rec, tmp_path / f"a{ext}")
    back = read_recording(tmp_path / f"a{ext}")
    assert len(back.heading) == len(rec.heading) and not len(back.attitude)
    th = rec.heading.t
    tilted = Recording(source="b", kind="synthetic", heading=rec.heading,
                       attitude=Stream(th, {"roll_rad": np.full(len(th), 0.2), "pitch_rad": np.full(len(th), -0.1)}))
    write_recording(tilted, tmp_path / f"b{ext}")
    back = read_recording(tmp_path / f"b{ext}")
    np.testing.assert_allclose(back.attitude["roll_rad"], 0.2, atol=1e-4)
    np.testing.assert_allclose(back.attitude["pitch_rad"], -0.1, atol=1e-4)


def test_a_tlog_refuses_a_gyro_without_a_heading_to_carry_it(tmp_path):
    t = np.arange(0, 100) * 0.1
    rec = Recording(source="y", kind="synthetic", imu=Stream(t, {"yaw_rate_rads": np.full(100, 0.1)}),
                    gnss=Stream(t, {"lat_deg": np.full(100, 37.0), "lon_deg": -5.0 + 1e-6 * t}))
    with pytest.raises(TwinError, match="has a gyro but no heading"):
        write_recording(rec, tmp_path / "y.tlog")
    assert not (tmp_path / "y.tlog").exists()


def test_a_bin_keeps_a_recordings_calendar_day_and_a_simulated_run_claims_none(tmp_path):
    """The GPS clock a .bin is written with: the recording's own calendar origin (a converted log keeps
    its day, which `twin fleet` groups by), and for a simulated run no calendar day at all."""
    from twin.formats import write_run
    from twin.run import Run

    t = np.arange(0, 101) * 0.1
    dated = Recording(source="d", kind="synthetic", origin_s=1.75e9,
                      gnss=Stream(t, {"lat_deg": np.full(101, 59.0), "lon_deg": 10.0 + 1e-6 * t}),
                      heading=Stream(t, {"psi_rad": np.zeros(101)}))
    write_recording(dated, tmp_path / "d.bin")
    assert read_recording(tmp_path / "d.bin").origin_s == pytest.approx(1.75e9, abs=0.01)
    n = len(t)
    run = Run(t, np.column_stack([t, 0 * t, 0 * t]), np.column_stack([np.ones(n), 0 * t, 0 * t]),
              np.full((n, 2), 1600.0), np.zeros((n, 2)))
    write_run(run, tmp_path / "run.bin")
    assert read_recording(tmp_path / "run.bin").origin_s < 946684800.0  # before 2000: no calendar day


def test_mcap_message_that_is_not_json_is_left_out_and_said(tmp_path, monkeypatch):
    """A message whose bytes no longer parse (a flipped byte in an uncompressed chunk) is left out, the
    rest read, and the loss named: a damaged message must not end the reading or pass silently."""
    import functools

    from mcap.writer import CompressionType

    import twin.formats.mcap as mcap_format

    rec = synthetic(6, extras=True)
    monkeypatch.setattr(mcap_format, "Writer", functools.partial(mcap_format.Writer, compression=CompressionType.NONE))
    write_recording(rec, tmp_path / "r.mcap")
    data = bytearray((tmp_path / "r.mcap").read_bytes())
    at = data.index(b'{"psi_rad"', len(data) // 2)  # a heading message in the file's second half
    data[at] = ord("X")
    (tmp_path / "bad.mcap").write_bytes(bytes(data))
    back = read_recording(tmp_path / "bad.mcap")
    assert any("1 messages whose bytes are not JSON left out" in n for n in back.notes), back.notes
    total = sum(len(getattr(rec, s)) for s in ("gnss", "heading", "pwm", "imu"))
    assert sum(len(getattr(back, s)) for s in ("gnss", "heading", "pwm", "imu")) == total - 1


def test_a_two_pole_low_pass_delays_a_boats_turns_by_its_group_delay():
    """ArduPilot's gyro low-pass (a two-pole Butterworth at INS_GYRO_FILTER, sampled at 1 kHz here)
    lays a boat's turning (0.2 and 0.5 Hz) √2/(2π·f_c) late, what the readers take back (±2 ms)."""
    from scipy.signal import butter, lfilter

    from twin.formats.ardupilot import gyro_filter_delay_s

    fs = 1000.0
    t = np.arange(0.0, 60.0, 1 / fs)
    rate = 0.3 * np.sin(2 * np.pi * 0.2 * t) + 0.1 * np.sin(2 * np.pi * 0.5 * t + 1.0)
    for cutoff_hz in (4.0, 10.0, 20.0):
        filtered = lfilter(*butter(2, cutoff_hz, fs=fs), rate)
        shifts = np.arange(0.0, 0.12, 0.001)
        keep = t > 5.0
        cost = [np.mean((filtered[keep] - np.interp(t[keep] - s, t, rate)) ** 2) for s in shifts]
        assert shifts[int(np.argmin(cost))] == pytest.approx(gyro_filter_delay_s({"INS_GYRO_FILTER": cutoff_hz}),
                                                             abs=0.002), cutoff_hz
    assert gyro_filter_delay_s({"INS_GYRO_FILTER": 4.0}) == pytest.approx(0.0563, abs=1e-4)
    assert gyro_filter_delay_s({"INS_GYRO_FILTER": 0.0}) == gyro_filter_delay_s({}) == 0.0


def test_a_harmonic_notch_delays_a_boats_turning_by_what_its_shape_gives():
    """ArduPilot's notch biquads (NotchFilter: b0 = 1 + αA², a0 = 1 + α, α = sin Ω/2Q) at 1 kHz, at two
    harmonics of 80 Hz, delay a boat's turning by what notch_delay_s gives from the logged shape (within
    a tenth: the digital filter's delay is a little under the analog one's); a shape not stated: None."""
    from scipy.signal import lfilter

    from twin.formats.ardupilot import notch_delay_s, read_gyro_on_time

    shape = {"INS_HNTCH_FREQ": 80.0, "INS_HNTCH_BW": 40.0, "INS_HNTCH_ATT": 40.0, "INS_HNTCH_HMNCS": 3}
    fs = 1000.0
    t = np.arange(0.0, 20.0, 1 / fs)
    rate = 0.3 * np.sin(2 * np.pi * 0.2 * t)
    octaves = 2 * np.log2(80.0 / 60.0)
    q, a_sq = np.sqrt(2 ** octaves) / (2 ** octaves - 1), 10 ** (-40.0 / 20)
    out = rate
    for centre in (80.0, 160.0):
        omega = 2 * np.pi * centre / fs
        alpha = np.sin(omega) / (2 * q)
        out = lfilter([1 + alpha * a_sq, -2 * np.cos(omega), 1 - alpha * a_sq], [1 + alpha, -2 * np.cos(omega), 1 - alpha],
                      out)
    keep = t > 2.0
    shifts = np.arange(0.0, 0.004, 0.00005)
    cost = [np.mean((out[keep] - np.interp(t[keep] - s, t, rate)) ** 2) for s in shifts]
    delay = notch_delay_s(shape)
    assert 1.5e-3 < delay < 2.0e-3 and shifts[int(np.argmin(cost))] == pytest.approx(delay, rel=0.1)
    assert notch_delay_s({**shape, "INS_HNTCH_HMNCS": 1}) == pytest.approx(delay * 2 / 3)
    assert notch_delay_s({k: v for k, v in shape.items() if k != "INS_HNTCH_BW"}) is None
    assert notch_delay_s({**shape, "INS_HNTCH_BW": 200.0}) is None  # no notch has a bandwidth over twice its centre
    assert notch_delay_s({**shape, "INS_HNTCH_HMNCS": 256}) == pytest.approx(delay * 2 / 3 / 9)  # the 9th harmonic
    rec = Recording(source="g", kind="dataflash", imu=Stream(t[:100].copy(), {"yaw_rate_rads": rate[:100]}),
                    parameters={"INS_GYRO_FILTER": 4.0, "INS_HNTCH_ENABLE": 1.0, **shape})
    read_gyro_on_time(rec)  # the notch is said with its size, the low-pass alone read back
    assert "by 1.7 ms at its 80-Hz base" in rec.notes[-1] and rec.imu.t[0] == pytest.approx(-0.0563, abs=1e-4)
    second = {k.replace("HNTCH", "HNT2"): v for k, v in shape.items()}  # a second notch adds its own
    rec = Recording(source="g", kind="dataflash", imu=Stream(t[:100].copy(), {"yaw_rate_rads": rate[:100]}),
                    parameters={"INS_GYRO_FILTER": 4.0, "INS_HNTCH_ENABLE": 1.0, "INS_HNT2_ENABLE": 1.0, **shape,
                                **second})
    read_gyro_on_time(rec)
    assert "(INS_HNTCH_ENABLE 1 and INS_HNT2_ENABLE 1) delays it further, by 3.4 ms at its 80, 80-Hz bases" \
        in rec.notes[-1]


@pytest.mark.parametrize("ext", [".bin", ".tlog"])
def test_an_ardupilot_gyro_is_read_when_it_turned_and_written_back_as_logged(tmp_path, ext):
    """A log whose parameters state INS_GYRO_FILTER 4 holds its gyro 0.056 s after the turn: the
    reader reads it that much earlier and says so; written back to the format, the delay is put
    back, so the conversion reads again the same; a log with the filter off is read as stamped."""
    from pymavlink import DFReader

    th = np.arange(0, 3000) * 0.02
    rate = 0.3 * np.sin(2 * np.pi * 0.05 * th)
    delay = np.sqrt(2) / (2 * np.pi * 4.0)
    for cutoff_hz, late in ((4.0, delay), (0.0, 0.0)):
        rec = Recording(source="g", kind="synthetic", heading=Stream(th, {"psi_rad": wrapped(np.cumsum(rate) * 0.02)}),
                        imu=Stream(th.copy(), {"yaw_rate_rads": rate}), parameters={"INS_GYRO_FILTER": cutoff_hz})
        out = tmp_path / f"g{cutoff_hz:g}{ext}"
        write_recording(rec, out)
        if ext == ".bin":  # the file holds the gyro where ArduPilot stamps it
            log = DFReader.DFReader_binary(str(out), zero_time_base=False)
            stamps = []
            while (m := log.recv_match(type=["IMU"])) is not None:
                stamps.append(m.TimeUS * 1e-6)
            np.testing.assert_allclose(stamps, th + late, atol=1.5e-6)
        back = read_recording(out)
        said = [n for n in back.notes if n.startswith("gyro: logged after")]
        assert len(said) == (1 if late else 0) and (not late or "read 0.056 s earlier" in said[0])
        inside = (back.imu.t > 1.0) & (back.imu.t < th[-1] - 1.0)
        np.testing.assert_allclose(back.imu["yaw_rate_rads"][inside],
                                   np.interp(back.imu.t[inside], th, rate), atol=2e-4 if ext == ".tlog" else 1e-6)
        if ext == ".bin":
            np.testing.assert_allclose(back.imu.t, th, atol=1.5e-6)


GPS_CASES = [
    ({"SIM_GPS1_LAG_MS": 100.0, "GPS_DELAY_MS": 0.0, "GPS_TYPE": 1.0}, 0.100, "as the log's SIM_GPS1_LAG_MS says"),
    ({"SIM_GPS1_LAG_MS": 0.0, "GPS_TYPE": 1.0}, 0.0, None),  # a simulation stating no lag: on time, nothing to say
    ({"GPS1_DELAY_MS": 120.0, "GPS1_TYPE": 2.0}, 0.120, "as the log's GPS1_DELAY_MS says"),
    ({"GPS_DELAY_MS": 0.0, "GPS_TYPE": 1.0}, 0.0, "(GPS_DELAY_MS 0 leaves it to the receiver's driver; ArduPilot's for "
                                                  "a u-blox 7 or later is 0.12 s)"),
    ({"GPS1_TYPE": 14.0}, 0.0, "(no GPS delay set leaves it to the receiver's driver)"),  # a MAVLink GPS: no u-blox
    ({"GPS_DELAY_MS": 5000.0, "GPS_TYPE": 1.0}, 0.0, "GPS_DELAY_MS 5000 ms is outside what ArduPilot takes"),
    ({}, 0.0, None),
]


@pytest.mark.parametrize("ext", [".bin", ".tlog"])
@pytest.mark.parametrize("params, delay_s, said", GPS_CASES)
def test_an_ardupilot_gps_fix_is_read_when_the_log_says_it_was_taken(tmp_path, ext, params, delay_s, said):
    """A GPS fix is stamped when the autopilot received it: where the log states the receiver's
    delay (SITL's lag, or the delay the autopilot compensates for, within ArduPilot's range) the fix
    is read that much earlier and the note says which parameter; an autopilot's log that states none
    says so (naming ArduPilot's u-blox figure only for a u-blox), one out of range is warned of and
    read as stamped; a recording with no autopilot parameters (a simulated run) is read as
    stamped, in silence. Written back, the file holds the stamps ArduPilot gave."""
    from pymavlink import DFReader

    rec = synthetic(5)
    rec.parameters = dict(params)
    out = tmp_path / f"fixes{ext}"
    write_recording(rec, out)
    if ext == ".bin":
        log = DFReader.DFReader_binary(str(out), zero_time_base=False)
        stamps = []
        while (m := log.recv_match(type=["GPS"])) is not None:
            stamps.append(m.TimeUS * 1e-6)
    else:
        stamps = [m.time_usec * 1e-6 for _, m in iter_tlog(out.read_bytes(), ("GPS_RAW_INT",), Counter())]
    np.testing.assert_allclose(stamps, rec.gnss.t + delay_s, atol=1.5e-6)
    back = read_recording(out)
    np.testing.assert_allclose(back.gnss.t - back.heading.t[0], rec.gnss.t - rec.heading.t[0], atol=1.5e-6)
    said_of_gnss = [n for n in back.notes + back.warnings if n.startswith("gnss:")]
    assert (said_of_gnss == []) if said is None else (len(said_of_gnss) == 1 and said in said_of_gnss[0]), said_of_gnss
    assert ("outside" in (said or "")) == any(w.startswith("gnss:") for w in back.warnings)


def test_a_gyro_filter_no_ardupilot_runs_is_warned_of_and_the_gyro_read_as_stamped(tmp_path):
    """INS_GYRO_FILTER NaN, negative or under 1 Hz (a 0.001-Hz one would move the gyro 225 s) is no
    filter's: warned of, the gyro read as stamped; 0 (the filter off) is read as stamped in silence."""
    th = np.arange(0, 1500) * 0.02
    for cutoff, warned in ((float("nan"), True), (-4.0, True), (0.001, True), (0.0, False)):
        rec = Recording(source="g", kind="synthetic", heading=Stream(th, {"psi_rad": 0.1 * th}),
                        imu=Stream(th.copy(), {"yaw_rate_rads": np.full(len(th), 0.1)}),
                        parameters={"INS_GYRO_FILTER": cutoff})
        write_recording(rec, tmp_path / "g.bin")
        back = read_recording(tmp_path / "g.bin")
        np.testing.assert_allclose(back.imu.t, th, atol=1.5e-6)
        assert any(w.startswith(f"gyro: INS_GYRO_FILTER {cutoff:g} is no low-pass") for w in back.warnings) == warned
        assert not any(n.startswith("gyro:") for n in back.notes)
        (tmp_path / "g.bin").unlink()
