"""`twin diagnose`: every library effect recovered by its candidate on data it was
injected in, the whole diagnosis on a concealed effect and on the twin's own data,
and the command's outputs."""
import json
from dataclasses import replace

import numpy as np
import pytest

import twin.vessel as vessel_mod
import twin_command
from twin.effects import candidates
from twin.diagnose.doctor import diagnose
from twin.prepare import supply_reference
from twin.diagnose.search import Search
from twin.engine.mjcf import compile_vessel
from twin.errors import TwinError
from twin.synth.dataset import PROFILES, generate
from twin.effects import EFFECTS, as_effect
from twin.fit.objective import Measurements
from twin.fit.windows import ModelCache, Window, make_windows
from twin.physics.sensors import log_name
from twin.formats import write_recording
from twin.fit.calibrate import prepare_for

PREP = {"window_s": 1.0, "heading_window_s": 0.5}
MIXED = ["rc", "circle_varying", "forward_varying", "zigzag"]

# effect injected → (candidate, tolerance on each effect parameter: relative, or absolute for angles/offsets)
CASES = {
    "current=0.3,60": ("current", {"speed_m_s": 0.05, "dir_deg": 5.0}),
    "wind=8,30": ("wind", {"speed_m_s": 0.15, "dir_deg": 10.0}),
    "wind_shape=7,200,1.2,0.3": ("wind_shape", {"speed_m_s": 0.15, "dir_deg": 10.0, "cn": 0.15}),
    "thruster_lag=0.5": ("thruster_lag", {"lag_s": 0.1}),
    "input_delay=0.4": ("input_delay", {"delay_s": 0.021}),
    "thrust_ramp=2": ("thrust_ramp", {"ramp_s": 0.15}),
    "clock_offset=0.3": ("clock_offset", {"pwm_clock_offset_s": 0.021}),
    "dead_zone=0.2,0.2": ("dead_zone", {"fwd": 0.15, "rev": 0.15}),
    "dead_zone_left=0.2,0.2": ("dead_zone_left", {"fwd": 0.15, "rev": 0.15}),
    "dead_zone_right=0.25,0.15": ("dead_zone_right", {"fwd": 0.15, "rev": 0.15}),
    "motor_start=0.16,0.17": ("motor_start", {"fwd": 0.026, "rev": 0.026}),
    "thruster_asymmetry=0.85": ("thruster_asymmetry", {"ratio": 0.03}),
    "thrust_gain=1.2": ("thrust_gain", {"scale": 0.03}),
    "thruster_gain_left=0.7": ("thruster_gain_left", {"scale": 0.03}),
    "thruster_gain_right=1.2": ("thruster_gain_right", {"scale": 0.03}),
    "pwm_span_right=1.3": ("pwm_span_right", {"span": 0.03}),
    "pwm_span_left=0.8": ("pwm_span_left", {"span": 0.03}),
    "reverse_thrust=0.6": ("reverse_thrust", {"scale": 0.05}),
    "full_thrust=0.7": ("full_thrust", {"share": 0.05}),
    "thrust_decay=0.1": ("thrust_decay", {"decay_per_min": 0.15}),
    # the reference the diagnosis takes (the logged voltage's 99th percentile) is within a few mV of the
    # truth's 16 V: one of the dataset's packs starts full
    "supply_voltage=2,16": ("supply_voltage", {"exponent": 0.1}),
    "thrust_speed_loss=1.5": ("thrust_speed_loss", {"advance_loss": 0.6}),
    "heading_bias=5": ("heading_bias", {"heading_bias_deg": 0.5}),
    "gnss_latency=0.4": ("gnss_latency", {"gnss_latency_s": 0.05}),
    "heading_latency=0.4": ("heading_latency", {"heading_latency_s": 0.05}),
    "compass_deviation=6,-4": ("compass_deviation", {"b_deg": 1.0, "c_deg": 1.0}),
    "compass_motor=10,-6": ("compass_motor", {"b_deg": 1.5, "c_deg": 1.5}),
    "gnss_lever_arm=0.4,-0.3": ("gnss_lever_arm", {"dx_m": 0.08, "dy_m": 0.08}),
    "quadratic_damping=Xuu:1.5": ("quadratic_damping", {"Xuu": 0.1}),
    "astern_resistance=1.0": ("astern_resistance", {"excess": 0.1}),
    "linear_damping=Nr:0.6": ("linear_damping", {"Nr": 0.1}),
    "surge_resistance=Xu:0.5,Xuu:1.4": ("surge_resistance", {"Xu": 0.25, "Xuu": 0.05}),  # Xu·u is a sixth of Xuu·u² at 1.5 m/s
    "coupling_damping=-6,-4": ("coupling_damping", {"Yr": 2.0, "Nv": 2.0}),
    "added_mass=Yvdot:1.6": ("added_mass", {"Yvdot": 0.15}),
    "speed_damping=-20,-15": ("speed_damping", {"Yuv": 8.0, "Nur": 3.0}),
    "speed_coupling=15,-5": ("speed_coupling", {"Yur": 3.0, "Nuv": 3.0}),
    "cg_offset=0.2,0": ("cg_offset", {"dx_m": 0.05, "dy_m": 0.05}),
}
ABSOLUTE = {"dir_deg", "delay_s", "pwm_clock_offset_s", "heading_bias_deg", "b_deg", "c_deg", "dx_m", "dy_m", "Yr", "Nv", "fwd", "rev",
            "Yuv", "Nur", "Yur", "Nuv", "gnss_latency_s",
            "heading_latency_s"}


def make_search(prior, preps, recs, cv, library):
    """A Search over every 10-s window of the recordings (its refine fits on fold 0's training part)."""
    windows = make_windows(preps, 10.0, 10.0, min_length_s=10.0)
    return Search(prior, Measurements(preps, recs, cv, PREP), windows, ModelCache(0.05), library,
                  np.array([0.02, 0.02, 0.005]))


@pytest.fixture(scope="module")
def prior():
    return vessel_mod.load("yellowfish")


def test_every_library_effect_has_a_case():
    # the per-log effects have tests of their own (below; tests/test_wind_per_log.py)
    covered = {as_effect(text).name for text in CASES} | {"thruster_asymmetry", "heading_bias_per_log", "wind_per_log",
                                                      "wind_load_shape"}
    assert covered >= set(EFFECTS)


def test_a_dead_zone_widened_astern_only_is_screened_at_that_edge(prior):
    """The reverse edge alone moved (0.0925 → 0.2; the thrust it removes reaches 2.7 N, where a moved edge
    near neutral removes tenths of a newton and no fit can place it): screening scans each edge alone,
    and lands on it, which a scan of both edges together cannot."""
    ds = generate(prior, effects=["dead_zone=0.0775,0.2"], n_segments=3, seed=2, noise=PROFILES["none"],
                  segment_s=(35, 40), manoeuvres=MIXED)
    cv = compile_vessel(prior)
    search = make_search(prior, [prepare_for(ds.recording, cv, **PREP)], [ds.recording], cv, candidates(prior))
    screened = min(search.screen(prior, search.library["dead_zone"]), key=lambda f: f.train_cost)
    assert screened.values["fwd"] == pytest.approx(0.0775) and screened.values["rev"] == pytest.approx(0.2, abs=0.026)


def test_a_folds_scanned_fit_does_not_start_from_the_screening_that_saw_its_held_out_blocks(prior):
    """The screening windows are fold 0's training windows, which are the other folds' held-out ones:
    a scanned candidate's fold fit scans its own coarse grid again, so what screening chose (here a
    value far from the truth) does not decide the value that fold's blocks then judge."""
    from dataclasses import replace as with_values

    ds = generate(prior, effects=["input_delay=0.4"], n_segments=3, seed=3, noise=PROFILES["none"],
                  segment_s=(35, 40), manoeuvres=MIXED)
    cv = compile_vessel(prior)
    search = make_search(prior, [prepare_for(ds.recording, cv, **PREP)], [ds.recording], cv, candidates(prior))
    screened = min(search.screen(prior, search.library["input_delay"]), key=lambda f: f.train_cost)
    elsewhere = with_values(screened, values={"delay_s": 1.08})
    train = search.folds[1][0]
    near, far = (search.refine(prior, f, train).values["delay_s"] for f in (screened, elsewhere))
    assert near == far == pytest.approx(0.4, abs=0.03)


