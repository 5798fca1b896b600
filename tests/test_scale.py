"""twin/scale on this machine: seeded batches, the Monte Carlo band and its coverage, sharded
datasets, fleet diagnoses, and their commands (the Ray executor: test_scale_ray.py)."""
import json
import logging
import re
import sys
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

import twin.vessel as vessel_mod
from scale_fixtures import identified
from twin.errors import TwinError
from twin.scale import batches, datasets, fleet, montecarlo as mc
from twin.scale.draws import Variation, parse_effect_range, parse_factor, with_mass_scale
import twin_command


def twin(*args, timeout=300):
    return twin_command.twin(*args)


@pytest.fixture(scope="module")
def vessel():
    return identified()


@pytest.fixture(scope="module")
def mission(vessel):
    return mc.scenario_mission(vessel, "turn", 20.0, 0.5)


# ---------------------------------------------------------------- batches

def test_a_batch_draws_from_its_own_child_seed_whoever_runs_it():
    plan = batches.plan(10, 4, seed=7)
    assert [(b.start, b.stop) for b in plan] == [(0, 4), (4, 8), (8, 10)]
    children = np.random.SeedSequence(7).spawn(3)
    for b, child in zip(plan, children):
        assert np.array_equal(b.rng().standard_normal(5), np.random.default_rng(child).standard_normal(5))
    assert not np.array_equal(plan[0].rng().standard_normal(5), plan[1].rng().standard_normal(5))
    with pytest.raises(TwinError, match="batch size"):
        batches.plan(10, 0, 0)


def test_chunked_rollout_is_the_one_long_rollout_bit_for_bit(vessel, mission, monkeypatch):
    drawn, _ = Variation(covariance=True).draw(vessel, 6, np.random.default_rng(3))
    vessels = [d.truth() for d in drawn]
    whole, _ = mc.simulate_tracks(vessels, mission)
    monkeypatch.setattr(mc, "CHUNK_BYTES", 1)  # one sample period per rollout call
    chunked, _ = mc.simulate_tracks(vessels, mission)
    assert np.array_equal(whole, chunked)
    assert np.ptp(whole[:, -1, 0]) > 0.1  # the draws differ: their tracks spread


def test_the_mission_replays_the_closed_loop_run_open_loop(vessel):
    from twin.drive import get
    from twin.engine.mjcf import compile_vessel
    from twin.engine.sim import simulate

    m = mc.scenario_mission(vessel, "zigzag", 30.0, 0.5)
    run = simulate(compile_vessel(vessel), get("zigzag"), 30.0, sample_dt_s=0.5)
    tracks, diverged = mc.simulate_tracks([vessel], m)
    assert not diverged and "closed loop" in m.source
    assert np.max(np.abs(tracks[0, :, :3] - run.eta)) < 1e-9 and np.max(np.abs(tracks[0, :, 3:] - run.nu)) < 1e-9


# ---------------------------------------------------------------- Monte Carlo

@pytest.fixture(scope="module")
def band_run(vessel, mission):
    return mc.run(vessel, mission, 300, seed=1, batch_size=64)


def test_a_truth_drawn_from_the_same_covariance_is_inside_the_band_as_often_as_it_should(vessel, mission,
                                                                                          band_run):
    truths, _ = Variation(covariance=True).draw(vessel, 200, np.random.default_rng(12345))
    tracks, diverged = mc.simulate_tracks([d.truth() for d in truths], mission)
    assert not diverged
    at_90 = mc.coverage(band_run.band, tracks, 0.9)
    at_50 = mc.coverage(band_run.band, tracks, 0.5)
    # 200 truths and a band of 300 draws: a few per cent of sampling error either way; a band of
    # 1.5 times the spread would hold 98 %, one of two thirds 73 %
    for q in mc.QUANTITIES:
        assert 0.84 <= at_90[q] <= 0.96, (q, at_90[q])
        assert 0.38 <= at_50[q] <= 0.62, (q, at_50[q])
    assert np.mean(list(at_90.values())) == pytest.approx(0.9, abs=0.03)
    assert np.mean(list(at_50.values())) == pytest.approx(0.5, abs=0.06)
    # the band is not trivially wide: the nominal twin stays inside it, a 30 % faster twin does not
    slow = replace(vessel, thrusters=replace(vessel.thrusters, gain_left=1.3, gain_right=1.3))
    off, _ = mc.simulate_tracks([slow], mission)
    assert mc.coverage(band_run.band, off)["u"] < 0.2


