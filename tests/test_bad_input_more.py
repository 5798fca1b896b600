"""More bad input, each ending in one `error: ...` line and exit code 2 before any work (or read in full,
with what was left out counted): a DataFlash log with a message of an undefined type, a CSV with a stray
quote or a field over the csv module's 128 kB, `--smoother model` and `--sim` without the inputs they
need, a vessel file nested too deeply, stdout closed or full, and headings, propeller speeds and rudder
angles in another unit than the layout's."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from twin_command import twin

from twin.errors import TwinError
from twin.formats import read_recording
from twin.recording import format_summary

SHARED = Path(__file__).resolve().parent.parent.parent / "shared"
DATA = SHARED / "data"
ESSO_HEADER = ("t [s],x_position_mid [m],u_velo [m/s],y_position_mid [m],vm_velo [m/s],psi_hat [rad],"
               "r_angvelo [rad/s],n_prop [rps],delta_rudder [rad]")


def shared(*parts: str) -> Path:
    path = DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"{path} is not present")
    return path


def one_error(done, code: int = 2) -> str:
    """The single stderr line of a command that failed with `code`."""
    lines = done.stderr.strip().splitlines()
    assert done.returncode == code and len(lines) == 1 and lines[0].startswith("error: "), (done.returncode,
                                                                                          done.stderr)
    assert "Traceback" not in done.stderr
    return lines[0]


def simulated(tmp_path: Path, name: str, *args: str) -> Path:
    out = tmp_path / name
    done = twin("simulate", *args, "--out", out)
    assert done.returncode == 0, done.stderr
    return out


def esso_csv(path: Path, *, psi_scale: float = 1.0, n_scale: float = 1.0, delta_scale: float = 1.0,
             n: int = 1500) -> Path:
    """An Esso Osaka layout log of a steady turn at 0.5 m/s, 0.06 rad/s, 10 rps, rudder 0.3 rad (10 Hz),
    its heading wrapped to ±π, with the heading, propeller and rudder columns scaled (a unit slip)."""
    t = np.arange(n) * 0.1
    psi = 0.06 * t
    x = np.cumsum(0.05 * np.cos(psi))
    y = np.cumsum(0.05 * np.sin(psi))
    wrapped = np.angle(np.exp(1j * psi))
    rows = [ESSO_HEADER]
    rows += [f"{t[k]:.1f},{x[k]:.5f},0.5,{y[k]:.5f},0,{wrapped[k] * psi_scale:.6f},0.06,{10.0 * n_scale:g},"
             f"{0.3 * delta_scale:.6f}" for k in range(n)]
    path.write_text("\n".join(rows) + "\n")
    return path


# ------------------------------------------------------------------ 1. a DataFlash message of an undefined type


def _damaged(data: bytes, near: int) -> tuple[bytes, int]:
    """`data` with the type byte of the first message header at or after `near` set to an undefined type."""
    damaged = bytearray(data)
    at = damaged.find(b"\xa3\x95", near)
    assert at > 0
    damaged[at + 2] = 0xEE
    return bytes(damaged), at


def test_dataflash_message_of_an_undefined_type_is_skipped_not_the_rest(tmp_path):
    log = simulated(tmp_path, "x.bin", "--vessel", "blueboat", "--duration", "60")
    whole = read_recording(log)
    data, _ = _damaged(log.read_bytes(), len(log.read_bytes()) // 10)
    bad = tmp_path / "bad.bin"
    bad.write_bytes(data)
    rec = read_recording(bad)
    assert rec.duration_s() == pytest.approx(whole.duration_s(), abs=0.1)  # was cut to a tenth
    assert sum(len(s) for s in rec.streams().values()) == sum(len(s) for s in whole.streams().values()) - 1
    skipped = dict(rec.dropped)
    reason = next(r for r in skipped if r.startswith("dataflash: messages of a type no FMT defines"))
    assert skipped[reason] == 1
    done = twin("info", bad)
    assert done.returncode == 0 and f"dropped: {reason}: 1" in done.stdout


def test_shared_dataflash_log_with_a_flipped_type_byte_is_read_in_full(tmp_path):
    original = shared("ardupilot", "ardusub_small.BIN")
    data, _ = _damaged(original.read_bytes(), 50_000)
    bad = tmp_path / "sub.BIN"
    bad.write_bytes(data)
    rec = read_recording(bad)
    assert rec.duration_s() == pytest.approx(read_recording(original).duration_s(), abs=0.2)  # 23.7 s, not 4.7
    assert any(r.startswith("dataflash: messages of a type no FMT defines") for r, _ in rec.dropped)
    assert not any("no FMT defines" in r for r, _ in read_recording(original).dropped)


# ------------------------------------------------------------------ 2-3. a stray quote, a field over 128 kB


def generic_lines(n: int = 300) -> list[str]:
    t = np.arange(n) * 0.1
    return ["t,north,east,psi,r"] + [f"{x:.1f},{0.5 * x:.3f},0,0,0" for x in t]


def test_csv_stray_quote_costs_its_row_only(tmp_path):
    lines = generic_lines()
    lines[50] = lines[50].replace(",0,0,0", ',"0,0,0')  # a quote that never closes
    path = tmp_path / "q.csv"
    path.write_text("\n".join(lines) + "\n")
    rec = read_recording(path)
    assert len(rec.gnss) == 299  # every row after it was swallowed into one field
    reasons = dict(rec.dropped)
    assert reasons["csv: rows with a stray quote character (one that does not close a field on its line), left out"] == 1
    assert "csv: rows with the wrong number of fields" not in reasons
    assert "stray quote" in format_summary(rec.summary())


def test_csv_quoted_cells_still_read(tmp_path):
    lines = generic_lines()
    lines[0] = '"t","north","east","psi","r"'
    lines[10] = '"0.9","0.450",0,0,0'
    path = tmp_path / "quoted.csv"
    path.write_text("\n".join(lines) + "\n")
    rec = read_recording(path)
    assert len(rec.gnss) == 300 and not rec.dropped


@pytest.mark.parametrize("line", ['"' + "x" * 200_000 + '",0,0,0,0', "7.0,0,0,0," + "y" * 200_000 + '"'])
def test_csv_field_over_128_kb_is_a_counted_row_not_exit_3(tmp_path, line):
    lines = generic_lines()
    lines[40] = line
    path = tmp_path / "big.csv"
    path.write_text("\n".join(lines) + "\n")
    done = twin("info", path)
    assert done.returncode == 0, done.stderr
    assert "dropped: csv: rows with" in done.stdout and "field limit" not in done.stderr
    converted = twin("convert", path, tmp_path / "big.mcap")
    assert converted.returncode == 0, converted.stderr


def test_inputs_and_manifest_with_a_field_over_128_kb_are_one_line(tmp_path):
    inputs = tmp_path / "inputs.csv"
    inputs.write_text("t,pwm_left,pwm_right\n0,1500,1500\n1,\"" + "1" * 200_000 + "\",1500\n")
    line = one_error(twin("simulate", "--vessel", "blueboat", "--inputs", inputs, "--out", tmp_path / "o.csv"))
    assert "inputs.csv" in line and "not readable as CSV" in line
    manifest = tmp_path / "m.csv"
    manifest.write_text("recording,vessel\n\"" + "x" * 200_000 + "\",blueboat\n")
    line = one_error(twin("fleet", "--manifest", manifest, "--out", tmp_path / "fleet"))
    assert "m.csv" in line and "cannot read" in line


# ------------------------------------------------------------------ 4. --smoother model and --sim without inputs


def test_model_smoother_on_a_vessel_without_a_pwm_model_is_refused(tmp_path):
    log = esso_csv(tmp_path / "esso.csv", n=300)
    line = one_error(twin("view", log, "--vessel", "esso_osaka", "--smoother", "model", "--out", tmp_path / "v.rrd"))
    assert "--smoother model" in line and "esso_osaka" in line and "--smoother savgol" in line
    run = simulated(tmp_path, "cs.csv", "--vessel", "cybership1", "--duration", "20")
    line = one_error(twin("view", run, "--vessel", "cybership1", "--smoother", "model", "--out", tmp_path / "c.rrd"))
    assert "--smoother model" in line and "cybership1" in line
    assert not (tmp_path / "v.rrd").exists() and not (tmp_path / "c.rrd").exists()
    garbage = tmp_path / "garbage.csv"  # refused before any log is read: the vessel alone decides
    garbage.write_bytes(bytes(range(256)) * 4)
    line = one_error(twin("view", garbage, "--vessel", "esso_osaka", "--smoother", "model", "--out", tmp_path / "g.rrd"))
    assert "--smoother model" in line and "esso_osaka" in line


def test_model_smoother_on_a_log_without_pwm_is_refused(tmp_path):
    run = simulated(tmp_path, "cs.csv", "--vessel", "cybership1", "--duration", "20")
    line = one_error(twin("view", run, "--vessel", "blueboat", "--smoother", "model", "--out", tmp_path / "v.rrd"))
    assert line.startswith("error: cs.csv: the model-based smoother") and "holds none" in line


def test_view_sim_of_a_run_without_inputs_does_not_say_it_holds_pwm(tmp_path):
    run = simulated(tmp_path, "cs.csv", "--vessel", "cybership1", "--duration", "20")
    line = one_error(twin("view", "--sim", "--vessel", "cybership1", run, "--out", tmp_path / "v.rrd"))
    assert "holds PWM" not in line and "no thrust to replay" in line


# ------------------------------------------------------------------ 5. a vessel file nested too deeply


@pytest.mark.parametrize("command", [("params",), ("simulate", "--out", "d.csv"), ("validate",)])
def test_deeply_nested_vessel_file_is_one_line(tmp_path, command):
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    line = one_error(twin(*command, "--model", deep, cwd=tmp_path))
    assert line.startswith("error: deep.json: not a vessel file") and "nested too deeply" in line


# ------------------------------------------------------------------ 6. stdout closed or full


def _run_twin_process(args, cwd: Path, **kwargs) -> subprocess.CompletedProcess:
    """`python -m twin ARGS` in a new process, the package taken from this checkout."""
    repo = str(Path(__file__).resolve().parent.parent)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([repo, *filter(None, [os.environ.get("PYTHONPATH")])])}
    return subprocess.run([sys.executable, "-m", "twin", *map(str, args)], cwd=cwd, stderr=subprocess.PIPE,
                          text=True, timeout=120, env=env, **kwargs)


def test_stdout_closed_is_one_line_and_exit_2(tmp_path):
    run = simulated(tmp_path, "s.csv", "--vessel", "blueboat", "--duration", "10")
    done = _run_twin_process(["info", run], tmp_path, stdin=subprocess.DEVNULL, preexec_fn=lambda: os.close(1))
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.strip().splitlines() == [
        "error: standard output is closed: the command prints there (redirect it, e.g. to /dev/null, instead of "
        "closing it)"]


def test_stdout_full_names_what_failed(tmp_path):
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full")
    run = simulated(tmp_path, "s.csv", "--vessel", "blueboat", "--duration", "10")
    with open("/dev/full", "w") as full:
        done = _run_twin_process(["info", run], tmp_path, stdout=full)
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.strip().splitlines() == ["error: cannot write to standard output: No space left on device"]


# ------------------------------------------------------------------ 7. heading units


def _with_column(path: Path, out: Path, column: str, convert) -> Path:
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    i = header.index(column)
    rows = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        if cells[i].strip():
            cells[i] = repr(float(convert(float(cells[i]))))
        rows.append(",".join(cells))
    out.write_text("\n".join(rows) + "\n")
    return out


def test_generic_psi_in_degrees_is_refused(tmp_path):
    run = simulated(tmp_path, "run.csv", "--vessel", "blueboat", "--duration", "60", "--scenario", "turn")
    assert read_recording(run).misread == []
    degrees = _with_column(run, tmp_path / "deg.csv", "psi", np.degrees)
    rec = read_recording(degrees)
    assert len(rec.misread) == 1 and rec.misread[0].startswith("psi ") and "looks like degrees" in rec.misread[0]
    line = one_error(twin("evaluate", degrees, "--vessel", "blueboat"))
    assert line == f"error: deg.csv: {rec.misread[0]}"
    info = twin("info", degrees)
    assert info.returncode == 0 and "looks like degrees" in info.stdout


@pytest.mark.parametrize("rate, said", [(0.12, "psi steps by about 360 where it wraps"),
                                         (0.04, "the course over ground lies")])
def test_generic_psi_in_degrees_without_a_gyro_is_refused(tmp_path, rate, said):
    t = np.arange(600) * 0.1
    turn = rate * t  # a slow turn at 1 m/s, in degrees wrapped to ±180 (through ±180 at the faster rate)
    psi = np.degrees(np.angle(np.exp(1j * turn)))
    north, east = np.sin(turn) / rate, (1 - np.cos(turn)) / rate
    rows = ["t,north,east,psi"] + [f"{t[k]:.1f},{north[k]:.4f},{east[k]:.4f},{psi[k]:.4f}" for k in range(len(t))]
    path = tmp_path / "slow.csv"
    path.write_text("\n".join(rows) + "\n")
    (reason,) = read_recording(path).misread
    assert reason.startswith(said) and "looks like degrees" in reason
    radians = tmp_path / "radians.csv"
    radians.write_text("\n".join(rows[:1] + [",".join([*r.split(",")[:3], f"{np.radians(p):.6f}"])
                                             for r, p in zip(rows[1:], psi)]) + "\n")
    assert read_recording(radians).misread == []


def test_esso_heading_in_degrees_is_refused(tmp_path):
    assert esso_csv(tmp_path / "ok.csv").exists() and read_recording(tmp_path / "ok.csv").misread == []
    rec = read_recording(esso_csv(tmp_path / "deg.csv", psi_scale=np.degrees(1.0)))
    assert rec.misread and rec.misread[0].startswith("psi_hat [rad]") and "looks like degrees" in rec.misread[0]


def test_shared_esso_heading_in_degrees_is_refused_even_without_a_wrap(tmp_path):
    # this test never turns through ±180°: the gyro tells
    original = shared("esso", "random_06-Aug-2020_16_24_25_6.csv")
    rec = read_recording(_with_column(original, tmp_path / "deg.csv", "psi_hat [rad]", np.degrees))
    assert rec.misread and "psi_hat [rad]" in rec.misread[0] and "degrees" in rec.misread[0]


@pytest.mark.parametrize("name", [f"fixed_00000{n}.csv" for n in (216, 218, 220, 221, 222, 223, 224, 225, 226, 228)])
def test_shared_blueboat_yaw_in_radians_is_refused(tmp_path, name):
    # four of the ten never wrap nor turn their track far: the file's own yaw_rate estimate tells the unit
    original = shared("blueboat", name)
    rec = read_recording(_with_column(original, tmp_path / name, "yaw", np.radians))
    assert len(rec.misread) == 1 and "yaw" in rec.misread[0] and "looks like radians" in rec.misread[0]


def test_every_shared_log_reads_in_its_units():
    logs = sorted(p for p in DATA.glob("*/*") if p.suffix.lower() in (".csv", ".bin", ".tlog")) if DATA.is_dir() else []
    if not logs:
        pytest.skip(f"{DATA} is not present")
    misread = {p.name: read_recording(p).misread for p in logs}
    assert {name: m for name, m in misread.items() if m} == {}


@pytest.mark.parametrize("vessel, scenario, suffix", [("blueboat", "spin", ".csv"), ("blueboat", "zigzag", ".bin"),
                                                      ("yellowfish", "random", ".csv"), ("cybership1", "turn", ".csv"),
                                                      ("esso_osaka", "turn", ".csv"), ("yellowfish", "spin", ".mcap")])
def test_simulated_logs_read_in_their_units(tmp_path, vessel, scenario, suffix):
    run = simulated(tmp_path, f"run{suffix}", "--vessel", vessel, "--scenario", scenario, "--duration", "120")
    assert read_recording(run).misread == []


# ------------------------------------------------------------------ 8. Esso propeller in rpm, rudder in degrees


@pytest.mark.parametrize("rps", [8.0, 10.0])  # 480 rpm: within the ±500 rps no sensor passes; 600 rpm beyond it
def test_esso_propeller_speed_in_rpm_is_refused(tmp_path, rps):
    log = esso_csv(tmp_path / "rpm.csv", n_scale=6.0 * rps, n=300)
    for command in (("info", log), ("evaluate", log, "--vessel", "esso_osaka"),
                    ("view", log, "--sim", "--vessel", "esso_osaka", "--out", tmp_path / "v.rrd")):
        line = one_error(twin(*command))
        assert line.startswith(f"error: {log}: n_prop [rps] reaches {60 * rps:g}") and "looks like rpm" in line
    assert not (tmp_path / "v.rrd").exists()


def test_esso_rudder_in_degrees_is_refused(tmp_path):
    log = esso_csv(tmp_path / "rdeg.csv", delta_scale=np.degrees(1.0), n=300)
    for command in (("info", log), ("evaluate", log, "--vessel", "esso_osaka")):
        line = one_error(twin(*command))
        assert line.startswith(f"error: {log}: delta_rudder [rad] lies beyond ±90°") and "looks like degrees" in line


def test_esso_inputs_in_their_units_are_read():
    for name in ("turn_14-Oct-2020_15_06_53.csv", "random_03-Aug-2020_11_04_37.csv"):  # rudder to 0.70 rad, 10 rps
        rec = read_recording(shared("esso", name))
        assert len(rec.prop_rudder) and rec.misread == []


def test_manoeuvre_draws_past_hours_of_trials_are_refused_before_any_run(tmp_path):
    line = one_error(twin("manoeuvres", "--vessel", "blueboat", "--draws", "100000000"))
    assert "--draws is at most 100000" in line


def test_sitl_write_params_refuses_a_sessions_options_it_would_drop(tmp_path):
    for extra in (["--port", "99999"], ["--esc-arm", "-1"], ["--heading", "nan"], ["--record", str(tmp_path / "r.csv")]):
        line = one_error(twin("sitl", "--vessel", "blueboat", "--write-params", tmp_path / "b.parm", *extra))
        assert "--write-params writes ArduPilot's parameter file and exits" in line and extra[0] in line
    assert not (tmp_path / "b.parm").exists() and not (tmp_path / "r.csv").exists()
    done = twin("sitl", "--vessel", "blueboat", "--write-params", tmp_path / "b.parm", "--channels", "1,3")
    assert done.returncode == 0 and (tmp_path / "b.parm").is_file()


def test_an_inputs_file_or_a_manifest_with_a_stray_quote_is_named_with_its_line(tmp_path):
    inputs = tmp_path / "inputs.csv"
    inputs.write_text("t,pwm_left,pwm_right\n0,1500,1500\n1,\"1600,1600\n2,1600,1600\n3,1500,1500\n")
    line = one_error(twin("simulate", "--vessel", "blueboat", "--inputs", inputs, "--duration", "3",
                          "--out", tmp_path / "r.csv"))
    assert "inputs.csv: line 3 holds a quote character" in line
    manifest = tmp_path / "fleet.csv"
    manifest.write_text("recording,vessel\n\"a.csv,blueboat\nb.csv," + "x" * 200_000 + "\n")
    line = one_error(twin("fleet", "--manifest", manifest, "--out", tmp_path / "out"))
    assert "fleet.csv" in line


def test_a_pipe_given_as_a_recording_is_named_as_one(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no named pipes on this system")
    pipe = tmp_path / "log.csv"
    os.mkfifo(pipe)
    with pytest.raises(TwinError, match="not a regular file"):
        read_recording(pipe)


def test_generic_heading_in_radians_told_by_its_yaw_rate_column(tmp_path):
    # a slow sway of the heading (±0.5 rad), no wrap, the track nearly straight: only the yaw rate tells
    t = np.arange(0.0, 120.0, 0.1)
    psi = 0.5 * np.sin(2 * np.pi * t / 30.0)
    rate = np.gradient(psi, t)
    north, east = 0.5 * t, 0.02 * np.sin(t)
    def write(path, heading):
        rows = ["t,north,east,heading_deg,yaw_rate"] + [f"{a:.1f},{n:.4f},{e:.4f},{h:.6f},{r:.6f}" for a, n, e, h, r
                                                          in zip(t, north, east, heading, rate)]
        path.write_text("\n".join(rows) + "\n")
        return read_recording(path).misread
    assert write(tmp_path / "deg.csv", np.degrees(psi)) == []
    (reason,) = write(tmp_path / "rad.csv", psi)
    assert "the yaw rate column yaw_rate turns 57 times as fast" in reason and "looks like radians" in reason