def test_heading_bias_of_each_log_recovered(prior):
    """Two logs, each with its own compass bias: one parameter per log, by the log's file name."""
    recs = [generate(prior, effects=[f"heading_bias={b}"], n_segments=3, seed=20 + i, noise=PROFILES["none"],
                     segment_s=(35, 40), manoeuvres=MIXED).recording for i, b in enumerate((4.0, -3.0))]
    cv = compile_vessel(prior)
    preps = [prepare_for(r, cv, **PREP) for r in recs]
    logs = [log_name(r.source) for r in recs]
    library = candidates(prior, logs)
    assert "heading_bias_per_log" not in candidates(prior, logs[:1])  # one log: that is heading_bias
    search = make_search(prior, preps, recs, cv, library)
    cand = library["heading_bias_per_log"]
    fitted = search.refine(prior, min(search.screen(prior, cand), key=lambda f: f.train_cost))
    got = cand.to_effect(fitted.values).params
    assert got[logs[0]] == pytest.approx(4.0, abs=0.3) and got[logs[1]] == pytest.approx(-3.0, abs=0.3)
    amended = as_effect(cand.to_effect(fitted.values).text).spec.apply(prior, got)
    assert amended.sensors.for_log("/any/folder/" + logs[1]).heading_bias_deg == pytest.approx(got[logs[1]])


def test_a_scale_effect_frees_only_the_scales_its_training_blocks_pin(prior):
    """Yaw damping ×0.6 alone: fitted on enough blocks, a scale its windows do not move by 3 σ stays
    at the prior's value (and the twin's coefficient with it) and the others are refitted without
    it; on a handful of blocks the sandwich's σ is not trusted and every scale stays free."""
    ds = generate(prior, effects=["linear_damping=Nr:0.6"], n_segments=8, seed=3, noise=PROFILES["realistic"],
                  segment_s=(35, 40), manoeuvres=MIXED)
    cv = compile_vessel(prior)
    search = make_search(prior, [prepare_for(ds.recording, cv, **PREP)], [ds.recording], cv, candidates(prior))
    cand = search.library["linear_damping"]
    assert cand.separable and [p.name for p in cand.params] == ["Xu_scale", "Yv_scale", "Nr_scale"]
    fitted = search.refine(prior, min(search.screen(prior, cand), key=lambda f: f.train_cost), search.windows)
    assert fitted.fixed and "Nr_scale" not in fitted.fixed  # here sway's scale (seed 4: surge's too)
    assert fitted.values["Nr_scale"] == pytest.approx(0.6, abs=0.05)
    assert all(fitted.values[k] == 1.0 for k in fitted.fixed) and fitted.vessel.damping.Yv == prior.damping.Yv
    few = search.refine(prior, min(search.screen(prior, cand), key=lambda f: f.train_cost), search.windows[:15])
    assert few.fixed == ()


def test_an_identified_twin_weighs_each_dof_by_its_own_misfit_there(prior):
    """A twin that carries its form error (identified on other runs) scales each DOF's residual by
    √(noise² + its RMS misfit on the recordings): every DOF then costs about as much per sample,
    however poorly the twin predicts it; a prior keeps the spread of the measured signal."""

    from twin.diagnose.search import dof_scale
    from twin.fit.objective import Objective

    ds = generate(prior, effects=["linear_damping=Yv:0.4"], n_segments=3, seed=5, noise=PROFILES["realistic"],
                  segment_s=(35, 40), manoeuvres=MIXED)
    cv = compile_vessel(prior)
    preps = [prepare_for(ds.recording, cv, **PREP)]
    windows = make_windows(preps, 10.0, 10.0, min_length_s=10.0)
    whole = Objective(prior, [], Measurements(preps, [ds.recording], cv, PREP), windows, ModelCache(0.05))
    noise = np.array([0.02, 0.02, 0.005])
    assert np.array_equal(dof_scale(prior, whole, noise), whole.sigma)
    identified = replace(prior, uncertainty={"form_error": {"quantiles": {}}})
    scale = dof_scale(identified, whole, noise)
    r = whole.residuals_of([prior])[0] * whole.sigma[np.broadcast_to(np.arange(3), whole.meas.shape)[whole.valid]]
    dof = np.broadcast_to(np.arange(3), whole.meas.shape)[whole.valid]
    for k in range(3):
        assert scale[k] == pytest.approx(np.sqrt(noise[k] ** 2 + np.mean(r[dof == k] ** 2)), rel=1e-9)
    # sway damping at 0.4 of the twin's: sway is the DOF it misses most against its signal's spread,
    # and the scale takes that spread's place for it
    share = np.array([np.mean(r[dof == k] ** 2) for k in range(3)]) / whole.sigma ** 2
    assert int(np.argmax(share)) == 1
    per_dof = np.array([np.mean(r[dof == k] ** 2) / scale[k] ** 2 for k in range(3)])
    assert np.all((per_dof > 0.5) & (per_dof < 1.0))


@pytest.mark.parametrize("text", list(CASES))
def test_candidate_recovers_its_effect(prior, text):
    name, tolerance = CASES[text]
    ds = generate(prior, effects=[text], n_segments=3, seed=2, noise=PROFILES["none"], segment_s=(35, 40),
                  manoeuvres=MIXED[:2] + ["astern_varying"] if name == "astern_resistance" else MIXED)
    cv = compile_vessel(prior)
    preps = [prepare_for(ds.recording, cv, **PREP)]
    search = make_search(prior, preps, [ds.recording], cv, candidates(prior, supply_ref_v=supply_reference(preps)))
    cand = search.library[name]
    fitted = search.refine(prior, min(search.screen(prior, cand), key=lambda f: f.train_cost))
    got = cand.to_effect(fitted.values).params
    injected = as_effect(text).params
    for key, tol in tolerance.items():
        want = injected[key]
        if key == "dir_deg":
            assert abs((got[key] - want + 180) % 360 - 180) < tol, (key, got[key], want)
        elif key in ABSOLUTE:
            assert got[key] == pytest.approx(want, abs=tol), (key, got[key], want)
        else:
            assert got[key] == pytest.approx(want, rel=tol), (key, got[key], want)