def test_the_band_is_the_same_numbers_on_any_number_of_threads(vessel, mission):
    one = mc.run(vessel, mission, 40, seed=5, batch_size=16, executor=batches.LocalExecutor(nthread=1))
    two = mc.run(vessel, mission, 40, seed=5, batch_size=16, executor=batches.LocalExecutor(nthread=2))
    assert all(np.array_equal(one.band.values[q], two.band.values[q]) for q in mc.QUANTITIES)
    assert np.array_equal(one.coordinates, two.coordinates) and one.coordinates.shape == (40, 5)
    # the drawn coordinates follow the block: mean and spread of ln|Xu|
    xu = vessel.uncertainty["mean"][0]
    assert abs(np.mean(one.coordinates[:, 0]) - xu) < 0.15 and 0.1 < np.std(one.coordinates[:, 0]) < 0.3


def test_a_twin_with_its_form_error_widens_the_band_in_quadrature_and_keeps_the_median(vessel, mission):
    # a form-error block by hand: |error| of u 0.1 m/s at every level and horizon, of the position 0.5 m per
    # 10 s of horizon (north, east, deviation) at every level; psi, v and r absent (their bands stay as drawn)
    horizons = [0.0, 10.0, 20.0, 30.0]
    levels = [0.5, 0.68, 0.8, 0.9, 0.95, 0.99]
    grow = [[0.05 * h] * len(levels) for h in horizons]
    block = {"horizon_s": horizons, "levels": levels, "windows": 1000,
             "quantiles": {"u": [[0.1] * len(levels)] * len(horizons), "north": grow, "east": grow, "deviation": grow}}
    widened_vessel = replace(vessel, uncertainty={**vessel.uncertainty, "form_error": block})
    drawn = mc.run(vessel, mission, 40, seed=5, batch_size=20)
    widened = mc.run(widened_vessel, mission, 40, seed=5, batch_size=20)
    alone = mc.run(widened_vessel, mission, 40, seed=5, batch_size=20, form_error=False)
    assert drawn.band.parameters_only is None and alone.band.parameters_only is None
    assert all(np.array_equal(alone.band.values[q], drawn.band.values[q]) for q in mc.QUANTITIES)
    b, d = widened.band, drawn.band
    assert all(np.array_equal(b.parameters_only[q], d.values[q]) for q in mc.QUANTITIES)
    i5, i50, i95 = (b.percentiles.index(p) for p in (5.0, 50.0, 95.0))
    assert np.array_equal(b.values["u"][i50], d.values["u"][i50])  # the median stays the draws'
    hi, nom = d.values["u"][i95], d.nominal["u"]
    assert b.values["u"][i95] == pytest.approx(nom + np.sqrt(np.clip(hi - nom, 0, None) ** 2 + 0.1 ** 2))
    assert np.all(b.values["u"][i5] < d.values["u"][i5]) and b.values["u"][i5][0] == pytest.approx(nom[0] - 0.1)
    for q in ("psi", "v", "r"):
        assert np.array_equal(b.values[q], d.values[q])
    # the distance off the nominal track at 20 s: 1 m of form error in quadrature; along and cross take it too
    i90, k = b.percentiles.index(90.0), int(np.argmin(np.abs(b.t_s - 20.0)))
    assert b.values["deviation"][i90, k] == pytest.approx(np.hypot(d.values["deviation"][i90, k], 1.0))
    assert b.values["cross"][i95, k] - b.nominal["cross"][k] >= 1.0
    d_json = widened.to_dict()
    assert d_json["widened_by_form_error"] and d_json["final_parameters_only"]["u"]["p95"] == pytest.approx(hi[-1])


def test_band_outputs_and_their_columns(band_run, tmp_path):
    from twin.scale import views

    text = band_run.to_csv_text()
    head = text.splitlines()[0].split(",")
    assert head[:3] == ["t_s", "north_m_nominal", "north_m_p05"] and "deviation_m_p90" in head
    rows = np.array([[float(x) for x in line.split(",")] for line in text.splitlines()[1:]])
    assert rows.shape == (41, len(head)) and rows[-1, 0] == pytest.approx(20.0)
    d = band_run.to_dict()
    assert d["draws"] == 300 and d["percentiles"] == [5.0, 25.0, 50.0, 75.0, 90.0, 95.0]
    assert d["final"]["deviation"]["p90"] > 0.5 and d["coordinates"]["names"][0] == "Xu"
    json.dumps(d, default=lambda x: x.tolist())
    views.write_rrd(band_run, tmp_path / "band.rrd")
    views.write_png(band_run, tmp_path / "band.png")
    assert (tmp_path / "band.rrd").stat().st_size > 10_000 and (tmp_path / "band.png").read_bytes()[:4] == b"\x89PNG"


