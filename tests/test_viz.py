"""MCAP and rerun exports: round trip, file layout, atomic writes."""
import json
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from twin.errors import TwinError
from twin.run import Run
from twin.formats import mcap as mcap_io
from twin.formats.mcap import read_run_mcap, write_run_mcap
from twin.viz import rerun_log
from twin.viz.rerun_log import write_runs_rrd

ASSETS = Path(__file__).resolve().parent.parent / "twin" / "assets"
RRD_MAGIC = b"RRF2"  # what rerun 0.41 writes first in every .rrd


def synthetic_run(seed: int = 0, n: int = 1200, dt: float = 0.1, pwm: bool = True) -> Run:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    eta = np.column_stack([np.cumsum(rng.normal(0, 0.1, n)), np.cumsum(rng.normal(0, 0.1, n)),
                           np.unwrap(rng.uniform(-np.pi, np.pi, n))])
    nu = rng.normal(0, [0.5, 0.1, 0.2], (n, 3))
    pwm_us = rng.uniform(1100, 1900, (n, 2)) if pwm else np.full((n, 2), np.nan)
    thrust = rng.normal(0, 10, (n, 2))
    return Run(t, eta, nu, pwm_us, thrust,
               meta={"vessel": "yellowfish", "engine": "mujoco", "timestep_s": 0.002, "steps": 5,
                     "inputs": object()})


def listing(d: Path) -> list[str]:
    return sorted(p.name for p in d.iterdir())


def test_mcap_round_trip(tmp_path):
    run = synthetic_run(1)
    run.pwm_us[::7, 0] = np.nan  # NaN must come back as NaN
    out = tmp_path / "run.mcap"
    write_run_mcap(run, out, vessel_name="yellowfish")
    assert listing(tmp_path) == ["run.mcap"]
    back = read_run_mcap(out)
    for attr in ("t", "eta", "nu", "pwm_us", "thrust_n"):
        np.testing.assert_allclose(getattr(back, attr), getattr(run, attr), rtol=0, atol=1e-9, equal_nan=True)
    assert back.meta == {"vessel": "yellowfish", "engine": "mujoco", "timestep_s": 0.002, "steps": 5}


def test_mcap_thrust_driven_run(tmp_path):
    run = synthetic_run(2, n=50, pwm=False)
    write_run_mcap(run, tmp_path / "r.mcap")
    back = read_run_mcap(tmp_path / "r.mcap")
    assert np.all(np.isnan(back.pwm_us))
    np.testing.assert_allclose(back.thrust_n, run.thrust_n, atol=1e-9)


