"""twin/scale on Ray (the optional `cluster` extra), a local instance of two CPUs: the same
results as on this machine's batch engine, and a worker that dies costs only its batch, which
Ray runs again."""
import json
import logging
import os
from types import SimpleNamespace

import numpy as np
import pytest

import twin.vessel as vessel_mod
from scale_fixtures import identified
from twin.errors import TwinError
from twin.scale import batches, datasets, fleet, montecarlo as mc
from twin.scale.draws import Variation, parse_effect_range, parse_factor

ray = pytest.importorskip("ray")
if not hasattr(ray, "init"):  # a folder named ray where the tests run (Ray's own /tmp/ray), not Ray
    pytest.skip("'ray' is a folder here, not the Ray package", allow_module_level=True)


@pytest.fixture(scope="module")
def cluster():
    # Ray starts its workers at niceness 15: beside the suite's other worker they would wait most of
    # the time for a core, which measures the scheduler and not the twin
    before = os.environ.get("RAY_worker_niceness")
    os.environ["RAY_worker_niceness"] = "0"
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, logging_level=logging.WARNING)
    yield batches.RayExecutor("auto", max_retries=2)
    ray.shutdown()
    if before is None:
        os.environ.pop("RAY_worker_niceness")
    else:
        os.environ["RAY_worker_niceness"] = before


@pytest.fixture(scope="module")
def job():
    v = identified()
    return v, mc.scenario_mission(v, "turn", 10.0, 0.5)


@pytest.fixture(scope="module")
def local(job):
    v, mission = job
    return mc.run(v, mission, 64, seed=11, batch_size=16)


def _same(a: mc.MonteCarlo, b: mc.MonteCarlo) -> bool:
    return (all(np.array_equal(a.band.values[q], b.band.values[q]) for q in mc.QUANTITIES)
            and np.array_equal(a.sample_tracks, b.sample_tracks) and np.array_equal(a.coordinates, b.coordinates))


def test_montecarlo_on_ray_is_the_local_one_bit_for_bit(cluster, job, local):
    v, mission = job
    remote = mc.run(v, mission, 64, seed=11, batch_size=16, executor=cluster)
    assert remote.executor == "ray" and _same(local, remote)
    assert np.ptp(local.sample_tracks[:, -1, 0]) > 0.05  # draws that differ, so equality says something


def test_a_killed_worker_loses_only_its_batch_which_is_retried(cluster, job, local, tmp_path, monkeypatch):
    v, mission = job
    original = mc.run_batch
    marker = tmp_path / "killed"

    def dies_once(job, b, extra=None):  # pickled by value: the worker runs this very closure
        if b.index == 2 and not marker.exists():
            marker.write_text(str(os.getpid()))
            os._exit(1)  # the worker process dies mid-task, as on a lost node
        return original(job, b, extra)

    monkeypatch.setattr(mc, "run_batch", dies_once)
    remote = mc.run(v, mission, 64, seed=11, batch_size=16, executor=cluster)
    assert marker.exists() and int(marker.read_text()) != os.getpid()
    assert _same(local, remote)
    marker.unlink()
    with pytest.raises(TwinError, match="batch 2 .* lost on the cluster after 0 retries"):
        mc.run(v, mission, 64, seed=11, batch_size=16, executor=batches.RayExecutor("auto", max_retries=0))


def test_an_error_in_a_task_is_one_line_and_not_retried(cluster, job, monkeypatch, tmp_path):
    v, mission = job
    calls = tmp_path / "calls"

    def bad(job, b, extra=None):
        with open(calls, "a") as fh:
            fh.write("x")
        raise TwinError("the twin diverged at t = 3.00 s")

    monkeypatch.setattr(mc, "run_batch", bad)
    with pytest.raises(TwinError, match=r"^the twin diverged at t = 3.00 s$"):
        mc.run(v, mission, 16, seed=0, batch_size=16, executor=cluster)
    assert calls.read_text() == "x"


def test_dataset_shards_on_ray_are_the_local_files(cluster, tmp_path):
    v = vessel_mod.load("yellowfish")
    settings = datasets.Settings(3, per_shard=2, segments=1, manoeuvres=("rc",), seed=5, variation=Variation(
        factors=(parse_factor("Nr=0.5..2", v),), effects=(parse_effect_range("current=0..0.2,0..360"),)))
    here = datasets.generate_shards(v, settings, tmp_path / "local")
    there = datasets.generate_shards(v, settings, tmp_path / "ray", executor=cluster)
    assert here.index == there.index and len(here.entries) == 3
    for e in here.entries:
        assert (tmp_path / "local" / e["file"]).read_bytes() == (tmp_path / "ray" / e["file"]).read_bytes()
    for shard in ("shard-00000", "shard-00001"):
        assert (json.loads((tmp_path / "local" / shard / "truth.json").read_text())
                == json.loads((tmp_path / "ray" / shard / "truth.json").read_text()))


def test_fleet_on_ray_sends_the_logs_and_gets_the_reports(cluster, tmp_path):
    from twin.formats import write_recording
    from twin.synth.dataset import PROFILES, generate

    v = vessel_mod.load("yellowfish")
    logs = []
    for i in range(3):
        rec = generate(v, n_segments=1, manoeuvres=["rc"], seed=i, noise=PROFILES["none"],
                       segment_s=(20.0 + 10 * i, 20.0 + 10 * i)).recording
        write_recording(rec, tmp_path / f"run{i}.mcap")
        logs.append(fleet.Log(tmp_path / f"run{i}.mcap", "yellowfish", "2026-06-0" + str(1 + i % 2)))

    def seconds_as_current(recordings, vessel, **options):  # by value, like any task code
        speed = round(recordings[0].duration_s() / 100.0, 6)
        effects = [{"name": "current", "parameters": {"speed_m_s": speed}}]
        return SimpleNamespace(effects=effects, to_dict=lambda: {"effects": effects, "pid": os.getpid()})

    here = fleet.diagnose_fleet(logs, tmp_path / "local", diagnose=seconds_as_current)
    there = fleet.diagnose_fleet(logs, tmp_path / "ray", diagnose=seconds_as_current, executor=cluster)
    assert here.summary["table"][0]["effects"] == ["current"]
    speeds = here.summary["effects"]["current"]["parameters"]["speed_m_s"]
    assert (speeds["min"], speeds["max"]) == pytest.approx((0.2, 0.4), abs=0.01)
    assert {k: v for k, v in there.summary.items() if k != "table"} == \
        {k: v for k, v in here.summary.items() if k != "table"}
    pids = {json.loads((tmp_path / "ray" / f"run{i}.json").read_text())["report"]["pid"] for i in range(3)}
    assert os.getpid() not in pids  # diagnosed in the workers