def test_effect_ranges_and_factors_are_drawn_within_their_ranges(vessel):
    r = parse_effect_range("current=0..0.3,90")
    drawn = [r.draw(np.random.default_rng(i)).params for i in range(20)]
    assert all(0 <= p["speed_m_s"] <= 0.3 and p["dir_deg"] == 90 for p in drawn)
    assert np.ptp([p["speed_m_s"] for p in drawn]) > 0.1
    with pytest.raises(TwinError, match="dir_deg"):
        parse_effect_range("current=0..0.3,0..400")
    with pytest.raises(TwinError, match="LO ≤ HI"):
        parse_factor("Xu=2..1", vessel)
    # a mass its hulls cannot carry fully submerged (the Yellowfish's displace 5.7 times its mass)
    with pytest.raises(TwinError, match=r"--vary mass: at ×8 .* it would sink"):
        parse_factor("mass=1..8", vessel)
    v = Variation(factors=(parse_factor("mass=1.2..1.2", vessel), parse_factor("Xu=0.5..0.5", vessel)))
    (d,), _ = v.draw(vessel, 1, np.random.default_rng(0))
    assert d.vessel.damping.Xu == pytest.approx(0.5 * vessel.damping.Xu)
    from twin.engine.mjcf import compile_vessel

    heavy = compile_vessel(d.vessel).geometry.rigid.mass_kg
    assert heavy == pytest.approx(1.2 * compile_vessel(vessel).geometry.rigid.mass_kg)
    assert with_mass_scale(vessel, 1.1).case != with_mass_scale(vessel, 1.2).case


def test_band_against_a_recording(vessel, tmp_path):
    from twin.synth.dataset import PROFILES, generate

    nominal = generate(vessel, n_segments=2, manoeuvres=["rc"], seed=2, noise=PROFILES["none"],
                       segment_s=(70.0, 70.0)).recording
    faster = generate(vessel, effects=["thrust_gain=1.5"], n_segments=2, manoeuvres=["rc"], seed=2,
                      noise=PROFILES["none"], segment_s=(70.0, 70.0)).recording
    options = {"draws": 48, "seed": 0, "window_s": 20.0, "batch_size": 16, "calibrated": False}
    inside = mc.recording_coverage(vessel, [nominal], **options)
    outside = mc.recording_coverage(vessel, [faster], **options)
    assert inside.windows >= 6 and inside.draws == 48 and len(inside.horizon_s) == 20
    assert inside.inside["u"] > 0.9 and inside.inside["r"] > 0.8 and inside.inside["deviation"] > 0.9
    assert outside.inside["u"] < 0.3 and outside.inside["deviation"] < 0.5
    assert "share of the recording inside" in inside.text() and set(inside.to_dict()["inside"]) >= {"u", "v", "r"}
    # draws left out of the band are said beside it, as `twin montecarlo` says them
    lossy = replace(inside, draws=46, diverged=2, rejected=5).text().splitlines()[0]
    assert lossy.startswith("band of 46 draws (2 more diverged on the recording and are left out) (5 redrawn as ")
    assert "diverged" not in inside.text().splitlines()[0] or inside.diverged


# ---------------------------------------------------------------- datasets

def _settings(**kw):
    v = vessel_mod.load("yellowfish")
    variation = Variation(factors=(parse_factor("mass=0.9..1.2", v), parse_factor("Xu=0.5..2", v)),
                          effects=(parse_effect_range("current=0..0.3,0..360"),), effect_share=0.5)
    return v, datasets.Settings(**{"vessels": 5, "per_shard": 2, "segments": 1, "manoeuvres": ("rc",), "seed": 3,
                                   "variation": variation, **kw})