def test_a_logged_pack_voltage_reaches_the_windows_and_offers_the_supply_effect(prior):
    """A recording with a battery stream: held on the grid (its first reading before it), its 99th
    percentile the reference, and the windows' thrust commands scaled by (V/V_ref)^k; a log without
    one, in the same diagnosis, withdraws the offer."""
    from twin.fit.windows import thrust_commands

    ds = generate(prior, effects=["supply_voltage=2,16"], n_segments=3, seed=2, noise=PROFILES["none"],
                  segment_s=(35, 40), manoeuvres=MIXED)
    cv = compile_vessel(prior)
    prep = prepare_for(ds.recording, cv, **PREP)
    assert prep.supply_v is not None and np.all(np.isfinite(prep.supply_v))
    assert prep.supply_v.min() == pytest.approx(0.88 * 16.0 - 0.01 * 16.0 * 37.5 / 60, abs=0.05)
    ref = supply_reference([prep])
    assert ref == pytest.approx(16.0, abs=0.02)
    assert "supply_voltage" in candidates(prior, supply_ref_v=ref) and "supply_voltage" not in candidates(prior)
    plain = generate(prior, n_segments=3, seed=3, noise=PROFILES["none"], segment_s=(35, 40), manoeuvres=MIXED)
    assert supply_reference([prep, prepare_for(plain.recording, cv, **PREP)]) is None
    with pytest.raises(TwinError, match="supply_voltage cannot be fitted .*every log's voltage"):
        diagnose([ds.recording, plain.recording], prior, library=["supply_voltage"])
    follows = replace(prior, thrusters=replace(prior.thrusters, supply_exponent=2.0, supply_ref_v=ref))
    w = make_windows([prep], 10.0, 10.0, min_length_s=10.0)[5]
    got, base = (thrust_commands(v, prep, w, 0.05) for v in (follows, prior))
    volt = prep.supply_v[w.start + np.arange(w.n * 2) // 2]
    np.testing.assert_allclose(got, base * ((volt / ref) ** 2)[:, None], rtol=1e-9)


def test_a_delay_within_an_engine_step_moves_the_thrust_by_the_share_of_the_step_it_covers(prior):
    """The engine holds each command over its 0.05-s step: the step's mean of the logged input, so
    a 0.02-s delay is 0.4 of the way from no delay to one whole step (held at the step's start,
    every delay within a step would give the same thrust and a fitted delay a plateau a step wide)."""
    from twin.fit.windows import thrust_commands

    ds = generate(prior, n_segments=1, seed=4, noise=PROFILES["none"], segment_s=(40, 41), manoeuvres=MIXED)
    prep = prepare_for(ds.recording, compile_vessel(prior), **PREP)
    w = make_windows([prep], 10.0, 10.0, min_length_s=10.0)[1]
    late = {d: thrust_commands(replace(prior, thrusters=replace(prior.thrusters, delay_s=d)), prep, w, 0.05)
            for d in (0.0, 0.02, 0.05)}
    np.testing.assert_allclose(late[0.02], 0.6 * late[0.0] + 0.4 * late[0.05], rtol=1e-12, atol=1e-12)
    assert np.abs(late[0.02] - late[0.0]).max() > 1.0  # the window's PWM changes: the delay moves thrust


def test_a_lags_and_a_gains_trials_share_the_commands_and_each_lag_starts_from_its_own_history(prior):
    """The commands are the same for every lag, gain and advance loss, so the cache computes them
    once; a lag filters them from its state at the window's start, that lag's filter of the
    commands since the segment began, whichever lag was asked first; a delay is not shared."""
    from scipy.signal import lfilter
    from twin.fit.windows import thrust_commands

    ds = generate(prior, n_segments=1, seed=4, noise=PROFILES["none"], segment_s=(40, 41), manoeuvres=MIXED)
    prep = prepare_for(ds.recording, compile_vessel(prior), **PREP)
    w = make_windows([prep], 10.0, 10.0, min_length_s=10.0)[2]
    cache = ModelCache(0.05)

    def boat(**kw):
        return replace(prior, thrusters=replace(prior.thrusters, **kw))

    raw = cache.inputs(boat(lag_s=0.0), prep, w, 0.05)
    assert cache.inputs(boat(lag_s=0.0, gain_right=0.9, advance_loss=1.0), prep, w, 0.05) is raw
    assert cache.inputs(boat(lag_s=0.0, delay_s=0.1), prep, w, 0.05) is not raw
    got = {lag: cache.inputs(boat(lag_s=lag, gain_right=0.9), prep, w, 0.05) for lag in (0.2, 0.6)}
    seg = prep.segments[int(prep.segment[w.start])]
    history = thrust_commands(prior, prep, Window(0, seg.start, w.start - seg.start), 0.05)
    assert len(history) == 2 * (w.start - seg.start) > 100
    for lag, thrust in got.items():
        a = np.exp(-0.05 / lag)
        start = lfilter([1 - a], [1, -a], history, axis=0, zi=(a * history[0])[None, :])[0][-1]
        # the first step's mean thrust: from the lag's start toward the step's command
        np.testing.assert_allclose(thrust[0], raw[0] + (start - raw[0]) * lag / 0.05 * (1 - a), rtol=1e-12)
    assert np.abs(got[0.2][0] - got[0.6][0]).max() > 0.5  # the two lags do start apart
    # every window's start is the history's own filter, bit for bit, though the cache filters each
    # segment once per lag
    from twin.fit.windows import lagged_thrust, lagged_thrust_at_start

    lagged = boat(lag_s=0.3)
    for v in make_windows([prep], 10.0, 5.0, min_length_s=5.0):
        cmd = thrust_commands(lagged, prep, v, 0.05)
        want = lagged_thrust(np.clip(cmd, *lagged.thrusters.bounds()),
                             lagged_thrust_at_start(lagged, prep, v, 0.05), 0.3, 0.05)
        assert np.array_equal(cache.inputs(lagged, prep, v, 0.05), want)


def test_a_lag_filtered_ahead_of_the_engine_is_exact_and_stable_at_any_step():
    """A step command through a 0.02-s lag at a 0.1-s step (RK4 on the lag as state runs away
    there: |hλ| 5) gives each step's exact mean thrust, never beyond the command."""
    from twin.fit.windows import lagged_thrust

    commands = np.column_stack([np.full(6, 10.0), np.full(6, -4.0)])
    got = lagged_thrust(commands, np.array([0.0, 2.0]), 0.02, 0.1)
    tau, h = 0.02, 0.1
    # ∫₀ʰ c + (y₀ − c) e^(−t/τ) dt / h for the first step, then y₀ = c(1 − e^(−h/τ)) + y₀ e^(−h/τ)
    want0 = commands[0] + (np.array([0.0, 2.0]) - commands[0]) * tau / h * (1 - np.exp(-h / tau))
    np.testing.assert_allclose(got[0], want0, rtol=1e-12)
    assert got[0, 0] == pytest.approx(8.013, abs=0.001) and np.all(got[:, 0] <= 10.0) and np.all(got[:, 1] >= -4.0)
    np.testing.assert_allclose(got[-1], commands[-1], atol=1e-9)


def test_a_concealed_current_is_named_with_an_interval_that_holds_it(prior):
    """A current concealed in a run with realistic sensors, offered beside a thrust scale: named, its
    95 % interval holding the truth, the amended twin carrying it and the sway's fit mended."""
    ds = generate(prior, effects=["current=0.2,120"], n_segments=6, seed=5, noise=PROFILES["realistic"])
    d = diagnose([ds.recording], prior, library=["current", "thrust_gain"])
    assert [e["name"] for e in d.effects] == ["current"]
    e = d.effects[0]
    lo, hi = e["ci"]["speed_m_s"]
    assert lo <= 0.2 <= hi and abs(e["parameters"]["dir_deg"] - 120) < 5
    assert d.fit_after["v"]["r2"] > d.fit_before["v"]["r2"] + 0.3
    assert d.amended.environment.current_speed_m_s == pytest.approx(e["parameters"]["speed_m_s"], rel=1e-6)
    # the amended twin says what amended it, and that it is not the prior's file
    assert "diagnosis" not in d.prior.sources and e["text"] in d.amended.sources["diagnosis"]
    assert "amended by a diagnosis (not saved)" in repr(d.amended)


def test_diagnose_names_nothing_on_the_twins_own_realistic_run(prior):
    """The whole library on the twin's own run with realistic sensors: nothing named, the answer said in
    notes."""
    null = diagnose([generate(prior, n_segments=6, seed=6, noise=PROFILES["realistic"]).recording], prior)
    assert null.effects == [] and null.notes and "diagnosis" not in null.amended.sources
    json.dumps(null.to_dict(), allow_nan=True)


def test_diagnose_command_writes_everything(tmp_path, prior):
    ds = generate(prior, effects=["thruster_asymmetry=0.85"], n_segments=6, seed=3, noise=PROFILES["realistic"],
                  manoeuvres=MIXED)
    rec = tmp_path / "run.tlog"
    write_recording(ds.recording, rec)
    out = {k: tmp_path / f"d.{k}" for k in ("json", "html", "rrd")}
    amended = tmp_path / "amended.json"
    cmd = ["diagnose", str(rec), "--vessel", "yellowfish", "--json",
           str(out["json"]), "--report", str(out["html"]), "--rrd", str(out["rrd"]), "--write-model", str(amended),
           "--effects", "thruster_asymmetry,thruster_gain_left,thruster_gain_right,thrust_gain,current"]  # its rivals
    done = twin_command.twin(*cmd)
    assert done.returncode == 0, done.stderr
    d = json.loads(out["json"].read_text())
    assert set(d) >= {"effects", "located", "fit_before", "fit_after", "unexplained", "noise"}
    assert d["effects"][0]["name"] == "thruster_asymmetry"
    assert d["effects"][0]["parameters"]["ratio"] == pytest.approx(0.85, abs=0.03)
    assert set(d["fit_after"]["r"]) >= {"r2", "mae"} and d["fit_after"]["r"]["r2"] > d["fit_before"]["r"]["r2"]
    assert out["html"].read_text().count("<img") == 2 and out["rrd"].stat().st_size > 1000
    assert d["answer"]["missing"][0].startswith("thruster_asymmetry")
    v = vessel_mod.load(str(amended))
    assert v.thrusters.gain_right / v.thrusters.gain_left == pytest.approx(0.85, abs=0.03)


def test_diagnose_given_judges_an_effect_as_given_without_a_search(tmp_path, prior):
    # the concealed asymmetry as given earns its place; the opposite one is contradicted; outputs of a
    # search are refused with --given, and a bad effect text before anything is read
    ds = generate(prior, effects=["thruster_asymmetry=0.85"], n_segments=6, seed=3, noise=PROFILES["realistic"],
                  manoeuvres=MIXED)
    rec = tmp_path / "run.csv"
    write_recording(ds.recording, rec)
    base = ["diagnose", str(rec), "--vessel", "yellowfish"]
    right = twin_command.twin(*(base + ["--given", "thruster_asymmetry=0.85", "--json", str(tmp_path / "g.json")]))
    assert right.returncode == 0, right.stderr
    assert right.stdout.startswith("thruster_asymmetry=0.85 earns its place as given: z ")
    g = json.loads((tmp_path / "g.json").read_text())
    assert g["earns_its_place"] and g["z"] >= 3 and g["excess_gain"] > 0.5 and g["given"] == ["thruster_asymmetry=0.85"]
    import twin
    from twin.diagnose.report import given_text

    wrong = twin.judge([ds.recording], prior, "thruster_asymmetry=1.15")  # in process: the same rule
    assert wrong.z <= -3 and "is contradicted by these recordings" in given_text(["thruster_asymmetry=1.15"], wrong)
    for extra, message in ((["--report", str(tmp_path / "r.html")], "--report does not apply"),
                           (["--given", "current=0.2"],
                            "effect 'current=0.2': expected current=speed_m_s,dir_deg (2 numbers), got 1 value '0.2'")):
        bad = twin_command.twin(*(base + ["--given", "current=0.1,0"] + extra))
        assert bad.returncode == 2 and message in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "r.html").exists()