def test_mcap_topics_schemas_and_metadata(tmp_path):
    run = synthetic_run(3, n=100)
    out = tmp_path / "run.mcap"
    write_run_mcap(run, out, vessel_name="yellowfish")
    with open(out, "rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        schemas = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
        assert {t: s.name for t, s in schemas.items()} == {
            "/vessel/pose": "foxglove.PoseInFrame",
            "/vessel/state": "twin.VesselState",
            "/vessel/inputs": "twin.ThrusterInputs",
            "/vessel/fix": "foxglove.LocationFix",
        }
        assert all(s.encoding == "jsonschema" for s in schemas.values())
        assert {c.message_encoding for c in summary.channels.values()} == {"json"}
        assert all(n == 100 for n in summary.statistics.channel_message_counts.values())
        poses = [(m.log_time, json.loads(m.data)) for _, _, m in reader.iter_messages(topics=["/vessel/pose"])]
        meta = {r.name: r.metadata for r in reader.iter_metadata()}
    i = 37
    log_time, pose = poses[i]
    assert log_time == round(run.t[i] * 1e9)
    assert pose["frame_id"] == "ned"
    assert pose["timestamp"]["sec"] * 10**9 + pose["timestamp"]["nsec"] == log_time
    q = pose["pose"]["orientation"]
    # the quaternion is a yaw ψ about z: recover ψ modulo 2π
    psi = 2 * np.arctan2(q["z"], q["w"])
    assert np.isclose(np.angle(np.exp(1j * (psi - run.eta[i, 2]))), 0, atol=1e-12)
    assert (q["x"], q["y"]) == (0.0, 0.0)
    assert meta["twin"]["vessel"] == "yellowfish"
    assert json.loads(meta["twin"]["meta"])["steps"] == 5


def test_read_mcap_rejects_garbage(tmp_path):
    bad = tmp_path / "garbage.mcap"
    bad.write_bytes(np.random.default_rng(0).bytes(4096))
    with pytest.raises(TwinError, match="not a readable MCAP"):
        read_run_mcap(bad)
    with pytest.raises(TwinError):
        read_run_mcap(tmp_path / "missing.mcap")


def test_read_mcap_truncated_file_gives_its_complete_part(tmp_path):
    """A file cut short (full disk, killed writer) keeps its metadata and all but its last chunk."""
    run = synthetic_run(4, n=1200)
    good = tmp_path / "good.mcap"
    write_run_mcap(run, good, vessel_name="yellowfish")
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    notes = []
    back = read_run_mcap(cut, notes)
    assert 0.3 * len(run.t) < len(back.t) < 0.55 * len(run.t)
    np.testing.assert_array_equal(back.eta, run.eta[: len(back.t)])
    np.testing.assert_array_equal(back.pwm_us, run.pwm_us[: len(back.t)])
    assert back.meta["vessel"] == "yellowfish"  # the metadata comes first
    assert len(notes) == 1 and "truncated" in notes[0] and "the rest is lost" in notes[0]
    with pytest.raises(TwinError, match="not a readable MCAP"):  # nothing complete left
        (tmp_path / "stub.mcap").write_bytes(good.read_bytes()[:12])
        read_run_mcap(tmp_path / "stub.mcap")


def test_read_mcap_without_state_topic(tmp_path):
    from mcap.writer import Writer

    other = tmp_path / "other.mcap"
    with open(other, "wb") as fh:
        w = Writer(fh)
        w.start()
        sid = w.register_schema("x", "jsonschema", b"{}")
        ch = w.register_channel("/something", "json", sid)
        w.add_message(ch, log_time=0, data=b"{}", publish_time=0)
        w.finish()
    with pytest.raises(TwinError, match="/vessel/state"):
        read_run_mcap(other)


def test_mcap_bad_run_leaves_nothing(tmp_path):
    run = synthetic_run(5, n=20)
    run.nu = run.nu[:-1]
    with pytest.raises(TwinError, match="nu"):
        write_run_mcap(run, tmp_path / "r.mcap")
    assert listing(tmp_path) == []


def test_mcap_failure_mid_write_removes_temp_and_keeps_old(tmp_path, monkeypatch):
    out = tmp_path / "r.mcap"
    out.write_bytes(b"old")

    def boom(*args):
        raise RuntimeError("disk gone")

    monkeypatch.setattr(mcap_io, "_write", boom)
    with pytest.raises(RuntimeError):
        write_run_mcap(synthetic_run(6, n=20), out)
    assert listing(tmp_path) == ["r.mcap"]
    assert out.read_bytes() == b"old"


def test_rrd_two_runs(tmp_path):
    out = tmp_path / "runs.rrd"
    runs = {"engine": synthetic_run(7), "analytic": synthetic_run(8, pwm=False)}
    start = time.perf_counter()
    write_runs_rrd(runs, out)
    assert time.perf_counter() - start < 2.0
    assert listing(tmp_path) == ["runs.rrd"]
    data = out.read_bytes()
    assert len(data) > 1000 and data.startswith(RRD_MAGIC)


def test_rrd_draws_nothing_across_a_gap(tmp_path, monkeypatch):
    """Two stretches 30 s apart (an outing's two logs, a recording's segments): the track is two
    strips and every plot is cleared once inside the gap, which rerun draws as a hole; a run
    without a gap is one strip and clears nothing."""
    strips, clears = [], []
    real_strips, real_clear = rerun_log.rr.LineStrips3D, rerun_log.rr.Clear

    def spy_strips(lines, **kwargs):
        strips.append(len(lines))
        return real_strips(lines, **kwargs)

    def spy_clear(**kwargs):
        clears.append(kwargs)
        return real_clear(**kwargs)

    monkeypatch.setattr(rerun_log.rr, "LineStrips3D", spy_strips)
    monkeypatch.setattr(rerun_log.rr, "Clear", spy_clear)
    run = synthetic_run(3, n=600)
    run.t = np.where(np.arange(600) < 300, run.t, run.t + 30.0)
    assert list(rerun_log.gap_ends(run.t)) == [299]
    write_runs_rrd({"outing": run}, tmp_path / "gap.rrd")
    assert strips == [2] and len(clears) == 7  # u, v, r, two thrusts, two PWMs
    strips.clear(), clears.clear()
    write_runs_rrd({"one": synthetic_run(3, n=600)}, tmp_path / "one.rrd")
    assert strips == [1] and clears == []


def test_rrd_with_meshes_and_geometry(tmp_path):
    class Geometry:  # only the sites are used
        thruster_pos_m = np.array([[-0.5, -0.3, 0.0], [-0.5, 0.3, 0.0]])
        gnss_pos_m = np.array([0.0, 0.0, -0.5])
        imu_pos_m = np.array([0.1, 0.0, -0.3])

    meshes = [ASSETS / "yellowfish_hull_port.stl", ASSETS / "yellowfish_hull_starboard.stl"]
    out = tmp_path / "sub" / "real_twin.rrd"
    out.parent.mkdir()
    write_runs_rrd({"real": synthetic_run(9, n=300), "twin": synthetic_run(10, n=300)}, out,
                   geometry=Geometry(), hull_mesh_paths=meshes, application_id="twin_test")
    assert out.read_bytes().startswith(RRD_MAGIC)
    assert listing(out.parent) == ["real_twin.rrd"]


def test_rrd_bad_run_leaves_nothing(tmp_path):
    bad = synthetic_run(11, n=30)
    bad.thrust_n = bad.thrust_n[:10]
    with pytest.raises(TwinError, match="thrust_n"):
        write_runs_rrd({"engine": synthetic_run(12, n=30), "bad": bad}, tmp_path / "x.rrd")
    assert listing(tmp_path) == []


def test_rrd_failure_mid_write_removes_temp(tmp_path, monkeypatch):
    def boom(*args):
        raise RuntimeError("logging failed")

    monkeypatch.setattr(rerun_log, "_log_run", boom)
    with pytest.raises(RuntimeError):
        write_runs_rrd({"engine": synthetic_run(13, n=30)}, tmp_path / "x.rrd")
    assert listing(tmp_path) == []


def test_rrd_bad_mesh_is_twin_error(tmp_path):
    with pytest.raises(TwinError, match="hull mesh"):
        write_runs_rrd({"engine": synthetic_run(14, n=10)}, tmp_path / "x.rrd",
                       hull_mesh_paths=[tmp_path / "nope.stl"])
    assert listing(tmp_path) == []


def test_rrd_on_a_full_disk_keeps_the_older_file(tmp_path, full_disk):
    """rerun's file sink writes on its own thread and says nothing of a failed write: the recording is
    made in memory and written as every output is, so a full disk is an error naming the file and the
    good recording already there stays whole."""
    out = tmp_path / "runs.rrd"
    write_runs_rrd({"engine": synthetic_run(15, n=50)}, out)
    good = out.read_bytes()

    full_disk(1 / 3)
    with pytest.raises(TwinError, match=f"cannot write '{out}': No space left on device"):
        write_runs_rrd({"engine": synthetic_run(16, n=50)}, out)
    assert out.read_bytes() == good and listing(tmp_path) == ["runs.rrd"]