def test_shards_with_one_truth_index_and_resume(tmp_path):
    v, settings = _settings()
    first = datasets.generate_shards(v, settings, tmp_path / "a")
    index = json.loads((tmp_path / "a" / "index.json").read_text())
    assert index["shards"] == 3 and [e["vessel_index"] for e in index["entries"]] == [0, 1, 2, 3, 4]
    assert first.made == 3 and first.reused == 0
    for e in index["entries"]:
        truth = json.loads((tmp_path / "a" / f"shard-{e['shard']:05d}" / "truth.json").read_text())
        mine = next(t for t in truth["truths"] if t["vessel_index"] == e["vessel_index"])
        assert (tmp_path / "a" / e["file"]).stat().st_size > 1000
        assert e["labels"]["Xu"] == pytest.approx(v.damping.Xu * e["factors"]["Xu"])
        assert mine["vessel"]["damping"]["Xu"] == pytest.approx(e["labels"]["Xu"])
        assert e["mass_kg"] == pytest.approx(24.39 * e["factors"]["mass"])
        assert [x["text"] for x in mine["effects"]] == e["effects"]
    assert 0 < sum(bool(e["effects"]) for e in index["entries"]) < 5  # share 0.5: some have the current
    csv_head = (tmp_path / "a" / "index.csv").read_text().splitlines()[0].split(",")
    assert {"file", "factor_mass", "label_Xu", "effects"} <= set(csv_head)
    # cut short: the middle shard's truth is gone, so resuming makes that shard alone, the same bytes
    shard = tmp_path / "a" / "shard-00001"
    before = (shard / "vessel-000002.mcap").read_bytes()
    (shard / "truth.json").unlink()
    again = datasets.generate_shards(v, settings, tmp_path / "a", resume=True)
    assert (again.made, again.reused) == (1, 2) and (shard / "vessel-000002.mcap").read_bytes() == before
    assert json.loads((tmp_path / "a" / "index.json").read_text()) == index
    # a recording cut short by hand since: its shard is made again, not kept as complete
    (shard / "vessel-000002.mcap").write_bytes(before[:1000])
    third = datasets.generate_shards(v, settings, tmp_path / "a", resume=True)
    assert (third.made, third.reused) == (1, 2) and (shard / "vessel-000002.mcap").read_bytes() == before
    with pytest.raises(TwinError, match="not empty"):
        datasets.generate_shards(v, settings, tmp_path / "a")
    with pytest.raises(TwinError, match="other settings"):
        datasets.generate_shards(v, replace(settings, seed=4), tmp_path / "a", resume=True)


# ---------------------------------------------------------------- fleet

def fake_diagnose(recordings, vessel, **options):
    """A stand-in diagnosis: a current whose speed is the log's duration / 1000 on 'boat' logs."""
    rec = recordings[0]
    if rec.duration_s() < 10:
        raise TwinError(f"{rec.source}: too short")
    effects = [{"name": "current", "parameters": {"speed_m_s": rec.duration_s() / 1000.0}, "held_out_gain": 0.5}]
    effects = effects if vessel.name == "yellowfish" else []
    answer = {} if effects else {"form": ["r 12× the noise off, following the PWM difference"]}
    return SimpleNamespace(effects=effects, to_dict=lambda: {"vessel": vessel.name, "effects": effects,
                                                           "options": options, "answer": answer})


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    from twin.formats import write_recording
    from twin.synth.dataset import PROFILES, generate

    d = tmp_path_factory.mktemp("fleet")
    v = vessel_mod.load("yellowfish")
    for i, seconds in enumerate((40.0, 60.0, 5.0)):
        ds = generate(v, n_segments=1, manoeuvres=["rc"], seed=i, noise=PROFILES["none"],
                      segment_s=(seconds, seconds))
        write_recording(ds.recording, d / f"log{i}.mcap")
    (d / "manifest.csv").write_text("recording,vessel,day\nlog0.mcap,yellowfish,2026-05-01\n"
                                    "log1.mcap,blueboat,2026-05-02\nlog2.mcap,,2026-05-02\n")
    return d