def test_bad_recordings_get_one_line_errors(tmp_path, prior):
    short = generate(prior, n_segments=1, seed=1, segment_s=(30, 31))
    with pytest.raises(TwinError, match="too short"):
        diagnose([short.recording], prior)
    rec = tmp_path / "nopwm.csv"
    rec.write_text("t,lat,lon,heading_deg\n" + "".join(f"{i * 0.2:.1f},37.4,-5.97,10\n" for i in range(900)))
    done = twin_command.twin("diagnose", rec, "--vessel", "yellowfish")
    assert done.returncode == 2 and done.stderr.startswith("error:") and len(done.stderr.strip().splitlines()) == 1
    assert "PWM" in done.stderr


def test_a_promising_candidate_short_of_blocks_is_a_hint_never_named():
    """z below Z_MIN only for want of affected blocks (6 of 6 for: z 2.15 at best): the answer says
    so under 'unsettled' and what to record, names nothing, and gives one hint per family."""
    from types import SimpleNamespace

    from twin.diagnose.report import answer

    def cand(name, z, excess, n_for, n_against):
        return {"name": name, "z": z, "excess_gain": excess, "blocks_for": n_for, "blocks_against": n_against,
                "affected_windows": 9, "fold_values": []}

    rounds = [{"candidates": [cand("input_delay", 2.15, 0.079, 6, 0), cand("clock_offset", 2.15, 0.079, 6, 0),
                              cand("current", 2.5, 0.01, 8, 2), cand("added_mass", 1.2, 0.3, 5, 3)]}]
    d = SimpleNamespace(effects=[], rounds=rounds, unexplained=[], located=[], fit_before={}, fit_after={},
                        prior=vessel_mod.load("yellowfish"), windows={"length_s": 10.0, "windows": 90})
    a = answer(d)
    assert a["missing"][0].startswith("no effect of the library earns its place")
    hints = [u for u in a["unsettled"] if "may be missing but is not proven" in u]
    assert len(hints) == 1 and hints[0].startswith("input_delay") and "6 for, 0 against" in hints[0]
    # six blocks, all for: ten such blocks reach z 3.1, so 10/6 of the 15 minutes
    assert "about 1.7× as long as these 15 min of windows" in hints[0]
    assert any(line.startswith("to settle timing effects") for line in a["next"])


def test_what_the_kinematics_could_not_tell_gets_its_recording_advice():
    """An antenna or a timing the kinematics neither named nor showed absent (too few spins or steps)
    gets RECORD NEXT advice: spins in place for a boat, the drawings for a ship; a finding told, or
    shown absent, gets none."""
    from types import SimpleNamespace

    from twin.diagnose.report import answer
    from twin.fit.kinematic import KinematicFinding

    def finding(effect, told=False, absent=False, why="2 groups of large heading changes; 4 are needed"):
        return KinematicFinding(effect, {}, {}, {}, told, absent, why)

    def advice(vessel, kinematic):
        d = SimpleNamespace(effects=[], rounds=[], unexplained=[], located=[], fit_before={}, fit_after={},
                            prior=vessel_mod.load(vessel), windows={"length_s": 10.0, "windows": 90},
                            kinematic=kinematic)
        return answer(d)["next"]

    boat = advice("blueboat", [finding("gnss_lever_arm"), finding("heading_latency", why="too few input steps")])
    assert len(boat) == 2 and boat[0].startswith("to tell where the GNSS antenna sits (not told: 2 groups")
    assert "spins in place both ways" in boat[0] and boat[1].startswith("to settle timing effects: steps of the sticks")
    (ship,) = advice("esso_osaka", [finding("gnss_lever_arm")])
    assert "ship's drawings" in ship and "sensors.antenna_offset_m" in ship
    assert advice("blueboat", [finding("gnss_lever_arm", told=True), finding("clock_offset", absent=True)]) == []
    assert advice("blueboat", []) == []


def test_a_share_beyond_the_whole_excess_over_the_noise_is_not_printed_as_a_percentage():
    """A candidate that removes more than the misfit above the noise (the noise estimate is high) is
    said so in words, never as e.g. 16883373999 %; a share within it stays a percentage."""
    from twin.diagnose.report import excess_share
    from twin.diagnose.search import excess_shown

    assert excess_share(0.079) == "8 % of the held-out misfit above the noise"
    assert excess_share(0.995) == "100 % of the held-out misfit above the noise"
    big = excess_share(1.7e8)
    assert "%" not in big and big.startswith("all of the held-out misfit above the noise (or more")
    # a JSON file's share stops at ±1, and the report read back from it says the same words
    assert excess_shown(2.48e7) == 1.0 and excess_shown(-3e6) == -1.0 and excess_shown(0.12345) == 0.1235
    assert excess_share(excess_shown(1.7e8)) == big


def test_a_residual_that_follows_no_signal_is_not_blamed_on_the_form_alone():
    """A DOF still far off after the amendment: with signals it follows, the twin's form is blamed; with none
    (the proof's chop, a random force the log does not record), the answer says it may be either."""
    from types import SimpleNamespace

    from twin.diagnose.report import answer

    def d_with(follows):
        off = {"dimension": "all", "dof": "u", "rms": 0.12, "rms_over_noise": 4.0, "correlates_with": follows}
        return SimpleNamespace(effects=[], rounds=[], unexplained=[off], located=[], fit_before={}, fit_after={},
                               prior=vessel_mod.load("yellowfish"), windows={"length_s": 10.0, "windows": 90})

    plain, followed = answer(d_with([]))["form"][0], answer(d_with([{"signal": "u", "r": 0.48}]))["form"][0]
    assert "follows none of the logged signals" in plain and "a disturbance the log does not record" in plain
    assert "and follows u (+0.48): the twin's form is off there" in followed and "disturbance" not in followed