def test_fleet_reports_and_summary_per_vessel_and_day(logs, tmp_path):
    entries = fleet.read_manifest(logs / "manifest.csv", default_vessel="yellowfish")
    assert [e.vessel for e in entries] == ["yellowfish", "blueboat", "yellowfish"]
    done = fleet.diagnose_fleet(entries, tmp_path / "out", window_s=5.0, diagnose=fake_diagnose)
    s = done.summary
    assert (s["logs"], s["diagnosed"]) == (3, 2) and "too short" in s["failed"][0]["error"]
    assert s["effects"]["current"]["logs"] == 1 and s["effects"]["current"]["share"] == 0.5
    assert s["effects"]["current"]["parameters"]["speed_m_s"]["median"] == pytest.approx(0.04, abs=0.002)
    assert s["per_vessel"]["blueboat"]["effects"] == {} and s["per_vessel"]["yellowfish"]["logs"] == 2
    assert s["per_day"]["2026-05-02"] == {"logs": 2, "diagnosed": 1, "effects": {}, "day_from": {"manifest": 2}}
    report = json.loads((tmp_path / "out" / "log0.json").read_text())
    assert report["ok"] and report["day"] == "2026-05-01" and report["report"]["options"] == {"window_s": 5.0}
    md = (tmp_path / "out" / "fleet.md").read_text()
    assert "| current | 1 | 50 % |" in md
    # a log where nothing was named but the twin's form is off says so; logs without an anemometer are
    # not told to use one
    assert "- log1.mcap: twin's form: r 12× the noise off, following the PWM difference" in md
    assert "wind" not in md and s["with_measured_wind"] == 0
    with pytest.raises(TwinError, match="not YYYY-MM-DD"):
        (logs / "bad.csv").write_text("recording,day\nlog0.mcap,May 1\n")
        fleet.read_manifest(logs / "bad.csv", "yellowfish")



def test_a_log_failing_on_a_rerun_keeps_its_earlier_report(logs, tmp_path):
    entries = fleet.read_manifest(logs / "manifest.csv", default_vessel="yellowfish")
    fleet.diagnose_fleet(entries, tmp_path / "out", diagnose=fake_diagnose)
    good = (tmp_path / "out" / "log0.json").read_bytes()

    def fails_on_log0(recordings, vessel, **options):
        if "log0" in str(recordings[0].source):
            raise TwinError("log0: no PWM")
        return fake_diagnose(recordings, vessel, **options)
    again = fleet.diagnose_fleet(entries, tmp_path / "out", diagnose=fails_on_log0)
    assert (tmp_path / "out" / "log0.json").read_bytes() == good  # the earlier diagnosis stays
    assert "no PWM" in json.loads((tmp_path / "out" / "log0.failed.json").read_text())["error"]
    assert again.summary["diagnosed"] == 1 and not (tmp_path / "out" / "log2.failed.json").exists()


def test_a_fleet_report_never_lands_on_a_vessel_file_it_reads(logs, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    model = vessel_mod.save(vessel_mod.load("yellowfish"), out / "log0.json")  # named like log0's report
    kept = model.read_bytes()
    entries = [fleet.Log(logs / "log0.mcap", str(model), ""), fleet.Log(logs / "log1.mcap", "yellowfish", "")]
    with pytest.raises(TwinError, match="report 'log0.json' would replace the input"):
        fleet.diagnose_fleet(entries, out, diagnose=fake_diagnose)
    assert model.read_bytes() == kept and sorted(p.name for p in out.iterdir()) == ["log0.json"]

def test_a_fleet_report_never_replaces_a_users_file_of_its_name_and_replaces_a_previous_fleets(logs, tmp_path):
    """A JSON or HTML a user keeps in --out under a log's report name (notes beside a log) is refused
    before any work; a previous fleet's reports are replaced and other files are not counted as reports."""
    out = tmp_path / "out"
    out.mkdir()
    notes = out / "log0.json"
    notes.write_text('{"operator": "anna", "weather": "calm"}\n')
    (out / "other.json").write_text("not json")
    entries = [fleet.Log(logs / "log0.mcap", "yellowfish", ""), fleet.Log(logs / "log1.mcap", "yellowfish", "")]
    with pytest.raises(TwinError, match="'log0.json' is there and is not a report of `twin fleet`"):
        fleet.diagnose_fleet(entries, out, diagnose=fake_diagnose)
    assert notes.read_text() == '{"operator": "anna", "weather": "calm"}\n'
    assert sorted(p.name for p in out.iterdir()) == ["log0.json", "other.json"]
    (out / "log1.html").write_text("<html>my page</html>")
    notes.unlink()
    with pytest.raises(TwinError, match="'log1.html' is there and is not a report"):
        fleet.diagnose_fleet(entries, out, diagnose=fake_diagnose, html=True)
    (out / "log1.html").unlink()
    fleet.diagnose_fleet(entries, out, diagnose=fake_diagnose)
    first = (out / "log0.json").read_bytes()
    assert fleet.is_fleet_report(out / "log0.json") and not fleet.is_fleet_report(out / "other.json")
    fleet.diagnose_fleet(entries, out, diagnose=fake_diagnose)  # a rerun replaces its own reports
    assert json.loads(first)["ok"] and json.loads((out / "log0.json").read_text())["log"].endswith("log0.mcap")
    from twin.cli.scale import other_reports
    assert other_reports(out, {"log0.json", "log1.json", "fleet.json"}) == []  # other.json is not a report


# ---------------------------------------------------------------- commands

def test_montecarlo_command_writes_every_output(vessel, tmp_path):
    model = vessel_mod.save(vessel, tmp_path / "identified.json")
    outs = [tmp_path / f"band.{ext}" for ext in ("csv", "json", "png", "rrd")]
    done = twin("montecarlo", "--model", model, "--scenario", "turn", "--duration", "10", "--draws", "40",
                "--batch-size", "16", *sum((["--out", p] for p in outs), []))
    assert done.returncode == 0, done.stderr
    assert "40 draws of 10 s" in done.stdout and "distance from nominal" in done.stdout
    band = json.loads(outs[1].read_text())
    # the heading's band is printed as headings, like u's (not against the nominal): the band's own ends
    low, high, nominal = map(float, re.search(r"heading \[([-\d.]+), ([-\d.]+)\]° \(nominal ([-\d.]+)°\)",
                                              done.stdout).groups())
    ends = np.degrees([band["band"]["psi"]["p05"][-1], band["band"]["psi"]["p95"][-1], band["nominal"]["psi"][-1]])
    assert np.allclose([low, high, nominal], ends, atol=0.051)
    assert band["draws"] == 40 and len(band["t_s"]) == 21 and band["variation"]["covariance"]
    assert all(p.stat().st_size > 1000 for p in outs)


def test_montecarlo_says_when_most_draws_fall_outside_physics(vessel, tmp_path):
    # X_u drawn with σ 0.5 N s/m about +0.3: three draws in four stop dissipating in surge and are redrawn
    wide = replace(vessel_mod.load("blueboat"), uncertainty={"coordinates": [{"name": "Xu", "log": False, "sign": -1.0}],
                                                             "mean": [0.3], "covariance": [[0.25]]})
    done = twin("montecarlo", "--model", vessel_mod.save(wide, tmp_path / "wide.json"), "--draws", "8", "--duration",
                "5", "--out", tmp_path / "band.json")
    assert done.returncode == 0, done.stderr
    rejected = int(re.search(r"(\d+) draws redrawn as unphysical", done.stdout).group(1))
    assert rejected > 8 and "pin the twin's coefficients loosely" in done.stdout
    tight = twin("montecarlo", "--model", vessel_mod.save(vessel, tmp_path / "tight.json"), "--draws", "8",
                 "--duration", "5", "--out", tmp_path / "band2.json")
    assert tight.returncode == 0 and "loosely" not in tight.stdout, tight.stdout


@pytest.mark.parametrize("args, message", [
    (["montecarlo", "--vessel", "yellowfish"], "carries no identification uncertainty"),
    (["montecarlo", "--vessel", "yellowfish", "--no-covariance"], "nothing varies"),
    (["montecarlo", "--vessel", "yellowfish", "--vary", "Xq=1..2"], "unknown coefficient 'Xq'"),
    (["montecarlo", "--vessel", "yellowfish", "--effect", "current=0..0.3,0..400"], "dir_deg must be"),
    (["montecarlo", "--vessel", "yellowfish", "--no-covariance", "--vary", "Xu=1..2", "--ray", "127.0.0.1:1"],
     "nothing answers"),
    (["montecarlo", "--vessel", "yellowfish", "--no-covariance", "--vary", "Xu=1..2", "--ray", "ray://127.0.0.1"],
     "expected auto"),
    (["dataset-shards", "--vessel", "yellowfish", "--vary", "mass=0..2"], "factors must be > 0"),
    (["dataset-shards", "--vessel", "yellowfish", "--manoeuvres", "loop"], "unknown manoeuvre"),
    (["dataset-shards", "--vessel", "yellowfish", "--vary", "Xu=0.5..0.6", "--vary", "Xu=1..1.1"],
     "--vary Xu given twice"),
    (["fleet", "--vessel", "yellowfish", "missing.tlog"], "no such file"),
])
def test_bad_input_is_one_line_and_exit_2(args, message, tmp_path, monkeypatch, capsys):
    from twin.cli.app import main

    out = tmp_path / ("b.json" if args[0] == "montecarlo" else "out")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", ["twin", *args, "--out", str(out)])
    with pytest.raises(SystemExit) as exit_info:
        main()
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


def _server(answer: bytes):
    """A one-connection TCP server on a free local port that sends `answer` to what it is sent."""
    import socket
    import threading

    listener = socket.create_server(("127.0.0.1", 0))

    def serve():
        conn, _ = listener.accept()
        with conn:
            conn.recv(64)
            conn.sendall(answer)
        listener.close()

    threading.Thread(target=serve, daemon=True).start()
    return f"127.0.0.1:{listener.getsockname()[1]}"


def test_a_ray_address_that_answers_but_not_as_ray_is_refused_at_once():
    """Ray retries a head that is not one for minutes, printing its own log lines: a server that does not
    answer HTTP/2's preface with a SETTINGS frame, as every gRPC server does, is refused before."""
    with pytest.raises(TwinError, match="something answers there, but not Ray"):
        batches.check_reachable(_server(b"HTTP/1.0 400 Bad Request\r\n\r\n"))
    batches.check_reachable(_server(bytes([0, 0, 6, 4, 0, 0, 0, 0, 0]) + bytes(6)))  # a gRPC server's SETTINGS


def test_a_private_ray_says_nothing_of_its_default_authentication_but_passes_other_warnings(caplog):
    def init(**_):
        logging.getLogger(batches.RAY_AUTH_LOGGER).warning("Token authentication is enabled for this Ray cluster.")
        logging.getLogger(batches.RAY_AUTH_LOGGER).warning("Token authentication is disabled for this Ray cluster.")

    assert batches.connect(SimpleNamespace(is_initialized=lambda: False, init=init), "local")
    said = " ".join(r.getMessage() for r in caplog.records)
    assert "is disabled" in said and "is enabled" not in said
    assert not logging.getLogger(batches.RAY_AUTH_LOGGER).filters


def test_ray_auto_without_a_cluster_is_refused_before_any_work(tmp_path, monkeypatch):
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    monkeypatch.setenv("RAY_TMPDIR", str(tmp_path))
    with pytest.raises(TwinError, match=f"--ray auto: no Ray cluster runs on this machine .*{tmp_path}/ray/ray_current"):
        batches.executor_from("auto")
    (tmp_path / "ray").mkdir()
    (tmp_path / "ray" / "ray_current_cluster").write_text(_server(bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])) + "\n")
    assert batches.executor_from("auto").address == "auto"  # the head `ray start` recorded answers as Ray