def test_the_answer_states_a_yaw_rate_residual_in_degrees_per_second():
    """The diagnosis computes in SI; the report has one unit for r, °/s, in its text as in its tables."""
    from types import SimpleNamespace

    from twin.diagnose.report import answer

    off = {"dimension": "all", "dof": "r", "rms": 0.1, "rms_over_noise": 40.0, "correlates_with": []}
    d = SimpleNamespace(effects=[], rounds=[], unexplained=[off], located=[], fit_before={}, fit_after={},
                        prior=vessel_mod.load("yellowfish"), windows={"length_s": 10.0, "windows": 90})
    assert "(RMS 5.73 °/s)" in answer(d)["form"][0] and "explains it on held-out blocks" in answer(d)["form"][0]
    # too few blocks for any effect to earn its place: the line does not say one was tested and failed
    few = SimpleNamespace(**{**vars(d), "windows": {"length_s": 10.0, "windows": 10}})
    assert "no effect of the library can be shown to explain it" in answer(few)["form"][0]


def test_the_answer_says_a_kinematic_finding_is_in_both_sides_of_what_it_changes():
    """A heading latency told from the kinematics is read into the logs before any fit: the held-out
    R² before and after are the same, and the answer says why rather than seeming to name a no-op."""
    from types import SimpleNamespace

    from twin.diagnose.report import answer

    told = {"name": "heading_latency", "kind": "kinematic", "parameters": {"latency_s": 0.16}, "ci": {},
            "rivals": [], "evidence": {"why": "the heading answers steps late", "basis": "input steps"}}
    fit = {k: {"r2": 0.9, "mae": 0.1} for k in "uvr"}
    d = SimpleNamespace(effects=[told], rounds=[], unexplained=[], located=[], fit_before=fit, fit_after=fit,
                        prior=vessel_mod.load("blueboat"), windows={"length_s": 10.0, "windows": 90})
    changes = answer(d)["changes"]
    assert changes.startswith("held-out R² u 0.900 → 0.900") and "both sides carry it" in changes
    assert "nothing of the dynamics was named" in changes
    # a named effect that leaves one velocity worse on the held-out blocks is said so
    worse = {**fit, "u": {"r2": 0.92, "mae": 0.1}}
    before = {**fit, "u": {"r2": 0.955, "mae": 0.1}}
    named = {**told, "kind": "dynamic", "name": "reverse_thrust", "z": 3.4, "excess_gain": 0.2}
    changes = answer(SimpleNamespace(**{**vars(d), "effects": [named], "fit_before": before, "fit_after": worse}))
    assert "u worse with it" in changes["changes"] and "both sides" not in changes["changes"]


def test_a_rival_the_blocks_prefer_is_reported_as_preferred_not_as_inseparable():
    """Seed 23's tidal current: compass_deviation kept, current preferred by the blocks (z 4.3 between
    the two) but short of its own place; the answer must not say the two cannot be told apart."""
    from types import SimpleNamespace

    from twin.diagnose.report import answer

    rival = {"name": "current", "z": -4.3, "separable": False, "held_out_gain": 0.2, "parameters": {}}
    close = {"name": "wind_shape", "z": -1.2, "separable": False, "held_out_gain": 0.2, "parameters": {}}
    kept = {"name": "compass_deviation", "parameters": {"b_deg": 1.0}, "ci": {}, "z": 3.4, "excess_gain": 0.2,
            "evidence": {"blocks_for": 12, "blocks_against": 1}, "rivals": [rival, close]}
    fit = {k: {"r2": 0.5} for k in "uvr"}
    d = SimpleNamespace(effects=[kept], rounds=[], unexplained=[], located=[], fit_before=fit, fit_after=fit,
                        prior=vessel_mod.load("yellowfish"), windows={"length_s": 10.0, "windows": 90})
    unsettled = answer(d)["unsettled"]
    assert any(u.startswith("compass_deviation or current: the blocks prefer current (z 4.3") and
               "may stand in for it" in u for u in unsettled)
    assert any(u.startswith("compass_deviation or wind_shape: this recording cannot tell them apart") for u in unsettled)
    # a compass that follows the throttle against a fixed deviation: what settles either is recorded next
    motor = {**kept, "name": "compass_motor", "rivals": [{**close, "name": "compass_deviation", "z": 1.3}]}
    nxt = answer(SimpleNamespace(**{**vars(d), "effects": [motor]}))["next"]
    assert [line.split(":")[0] for line in nxt] == ["to settle compass effects", "to settle drift effects"]


def test_how_much_more_to_record_for_a_hint():
    from twin.diagnose.verdict import more_recording_factor

    def c(z, n_for, n_against):
        return {"z": z, "blocks_for": n_for, "blocks_against": n_against}

    assert more_recording_factor(c(1.53, 4, 0)) == pytest.approx(2.5)  # ten unanimous blocks: exact z 3.1
    assert more_recording_factor(c(2.67, 16, 2)) == pytest.approx((3 / 2.67) ** 2)  # z ∝ √blocks
    assert more_recording_factor(c(2.5, 5, 1)) == pytest.approx(10 / 6)  # never fewer than ten blocks
    assert more_recording_factor(c(-0.4, 5, 6)) is None and more_recording_factor(c(0.0, 0, 0)) is None


def test_refitting_the_core_recovers_an_effect_beside_an_untuned_coefficient(prior):
    """The truth's yaw damping is half the prior's and its hull has a speed coupling. Fitted against the
    prior's yaw damping, the coupling takes the wrong values (N_uv stands in for the damping too); with
    the yaw group refitted beside it (search.py, CORE; beliefs worth a tenth of a window each, as little
    data as this) both come back: the coupling within 3-4 N s²/m, N_r within 15 %."""
    from twin.diagnose.doctor import _core

    ds = generate(prior, effects=["linear_damping=Nr:0.5", "speed_coupling=15,-5"], n_segments=4, seed=2,
                  noise=PROFILES["none"], segment_s=(35, 40), manoeuvres=MIXED)
    cv = compile_vessel(prior)
    preps = [prepare_for(ds.recording, cv, **PREP)]
    library = candidates(prior)
    core, names, start = _core(prior, ("yaw",))
    assert names == ["Nr", "Nrr", "Nrdot"] and start is prior
    results = {}
    for label, c in (("held", None), ("refitted", core)):
        search = Search(prior, Measurements(preps, [ds.recording], cv, PREP),
                        make_windows(preps, 10.0, 10.0, min_length_s=10.0), ModelCache(0.05),
                        {"speed_coupling": library["speed_coupling"]}, np.array([0.02, 0.02, 0.005]), core=c,
                        core_weight=0.1)
        base = search.fold_bases([], [])[0]
        cand = search.library["speed_coupling"]
        results[label] = search.refine(base, min(search.screen(base, cand), key=lambda f: f.train_cost))
    held, refitted = results["held"].values, results["refitted"].values
    assert abs(refitted["Yur"] - 15) < 3 and abs(refitted["Nuv"] + 5) < 4, refitted
    assert abs(held["Yur"] - 15) > 4 and abs(held["Nuv"] + 5) > 6, held  # without the core it cannot
    assert results["refitted"].vessel.damping.Nr == pytest.approx(0.5 * prior.damping.Nr, rel=0.15)


def test_what_the_core_already_does_is_not_offered_beside_it():
    """A damping scale, the thrust's overall gain, its lag, the reverse curve and the added masses are
    moved by the BlueBoat's core groups (the core's refit would write over them); one thruster's gain, a
    coupling or a current are not."""
    from twin.diagnose.doctor import _core
    from twin.diagnose.search import _moves_core

    boat = vessel_mod.load("blueboat")
    core, _, start = _core(boat, ("surge", "yaw", "sway", "thrust curve"))
    lib = candidates(start)
    moved = {n for n, c in lib.items() if _moves_core(c, core, start)}
    assert moved == {"thruster_lag", "thrust_gain", "reverse_thrust", "quadratic_damping", "linear_damping",
                     "surge_resistance", "added_mass"}
    assert start.thrusters.lag_s == pytest.approx(0.1)  # a refitted lag needs a start (simfit.map_start)
    with pytest.raises(TwinError, match="unknown group"):
        _core(boat, ("yaw", "hull"))


def test_diagnose_command_refits_the_core_with_each_candidate(tmp_path, prior):
    """`--refit yaw`: the untuned yaw damping (the truth's is 0.6 of the prior's) refitted beside a concealed
    current; the current is named, the amended twin carries the refitted N_r, the JSON says what was
    refitted, and a group the vessel does not have is one line of error."""
    ds = generate(prior, effects=["linear_damping=Nr:0.6", "current=0.2,120"], n_segments=6, seed=5,
                  noise=PROFILES["realistic"])
    rec = tmp_path / "run.tlog"
    write_recording(ds.recording, rec)
    out, amended = tmp_path / "d.json", tmp_path / "amended.json"
    base = ["diagnose", str(rec), "--vessel", "yellowfish"]
    done = twin_command.twin(*(base + ["--refit", "yaw", "--refit-weight", "0.1", "--effects", "current,speed_coupling",
                             "--json", str(out), "--write-model", str(amended)]))
    assert done.returncode == 0, done.stderr
    d = json.loads(out.read_text())
    assert d["refit"]["coefficients"] == ["Nr", "Nrr", "Nrdot"] and d["refit"]["beliefs_weight"] == 0.1
    assert [e["name"] for e in d["effects"]] == ["current"]
    assert abs(d["effects"][0]["parameters"]["dir_deg"] - 120) < 10
    assert vessel_mod.load(str(amended)).damping.Nr == pytest.approx(0.6 * prior.damping.Nr, rel=0.2)
    bad = twin_command.twin(*(base + ["--refit", "hull"]))
    assert bad.returncode == 2 and bad.stderr.startswith("error:") and len(bad.stderr.strip().splitlines()) == 1
    assert "unknown group" in bad.stderr


def test_an_effect_kept_before_the_one_that_supersedes_it_goes():
    """wind_shape kept first, then each log's own wind: the constant wind would act on no log, so it
    is dropped (search.without_superseded); an effect the winner does not supersede stays."""
    from twin.diagnose.search import Evidence, Kept, Trial, without_superseded
    from twin.effects.spec import Candidate

    def trial(name, supersedes=()):
        cand = Candidate(name, (), ((),), lambda p: None, "environment", supersedes=tuple(supersedes))
        return Trial(cand, [], Evidence(4.0, 0.2, 0.2, {}, 5, 0, 5))

    kept = [Kept(trial("wind_shape"), []), Kept(trial("current"), [])]
    winner = trial("wind_per_log", ("wind", "wind_shape"))
    left, gone = without_superseded(kept + [Kept(winner, [])], winner)
    assert [k.trial.name for k in left] == ["current", "wind_per_log"] and gone == {"wind_shape"}
    assert without_superseded(kept, trial("current"))[1] == set()


def test_the_rival_the_blocks_prefer_is_kept_when_it_earns_its_place_too():
    """Two effects explaining the same misfit: the larger pooled gain is kept unless the blocks lean to
    the rival (head-to-head z ≤ −1.5) and the rival earns its place itself; the most preferred wins."""
    from twin.diagnose.search import Evidence, Search, Trial
    from twin.effects.spec import Candidate

    def trial(name, z, rel):
        return Trial(Candidate(name, (), ((),), lambda p: None, "drag"), [], Evidence(z, rel, rel, {}, 10, 0, 10))

    winner, stand_in, weak, leaning_more = (trial("thrust_speed_loss", 5.0, 0.30), trial("quadratic_damping", 4.8, 0.29),
                                            trial("linear_damping", 2.0, 0.29), trial("speed_damping", 4.0, 0.28))
    trials = [winner, stand_in, weak, leaning_more]
    rivals = [{"name": "quadratic_damping", "z": -1.8, "separable": False},
              {"name": "linear_damping", "z": -2.5, "separable": False},
              {"name": "speed_damping", "z": -1.4, "separable": False}]
    assert Search._preferred(winner, trials, rivals) is stand_in  # linear_damping leans more but does not earn
    rivals[2]["z"] = -2.2
    assert Search._preferred(winner, trials, rivals) is leaning_more
    assert Search._preferred(winner, trials, [{"name": "quadratic_damping", "z": -1.2, "separable": False}]) is winner
    assert Search._preferred(winner, trials, []) is winner


def test_where_the_blocks_lean_to_neither_the_rival_with_fewer_quantities_is_kept():
    """A three-scale damping with the larger pooled gain against a one-quantity thrust scale the blocks
    cannot tell from it (|z| < 1.5): the thrust scale is kept; not where the blocks lean to the damping
    (z ≥ 1.5), nor where the thrust scale does not earn its place, nor where it is told apart."""
    from twin.diagnose.search import Evidence, Search, Trial
    from twin.effects.spec import Candidate

    def trial(name, n, z, rel):
        return Trial(Candidate(name, tuple(f"q{i}" for i in range(n)), ((0.0,) * n,), lambda p: None, "drag"), [],
                     Evidence(z, rel, rel, {}, 10, 0, 10))

    damping, scale, two = trial("linear_damping", 3, 5.7, 0.55), trial("thrust_gain", 1, 7.0, 0.42), \
        trial("surge_resistance", 2, 6.0, 0.50)
    trials = [damping, scale, two]

    def rivals(z_scale, z_two=0.5, separable=False):
        return [{"name": "thrust_gain", "z": z_scale, "separable": separable},
                {"name": "surge_resistance", "z": z_two, "separable": False}]

    assert Search._preferred(damping, trials, rivals(0.14)) is scale  # the fewest, not merely fewer
    assert Search._preferred(damping, trials, rivals(-1.4)) is scale
    assert Search._preferred(damping, trials, rivals(1.6)) is two  # the blocks lean away from the scale
    assert Search._preferred(damping, trials, rivals(1.6, 1.6)) is damping
    assert Search._preferred(damping, trials, rivals(3.5, 1.6, separable=True)) is damping
    weak = [damping, trial("thrust_gain", 1, 2.5, 0.42)]
    assert Search._preferred(damping, weak, rivals(0.1)[:1]) is damping
    assert Search._preferred(scale, trials, [{"name": "linear_damping", "z": -0.3, "separable": False}]) is scale


def test_a_window_votes_when_its_residuals_move_by_half_a_noise_sigma():
    """Residuals in each DOF's own noise units: a window votes when the change's RMS over its samples
    of u, v and r passes 0.5, whatever the DOFs' noise in the fit's scale (a sway noise 100 times
    the others' there no longer sets the bar for surge and yaw). A surge change of 0.6 σ over a third
    of the samples (RMS 0.35) does not vote; one of 1 σ (RMS 0.58) does; a lost sample always does."""
    from twin.diagnose.search import _moved
    rng = np.random.default_rng(4)
    base = rng.normal(size=300)
    dof = np.repeat([0, 1, 2], 100)
    for noise_var in (np.ones(3), np.array([1.0, 100.0, 1.0]), np.array([0.0025, 0.48, 0.0012])):
        small = base.copy()
        small[:100] += 0.6
        assert not _moved(base, small, dof, noise_var)
        large = base.copy()
        large[:100] += 1.0
        assert _moved(base, large, dof, noise_var)
        # a 20 % thrust asymmetry on a library BlueBoat log: u moved by 3 σ and r by 2 σ, v by 0.1 σ
        asymmetry = base + np.select([dof == 0, dof == 1], [3.0, 0.1], 2.0)
        assert _moved(base, asymmetry, dof, noise_var)
        assert _moved(base, base[:-1], dof, noise_var)