def test_dataset_shards_and_fleet_commands(logs, tmp_path):
    done = twin("dataset-shards", "--vessel", "yellowfish", "--out", tmp_path / "ds", "--vessels", "3",
                "--per-shard", "2", "--segments", "1", "--manoeuvres", "rc", "--vary", "Nr=0.8..1.25",
                "--format", "csv")
    assert done.returncode == 0, done.stderr
    index = json.loads((tmp_path / "ds" / "index.json").read_text())
    assert len(index["entries"]) == 3 and index["entries"][2]["file"] == "shard-00001/vessel-000002.csv"
    done = twin("fleet", logs / "log1.mcap", logs / "log2.mcap", "--vessel", "yellowfish", "--out", tmp_path / "f",
                "--effects", "current", "--window", "5")
    # a log too short to diagnose is listed, not a failure of the command (a fault in a log is: exit 2)
    assert done.returncode == 0 and "could not be diagnosed" not in done.stderr, done.stderr
    summary = json.loads((tmp_path / "f" / "fleet.json").read_text())
    assert (summary["logs"], summary["diagnosed"]) == (2, 1) and summary["failed"][0]["log"].endswith("log2.mcap")
    assert summary["failed"][0]["too_short"] and "too short" in summary["failed"][0]["error"]
    report = json.loads((tmp_path / "f" / "log1.json").read_text())
    assert report["ok"] and {"effects", "fit_before", "fit_after"} <= set(report["report"])


def test_evaluate_band_command_on_a_recording(vessel, tmp_path):
    from twin.formats import write_recording
    from twin.synth.dataset import PROFILES, generate

    rec = generate(vessel, n_segments=2, manoeuvres=["rc"], seed=2, noise=PROFILES["none"],
                   segment_s=(70.0, 70.0)).recording
    write_recording(rec, tmp_path / "run.csv")
    model = vessel_mod.save(vessel, tmp_path / "identified.json")
    done = twin("evaluate", tmp_path / "run.csv", "--model", model, "--no-calibration", "--band", "--draws", "32",
                "--json", tmp_path / "eval.json")
    assert done.returncode == 0, done.stderr
    band = json.loads((tmp_path / "eval.json").read_text())["band"]
    assert band["level"] == 0.9 and band["inside"]["u"] > 0.9 and "share of the recording inside" in done.stdout
    done = twin("evaluate", tmp_path / "run.csv", "--vessel", "yellowfish", "--band")
    assert done.returncode == 2 and "uncertainty" in done.stderr and len(done.stderr.strip().splitlines()) == 1