def test_fit_on_an_unphysical_edge_is_not_named():
    """Added yaw inertia ×20 on every fold (a thruster's slow response read as inertia) does not
    earn its place whatever its z; on one fold only, or a time shift at its range end, it may."""
    from twin.diagnose.search import Evidence, Fitted, at_unphysical_edge
    prior = vessel_mod.load("yellowfish")
    lib = candidates(prior)
    am = lib["added_mass"]
    fitted = lambda values: Fitted(am, values, prior, 0.0)  # noqa: E731
    edge = {"Xudot_scale": 1.3, "Yvdot_scale": 1.0, "Nrdot_scale": 20.0}
    inside = dict(edge, Nrdot_scale=19.0)
    assert at_unphysical_edge(am, [fitted(edge)] * 3) == ["Nrdot_scale"]
    assert at_unphysical_edge(am, [fitted(edge), fitted(inside), fitted(edge)]) == []
    low = dict(inside, Xudot_scale=0.05)
    assert at_unphysical_edge(am, [fitted(low)] * 3) == ["Xudot_scale"]
    delay = lib["input_delay"]
    hi = delay.params[0].hi
    assert at_unphysical_edge(delay, [Fitted(delay, {delay.names[0]: hi}, prior, 0.0)] * 3) == []
    strong = Evidence(6.0, 0.3, 0.4, {}, 20, 0, 40)
    assert strong.earns_its_place()
    strong.at_edge = ["Nrdot_scale"]
    assert not strong.earns_its_place()


def test_a_wind_shape_pushing_harder_than_a_flat_plate_is_not_named():
    """A wind's side-force coefficient per lateral area ends on an unphysical edge at a 2-D flat
    plate's 2.0 and at none (a current's drift read as a light wind on a superstructure pushing
    several times harder than a plate, as fitted at c_y 4.5): such a fit says the form is off. A
    c_y of 1.9, or the shipped 0.8, is a wind's."""
    from twin.diagnose.search import Fitted, at_unphysical_edge
    prior = vessel_mod.load("blueboat")
    shape = candidates(prior)["wind_shape"]
    cy = next(q for q in shape.params if q.name == "cy")
    assert (cy.lo, cy.hi, cy.edges_unphysical) == (0.0, 2.0, True)
    fitted = lambda cy_value: Fitted(shape, {"speed_m_s": 2.0, "dir_deg": 60.0, "cy": cy_value, "cn": -0.4},  # noqa: E731
                                     prior, 0.0)
    assert at_unphysical_edge(shape, [fitted(2.0)] * 3) == ["cy"]
    assert at_unphysical_edge(shape, [fitted(0.0), fitted(1e-4), fitted(0.0)]) == ["cy"]
    assert at_unphysical_edge(shape, [fitted(1.9)] * 3) == []
    assert at_unphysical_edge(shape, [fitted(2.0), fitted(0.8), fitted(2.0)]) == []
    # a vessel file that gives its superstructure more keeps its own value inside the range
    broad = replace(prior, wind_load=replace(prior.wind_load, cy=2.6))
    assert next(q for q in candidates(broad)["wind_shape"].params if q.name == "cy").hi == 2.6
    with pytest.raises(TwinError):
        as_effect("wind_shape=3,90,-0.5,0.1")  # a side force against the wind's


def test_a_recording_too_short_for_any_dynamic_finding_says_so():
    """Seven blocks, every one for a candidate, reach z 2.4 at best in the exact signed-rank test: the
    answer says that nothing can be named from the dynamics and how much more to record, not that
    no effect earns its place."""
    from types import SimpleNamespace

    from twin.diagnose.report import answer
    from twin.diagnose.search import _signed_rank_z

    assert _signed_rank_z(np.full(9, 0.2)) < 3.0 <= _signed_rank_z(np.full(10, 0.2))
    # every block against is as sure as every block for, the other way, and no surer: five blocks
    # cannot contradict an effect any more than they can prove it
    for n in (5, 7, 12):
        assert _signed_rank_z(np.full(n, -0.2)) == pytest.approx(-_signed_rank_z(np.full(n, 0.2)), abs=1e-9)
    assert -3.0 < _signed_rank_z(np.full(5, -0.2)) < -1.8
    mixed = np.array([0.3, -0.1, 0.2, 0.25, -0.05, 0.4, 0.15])
    assert _signed_rank_z(-mixed) == pytest.approx(-_signed_rank_z(mixed), abs=1e-9)
    d = SimpleNamespace(effects=[], rounds=[], unexplained=[], located=[], fit_before={}, fit_after={},
                        prior=vessel_mod.load("yellowfish"), windows={"length_s": 10.0, "windows": 20, "blocks": 7})
    (line,) = answer(d)["missing"]
    assert line.startswith("nothing can be named from the dynamics with 7 blocks of 30 s")
    assert "at least 1.5 min more" in line
    ev = {"blocks_for": 6, "blocks_against": 1}
    named = {"name": "current", "parameters": {"speed_m_s": 0.1}, "ci": {}, "evidence": ev, "z": 3.2, "rivals": [],
             "excess_gain": 0.3}
    d.windows, d.effects = {"length_s": 5.0, "windows": 40, "blocks": 14}, [named]
    d.fit_before = d.fit_after = {k: {"r2": 0.5, "mae": 0.1} for k in "uvr"}
    assert "over 7 blocks of 15 s (6 for, 1 against)" in answer(d)["missing"][0]  # blocks of the windows given


def test_the_report_says_the_form_is_off_where_an_edge_fit_was_refused():
    from types import SimpleNamespace

    from twin.diagnose.report import answer
    edge = {"name": "added_mass", "z": 3.61, "excess_gain": 0.199, "blocks_for": 14, "blocks_against": 2,
            "affected_windows": 27, "at_edge": ["Nrdot_scale"],
            "fold_values": [{"Nrdot_scale": 20.0}, {"Nrdot_scale": 20.0}, {"Nrdot_scale": 19.99}]}
    d = SimpleNamespace(effects=[], rounds=[{"candidates": [edge]}], unexplained=[], located=[], fit_before={},
                        fit_after={}, prior=vessel_mod.load("yellowfish"), windows={"length_s": 10.0, "windows": 70})
    a = answer(d)
    assert a["missing"][0].startswith("no effect of the library earns its place")
    form = [f for f in a["form"] if f.startswith("added_mass")]
    assert len(form) == 1 and "Nrdot_scale 20" in form[0] and "20 %" in form[0]
    assert not any("added_mass may be missing" in u for u in a["unsettled"])


def test_a_twins_own_noise_free_run_is_not_read_as_the_twins_form():
    # against the raw prediction and the white noise alone (≈ 0 here) the smoothing of the measured
    # velocities and the input log's 0.1-s sampling read as u, v, r 27-57× the noise off
    boat = vessel_mod.load("blueboat")
    ds = generate(boat, n_segments=6, seed=8, noise=PROFILES["none"])
    d = diagnose([ds.recording], boat, library=["current"])  # the replay and its floor: no search needed
    over = {dof: o["rms_over_noise"] for dof, o in d.overall["before"].items()}
    # the first second, where the run starts from the estimator's smoothed state, read as v 3.1×
    assert max(over.values()) < 2.0, over
    assert d.noise["replay_u"] > 3 * d.noise["u"] and d.noise["input_period_s"] > 0
    assert not d.unexplained
    assert d.overall["before"]["v"]["n"] < 0.9 * 3600  # the judged span leaves out each window's edges


def test_a_misfit_below_any_sensors_resolution_is_not_the_twins_form():
    """On a noise-free log the estimated noise is zero and any misfit is many times it: a residual
    of 0.6 mm/s (the replay's own arithmetic) is not reported as the twin's form; 1 cm/s is."""
    from twin.diagnose.doctor import _unexplained

    def overall(rms):
        return {"v": {"n": 100, "rms": rms, "bias": 0.0, "rms_over_noise": 4.0, "z_bias": 0.5}}
    assert _unexplained([], {}, overall(0.000625)) == []
    assert [u["dof"] for u in _unexplained([], {}, overall(0.01))] == ["v"]


def test_the_best_earth_fixed_candidate_is_judged_beside_the_leading_hull_terms():
    """Screening ranks hull and thrust terms first when they take up a twin's form error; the best
    current or wind is judged beside the first three, until an earth-fixed effect is kept. The rank
    is the cost on held-out windows (screen_cost), here the reverse of the cost on those fitted."""
    from types import SimpleNamespace

    import twin.diagnose.search as search

    order = ["speed_damping", "speed_coupling", "full_thrust", "thrust_gain", "added_mass", "quadratic_damping",
             "linear_damping", "thruster_lag", "input_delay", "current", "wind"]
    s = search.Search.__new__(search.Search)
    s.library = {name: SimpleNamespace(name=name) for name in order}
    s.screen = lambda base, cand: [SimpleNamespace(candidate=SimpleNamespace(name=cand.name, log_of_param=()),
                                                   train_cost=-order.index(cand.name), screen_cost=order.index(cand.name))]
    s.trial = lambda bases, costs, f: SimpleNamespace(
        name=f.candidate.name, evidence=SimpleNamespace(earns_its_place=lambda: False, rel_excess=0.0))
    s.log = lambda text: None
    assert len(order) > search.JUDGED_WHOLE
    judged = {t.name for t in s.round([None], None, set())}
    assert judged == {"speed_damping", "speed_coupling", "full_thrust", "current"}
    assert {t.name for t in s.round([None], None, set(), earth_slot=False)} == set(order[:3])
    assert {t.name for t in s.round([None], None, {"current"})} == set(order[:3]) | {"wind"}


def test_screening_ranks_on_windows_its_step_did_not_fit(prior):
    """On a recording with nothing in it, every candidate's screening steps lower the cost of the
    windows it fitted (it takes up noise); on the first
    fold's held-out windows the same steps gain nothing: the ranking follows what carries to data
    the step did not see."""
    ds = generate(prior, effects=[], n_segments=3, seed=2, segment_s=(35, 40), manoeuvres=MIXED)
    cv = compile_vessel(prior)
    search = make_search(prior, [prepare_for(ds.recording, cv, **PREP)], [ds.recording], cv, candidates(prior))
    assert not {id(w) for w in search.screening} & {id(w) for w in search.screening_held}
    screened = [min(search.screen(prior, c), key=lambda f: f.train_cost) for c in search.library.values()
                if not c.scan and not c.log_of_param and len(c.params) <= 2]
    fitted = np.array([f.train_cost for f in screened])
    held = np.array([f.screen_cost for f in screened])
    assert np.median(fitted) < 0.998 and np.median(held) > 1.0
    leader = screened[int(np.argmin(fitted))]
    assert leader.train_cost < 0.9 and leader.screen_cost > 1.05  # a heading bias fitted to noise


def test_screening_reaches_a_large_thrust_loss_with_speed_and_ranks_it_first():
    """A free run's answer to a thrust loss with speed of 3.2 is far from linear in it: screened by
    two Gauss-Newton steps it leads the constant thrust scale and the drag terms that stand in for
    it, on the windows the steps fitted and on those they did not."""
    prior = vessel_mod.load("blueboat")
    ds = generate(prior, effects=["thrust_speed_loss=3.2"], n_segments=4, seed=431, manoeuvres=MIXED)
    cv = compile_vessel(prior)
    search = make_search(prior, [prepare_for(ds.recording, cv, **PREP)], [ds.recording], cv, candidates(prior))
    names = ("thrust_speed_loss", "thrust_gain", "quadratic_damping", "surge_resistance", "linear_damping")
    screened = {n: min(search.screen(prior, search.library[n]), key=lambda f: f.train_cost) for n in names}
    assert min(screened, key=lambda n: screened[n].screen_cost) == "thrust_speed_loss"
    assert min(screened, key=lambda n: screened[n].train_cost) == "thrust_speed_loss"
    assert screened["thrust_speed_loss"].values["advance_loss"] == pytest.approx(3.2, rel=0.3)


def test_a_thrust_scale_kept_for_its_fewer_quantities_is_checked_for_a_loss_with_speed():
    """A linear damping (three quantities) wins a round; a constant thrust scale the blocks cannot
    tell from it is kept for its single quantity, and then, wanting less thrust the faster the boat
    goes on every fold, gives way to the loss with speed as a round's winner would."""
    from twin.diagnose.search import Evidence, Search, Trial
    from twin.effects.spec import Candidate

    def trial(name, n, rel):
        return Trial(Candidate(name, tuple(f"q{i}" for i in range(n)), ((0.0,) * n,), lambda p: None, "drag"), [],
                     Evidence(5.0, rel, rel, {}, 10, 0, 10))

    damping, scale, loss = trial("linear_damping", 3, 0.55), trial("thrust_gain", 1, 0.42), trial("thrust_speed_loss", 1, 0.40)
    z = {("linear_damping", "thrust_gain"): 0.14, ("linear_damping", "thrust_speed_loss"): 0.3,
         ("thrust_gain", "linear_damping"): -0.14, ("thrust_gain", "thrust_speed_loss"): 0.5,
         ("thrust_speed_loss", "linear_damping"): -0.3, ("thrust_speed_loss", "thrust_gain"): -0.5}
    search = Search.__new__(Search)
    search.log = lambda text: None
    search._rivals = lambda winner, trials, costs: [{"name": t.name, "z": z[winner.name, t.name], "separable": False}
                                                    for t in trials if t is not winner]
    for falls, kept in ((True, "thrust_speed_loss"), (False, "thrust_gain")):
        search.grows_with_speed = lambda t, bases, falls=falls: [(1.0, 0.7)] * 3 if falls else None
        winner, rivals = search._choose(damping, [damping, scale, loss], [None] * 3, None)
        assert winner.name == kept and {r["name"] for r in rivals} == {"linear_damping", "thrust_gain",
                                                                        "thrust_speed_loss"} - {kept}


def test_screening_judges_every_log_on_windows_of_its_own():
    """A short log among long ones: a stride over all held-out windows together can step over it,
    and a wind of that log's own would then be judged on none of its windows."""
    from twin.diagnose.search import _spread, _spread_per_log

    windows = [Window(rec, 10 * k, 100) for rec, n in enumerate((31, 1, 30, 1, 31)) for k in range(n)]
    assert {w.rec for w in _spread(windows, 32)} != set(range(5))
    spread = _spread_per_log(windows, 32)
    assert {w.rec for w in spread} == set(range(5)) and len(spread) <= 36
    assert all(len([w for w in spread if w.rec == r]) >= 10 for r in (0, 2, 4))


def test_a_given_effect_every_block_votes_against_is_said_to_be_opposed_where_too_few_blocks_contradict_it():
    """Seven blocks all against reach z −2.42 only (the exact test: p = 2⁻⁷): the answer says every block
    votes against it and how many blocks calling it contradicted takes; a split vote keeps the plain words."""
    from twin.diagnose.report import given_text
    from twin.diagnose.search import Evidence, _signed_rank_z

    votes = -np.linspace(0.1, 0.7, 7)
    z = _signed_rank_z(votes)
    assert z == pytest.approx(-2.418, abs=0.01)
    opposed = Evidence(z, -6.7, -8.0, {"u": 0.2, "v": -7.6, "r": -0.01}, 0, 7, 70, votes)
    text = given_text(["current=0.1,90"], opposed)
    assert "every block votes against it" in text and "10 blocks or more" in text and "contradicted by" not in text
    split = Evidence(-1.0, -0.1, -0.2, {"u": 0.0, "v": -0.1, "r": 0.0}, 2, 5, 70)
    assert "cannot prove it at these values" in given_text(["current=0.1,90"], split)