def test_a_fleet_day_read_from_the_files_time_says_so():
    """A day no manifest and no log clock gave is the file's modification time (a copy's, not the
    outing's): the summary says so beside it; a log's failure reads its reason once, not its name twice."""
    from twin.scale.fleet import format_summary, summarise

    results = [{"log": "a.csv", "vessel": "blueboat", "ok": True, "effects": [], "day": "2026-12-03",
                "day_from": "file time"},
               {"log": "empty.csv", "vessel": "blueboat", "ok": False, "error": "empty.csv: empty file",
                "day": "2026-12-03", "day_from": "file time"}]
    text = format_summary(summarise(results))
    assert "### 2026-12-03: 1 of 2 logs diagnosed (the day from the file's modification time: neither" in text
    # a day whose logs read it from different sources says so, each with its count
    mixed = [{"log": "turn_14-Oct-2020.csv", "vessel": "esso_osaka", "ok": True, "effects": [], "day": "2020-10-14",
              "day_from": "file name"},
             {"log": "copy.csv", "vessel": "esso_osaka", "ok": True, "effects": [], "day": "2020-10-14",
              "day_from": "file time"},
             {"log": "clocked.bin", "vessel": "esso_osaka", "ok": True, "effects": [], "day": "2020-10-15",
              "day_from": "log clock"}]
    mixed_text = format_summary(summarise(mixed))
    assert ("### 2020-10-14: 2 of 2 logs diagnosed (the day from a date in the file's name (1 of 2 logs), the "
            "file's modification time (1 of 2 logs): neither") in mixed_text
    assert "### 2020-10-15: 1 of 1 log diagnosed (the day from the log's own clock)" in mixed_text
    assert "- empty.csv: empty file" in text and "empty.csv: empty.csv" not in text


def test_a_fleet_day_is_read_from_a_date_in_the_file_name():
    """A copied log's modification time is the day it was copied: a date in its name (ISO, with or
    without dashes, or 14-Oct-2020) is the outing's day; a log counter's digits are not a date."""
    assert fleet.day_in_name("turn_14-Oct-2020_14_29_49.csv") == "2020-10-14"
    assert fleet.day_in_name("2026-05-02_survey.bin") == "2026-05-02"
    assert fleet.day_in_name("log_20201014_1200.tlog") == "2020-10-14"
    assert fleet.day_in_name("fixed_00000216.csv") is None
    assert fleet.day_in_name("run_20201399.csv") is None  # month 13: not a day
    rec = SimpleNamespace(origin_s=0.0)  # a log clock that is not a calendar time
    item = fleet._Item(0, "turn_14-Sep-2020_14_16_04.csv", b"", "esso_osaka", None, "2026-12-03")
    assert fleet._day(rec, item) == ("2020-09-14", "file name")
    counter = fleet._Item(1, "fixed_00000216.csv", b"", "blueboat", None, "2026-12-03")
    assert fleet._day(rec, counter) == ("2026-12-03", "file time")


def test_an_interrupted_fleet_leaves_no_empty_folder_it_made_and_keeps_one_it_did_not(logs, tmp_path):
    entries = fleet.read_manifest(logs / "manifest.csv", default_vessel="yellowfish")

    def interrupted(recordings, vessel, **options):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        fleet.diagnose_fleet(entries, tmp_path / "new", diagnose=interrupted)
    assert not (tmp_path / "new").exists()
    (tmp_path / "kept").mkdir()
    with pytest.raises(KeyboardInterrupt):
        fleet.diagnose_fleet(entries, tmp_path / "kept", diagnose=interrupted)
    assert (tmp_path / "kept").is_dir()


def test_fleet_report_names_are_one_per_log_even_where_a_numbered_name_is_another_logs_stem():
    from pathlib import Path

    logs = [SimpleNamespace(path=Path(p)) for p in ("a/run.csv", "b/run.csv", "c/run-2.csv", "d/run.csv", "e/x.csv")]
    names = fleet._report_names(logs)
    assert names == ["run", "run-3", "run-2", "run-4", "x"]
