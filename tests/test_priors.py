"""First-principles priors (physics/priors.py, verify/priors.py), splits where the judged runs lie
beyond the fitted ones (fit/extrapolation.py, crossval.beyond_folds), the twin's error on left-out
runs and the band it widens (crossval.form_error, scale.montecarlo), and the MMG resistance that
follows the friction line."""
import json
from dataclasses import replace

import numpy as np
import pytest
import trimesh

import twin.vessel as vessel_mod
from twin.fit.crossval import beyond_folds, form_error_at
from twin.fit.extrapolation import (activities, activity_order, by_activity, by_day, by_family, by_input_level,
                                    low_input_stretches)
from twin.fit.windows import make_windows
from twin.physics import mmg
from twin.physics.priors import (cross_flow_drag, ittc57_cf, lateral_profile, propulsor_at_rest, propulsor_lateral,
                                 resistance_curve, slender_hull_derivatives, twin_hull_yaw,
                                 without_added_mass_coriolis)
from twin.prepare.prepared import prepared_from_run
from twin.recording import Recording, Stream, within
from twin.run import Run
from twin.physics.thrusters import t200_voltage_gain
from twin.scale.montecarlo import _widened
from twin.verify.priors import first_principles


def test_ittc57_line_and_a_resistance_curve_that_holds_its_top_speed():
    assert ittc57_cf(1e6) == pytest.approx(0.075 / 16.0)
    assert ittc57_cf(1e7) < ittc57_cf(1e6)  # friction falls with the Reynolds number
    curve = resistance_curve(0.5, 1.0, 1.2, 3.0, 30.0)
    assert curve.resistance_n(3.0) == pytest.approx(30.0, rel=1e-9)
    u = np.linspace(0.3, 3.0, 10)
    fitted = -curve.xu * u - curve.xuu * u * u
    assert np.max(np.abs(fitted - curve.resistance_n(u))) < 0.03 * 30.0
    # a top speed friction alone cannot hold leaves no negative residuary part
    assert resistance_curve(0.5, 1.0, 1.2, 3.0, 0.1).residuary_cr == 0.0
    # at rest the line's floor keeps C_F finite: no resistance, not NaN (Re 0 below the line's domain)
    assert curve.resistance_n(0.0) == 0.0 and np.isfinite(ittc57_cf(0.0))


def test_slender_hull_derivatives_reduce_to_the_flat_plate_and_lose_their_ideal_fluid_parts():
    # B → 0: Y'_v = −π(T/L)², N'_r = −π(T/L)²/4, Y'_r = +π(T/L)²/2 (Clarke's regressions at zero beam)
    d = slender_hull_derivatives(1.0, 1e-9, 0.1, 0.7, rho_kg_m3=2.0)  # ½ρ = 1
    k = np.pi * 0.01
    assert (d.Yuv, d.Nur, d.Yur) == pytest.approx((-k, -0.25 * k, 0.5 * k), rel=1e-6)
    x = without_added_mass_coriolis(d, xudot=-1.0, yvdot=-5.0)
    assert x.Yur == pytest.approx(d.Yur + 1.0) and x.Nuv == pytest.approx(d.Nuv + 4.0)
    assert (x.Yuv, x.Nur) == (d.Yuv, d.Nur)


def test_a_thruster_astern_damps_yaw_and_couples_sway_as_a_fin_at_its_site():
    p = propulsor_lateral(-0.5, 0.1, 0.08, rho_kg_m3=1000.0)
    c = 1000.0 * np.pi / 4 * (0.01 + 0.0064)
    assert (p.Yuv, p.Yur, p.Nuv, p.Nur) == pytest.approx((-c, 0.5 * c, 0.5 * c, -0.25 * c))
    yv, yr, nv, nr = propulsor_at_rest(-0.5, 0.08, 20.0)
    area = np.pi * 0.0016
    mdot = 1000.0 * area * np.sqrt(20.0 / (2000.0 * area))
    assert (yv, nr) == pytest.approx((-mdot, -0.25 * mdot)) and yr == nv == pytest.approx(0.5 * mdot)
    assert propulsor_at_rest(-0.5, 0.08, 0.0) == (0.0, 0.0, 0.0, 0.0)  # no thrust, no flow


def test_cross_flow_drag_of_a_box_and_its_profile_from_a_mesh():
    box = trimesh.creation.box(extents=(2.0, 0.4, 0.3))  # x ±1 m, z ±0.15 m; waterline z = 0.05: draft 0.1 m
    x, t = lateral_profile(np.asarray(box.vertices), np.asarray(box.faces), 0.05, stations=40)
    inner = (np.abs(x) < 0.99)
    assert np.allclose(t[inner], 0.1, atol=1e-9)
    yvv, nrr = cross_flow_drag(np.array([-1.0, 1.0]), np.array([0.1, 0.1]), 1.0, rho_kg_m3=1000.0)
    assert yvv == pytest.approx(-500.0 * 0.1 * 2.0)
    x = np.linspace(-1, 1, 2001)
    assert cross_flow_drag(x, np.full_like(x, 0.1), 1.0)[1] == pytest.approx(-500.0 * 0.1 * 2 * 0.25, rel=1e-4)
    assert twin_hull_yaw(0.3, -2.0, -5.0) == pytest.approx((-0.18, -0.9))


def test_the_shipped_blueboat_prior_is_its_first_principles_estimate():
    v = vessel_mod.load("blueboat")
    fp = first_principles(v)
    for name, value in fp.values().items():
        if name.endswith("dot"):
            assert getattr(v.added_mass, name) == pytest.approx(value, rel=1e-3), name
            continue
        held = getattr(v.thrusters if name.startswith("gain") else v.damping, name)
        assert held == pytest.approx(value, rel=1e-3, abs=1e-3), name
    assert fp.values()["gain_left"] == pytest.approx(t200_voltage_gain(14.8)) == pytest.approx(1.605, abs=1e-3)
    h = fp.hulls[0]
    assert 0.9 < h.length_m < 1.0 and 0.05 < h.draft_m < 0.07 and 0.45 < h.block_coefficient < 0.6
    assert [round(x.y_m, 3) for x in fp.hulls] == [-0.285, 0.285]
    assert fp.values()["Nur"] < 0 and fp.values()["Yuv"] < 0  # yaw and sway damping grow with the speed
    assert "Clarke-1983" in fp.table() and "ITTC-1957" in fp.table()


def test_the_t200_gain_follows_the_published_thrust_by_voltage():
    assert t200_voltage_gain(10.0) == 1.0
    assert t200_voltage_gain(16.0) / t200_voltage_gain(12.0) == pytest.approx(5.25 / 3.71)
    assert t200_voltage_gain(20.0) / t200_voltage_gain(16.0) == pytest.approx(6.70 / 5.25)


def test_a_first_principles_estimate_needs_a_design_block():
    from twin.errors import TwinError

    with pytest.raises(TwinError, match="design block"):
        first_principles(vessel_mod.load("yellowfish"))


def _run(drive: float, turn: float, seconds: float = 60.0, seed: int = 0) -> Run:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 0.1)
    on = rng.random(len(t)) < drive
    pwm = np.where(on[:, None], 1700.0, 1500.0) * np.ones((len(t), 2))
    r = np.where(rng.random(len(t)) < turn, 0.5, 0.01)
    nu = np.column_stack([np.where(on, 1.0, 0.0), np.zeros(len(t)), r])
    eta = np.column_stack([np.cumsum(nu[:, 0]) * 0.1, np.zeros(len(t)), np.cumsum(r) * 0.1])
    return Run(t, eta, nu, pwm, np.zeros((len(t), 2)))


def _named(run: Run, name: str):
    p = prepared_from_run(run)
    return replace(p, settings=replace(p.settings, source=name))


def test_runs_are_ranked_by_time_under_way_and_turning():
    preps = [_named(_run(d, t, seed=i), f"run{i}.csv") for i, (d, t) in
             enumerate([(0.9, 0.5), (0.1, 0.05), (0.5, 0.2), (0.2, 0.1)])]
    acts = activities(preps)
    assert acts[1].under_way_share < acts[3].under_way_share < acts[2].under_way_share < acts[0].under_way_share
    assert activity_order(acts) == ["run1.csv", "run3.csv", "run2.csv", "run0.csv"]
    split = by_activity(preps, 2)
    assert split.fitted == ("run1.csv", "run3.csv") and split.judged == ("run2.csv", "run0.csv")
    fitted, judged = split.pick(preps, [f"run{i}.csv" for i in range(4)])
    assert [p.settings.source for p in judged] == ["run2.csv", "run0.csv"]
    # the twin predicting a run is fitted on the runs that go less far only
    windows = make_windows(preps, 10.0, 10.0, min_length_s=10.0)
    groups = np.array([w.rec for w in windows])
    folds = beyond_folds(windows, preps, groups)
    assert folds[1].tolist() == [0, 1, 2, 3] and folds[0].tolist() == [0] and set(folds[2]) == {0, 2}


def test_splits_by_input_level_and_by_family_and_their_refusals():
    from twin.errors import TwinError

    preps = [_named(_run(0.5, 0.1, seed=i), f"{fam}_{i}.csv") for i, fam in enumerate(["turn", "random", "turn"])]
    assert by_family([p.settings.source for p in preps], "random").judged == ("turn_0.csv", "turn_2.csv")
    preps[1] = replace(preps[1], pwm=1500.0 + 1.5 * (preps[1].pwm - 1500.0))  # 300 µs from neutral where others 200
    split = by_input_level(preps, 250.0)
    assert split.fitted == ("turn_0.csv", "turn_2.csv") and split.judged == ("random_1.csv",)
    with pytest.raises(TwinError, match="every run is on one side"):
        by_input_level(preps, 500.0)
    with pytest.raises(TwinError, match="at least two"):
        by_activity(preps[:1])
    days = ["turn_14-Sep-2020_1.csv", "turn_14-Oct-2020_2.csv", "random_14-Sep-2020_3.csv", "turn_cut_14-Sep-2020_4.csv"]
    split = by_day(days, "14-Sep-2020", family="turn")
    assert split.fitted == ("turn_14-Sep-2020_1.csv", "turn_cut_14-Sep-2020_4.csv")
    assert split.judged == ("turn_14-Oct-2020_2.csv",)  # another family's run is on neither side
    with pytest.raises(TwinError, match="every such run is on one side"):
        by_day(days, "31-Jul-2020", family="turn")


def test_slow_stretches_are_found_on_the_grid_and_cut_from_the_log():
    from twin.errors import TwinError

    run = _run(0.0, 0.1, seconds=120.0)
    pwm = np.full((len(run.t), 2), 1550.0)  # 50 µs from neutral
    pwm[(run.t >= 40.0) & (run.t < 45.0)] = 1800.0  # a burst of 300 µs
    pwm[run.t >= 100.0] = 1700.0
    prep = _named(replace(run, pwm_us=pwm), "slow.csv")
    got = low_input_stretches(prep, 100.0, 30.0)
    assert got == [pytest.approx((0.0, 39.9)), pytest.approx((45.0, 99.9))]
    assert low_input_stretches(prep, 100.0, 60.0) == []  # neither lasts a minute
    with pytest.raises(TwinError, match="more than 0 s"):
        low_input_stretches(prep, 100.0, 0.0)
    t = np.arange(0.0, 10.0, 0.5)
    rec = Recording("a/b.csv", "csv", heading=Stream(t, {"psi_rad": t * 0.1}), pwm=Stream(t[::2], {
        "left_us": t[::2], "right_us": t[::2]}))
    cut = within(rec, 2.0, 4.0, "a/b.csv#1")
    assert cut.heading.t.tolist() == [2.0, 2.5, 3.0, 3.5, 4.0] and cut.pwm.t.tolist() == [2.0, 3.0, 4.0]
    assert cut.heading["psi_rad"].tolist() == pytest.approx([0.2, 0.25, 0.3, 0.35, 0.4])
    assert cut.meta["stretch_of"] == "a/b.csv" and len(rec.heading) == 20  # the log itself is untouched
    with pytest.raises(TwinError, match="end after it starts"):
        within(rec, 4.0, 4.0, "x")


def test_form_error_interpolates_in_level_and_horizon_and_grows_a_position_beyond_it():
    block = {"horizon_s": [0.0, 10.0, 20.0], "levels": [0.5, 0.9],
             "quantiles": {"u": [[0.0, 0.0], [0.1, 0.3], [0.2, 0.5]], "north": [[0.0, 0.0], [0.5, 1.0], [1.0, 2.0]]}}
    assert form_error_at(block, "u", 0.7, np.array([10.0]))[0] == pytest.approx(0.2)
    # with 9 windows a 70 % level reads the ⌈10·0.7⌉/9 = 7/9 quantile (split conformal)
    assert form_error_at({**block, "windows": 9}, "u", 0.7, np.array([10.0]))[0] == pytest.approx(
        0.1 + 0.2 * (7 / 9 - 0.5) / 0.4)
    assert form_error_at(block, "u", 0.9, np.array([5.0, 40.0])) == pytest.approx([0.15, 0.5])  # a velocity holds
    assert form_error_at(block, "north", 0.9, np.array([30.0]))[0] == pytest.approx(3.0)  # a position grows on
    lo, hi = _widened(np.array([0.9]), np.array([1.3]), np.array([1.0]), np.array([0.4]), False)
    assert (lo[0], hi[0]) == pytest.approx((1.0 - np.hypot(0.1, 0.4), 1.0 + np.hypot(0.3, 0.4)))


def test_mmg_resistance_follows_the_friction_line_and_holds_at_its_reference_speed():
    v = vessel_mod.load("esso_osaka")
    assert v.mmg.friction_factor > 0
    constant = replace(v.mmg, friction_factor=0.0)

    def surge(m, u):
        return mmg.mmg_force(mmg.pack(m, -1.44, -1.5), u, 0.0, 0.0, 0.0, 0.0, True, False, False)[0]

    u_ref = v.mmg.reference_speed_m_s
    assert surge(v.mmg, u_ref) == pytest.approx(surge(constant, u_ref))
    fast, slow = 2.0 * u_ref, 0.4 * u_ref
    assert surge(v.mmg, fast) / surge(constant, fast) < 0.95 < 1.05 < surge(v.mmg, slow) / surge(constant, slow)
    f = v.mmg.friction_factor
    expected = (v.mmg.hull.R0 + f * (ittc57_cf(fast * 3.0 / 1e-6) - ittc57_cf(u_ref * 3.0 / 1e-6))) / v.mmg.hull.R0
    assert surge(v.mmg, fast) / surge(constant, fast) == pytest.approx(expected, rel=1e-9)
    saved = json.loads(json.dumps(replace(v, mmg=constant).to_dict()))
    assert "friction_factor" not in saved["mmg"]  # a constant R'_0 writes the file it always did


def test_a_resistance_below_its_friction_line_is_carried_in_proportion_to_it():
    """An R'_0 under F·C_F(U_ref) would leave a negative rest of the resistance: the line then carries
    it with F' = R'_0/C_F(U_ref), so the coefficient stays positive and above the additive line's at
    speed; an R'_0 above the line keeps the file's F."""
    v = vessel_mod.load("esso_osaka")
    u_ref, lnu = v.mmg.reference_speed_m_s, v.mmg.lpp_m / 1e-6
    cf_ref = ittc57_cf(u_ref * lnu)
    assert v.mmg.hull.R0 >= v.mmg.friction_factor * cf_ref  # the shipped prior: its F as the file gives it
    assert mmg.friction_line_factor(v.mmg) == v.mmg.friction_factor
    low = replace(v.mmg, hull=replace(v.mmg.hull, R0=0.4 * v.mmg.hull.R0))
    assert mmg.friction_line_factor(low) == pytest.approx(low.hull.R0 / cf_ref, rel=1e-12)

    def surge(m, u):
        return mmg.mmg_force(mmg.pack(m, -1.44, -1.5), u, 0.0, 0.0, 0.0, 0.0, True, False, False)[0]

    constant = replace(low, friction_factor=0.0)
    assert surge(low, u_ref) == pytest.approx(surge(constant, u_ref))
    for u in (0.5 * u_ref, 3.0 * u_ref, 10.0 * u_ref):
        proportional = ittc57_cf(u * lnu) / cf_ref  # R'_0(U)/R'_0 on a line through the origin
        assert surge(low, u) / surge(constant, u) == pytest.approx(proportional, rel=1e-9)
        additive = (low.hull.R0 + v.mmg.friction_factor * (ittc57_cf(u * lnu) - cf_ref)) / low.hull.R0
        assert (proportional - additive) * (u - u_ref) > 0  # less drop with speed, less rise below
    assert surge(low, 10.0 * u_ref) < 0.0  # still a resistance at ten times the reference speed


def test_first_principles_write_a_vessel_file_with_their_estimates_and_sources(tmp_path):
    from twin_command import twin

    out = tmp_path / "fp.json"
    done = twin("params", "--vessel", "blueboat", "--first-principles", "--json", "--write-model", out)
    assert done.returncode == 0 and json.loads(done.stdout)["vessel"] == "blueboat"
    written = vessel_mod.load(str(out))
    estimates = first_principles(vessel_mod.load("blueboat")).values()
    assert written.added_mass.Yvdot == pytest.approx(estimates["Yvdot"]) == pytest.approx(-7.9, abs=0.05)
    assert written.damping.Nur == pytest.approx(estimates["Nur"])
    assert written.sources["Xu"].startswith("twin params --first-principles: ITTC-1957")
    again = twin("params", "--vessel", "blueboat", "--first-principles", "--write-model", out)
    assert again.returncode == 2 and "exists: it is kept" in again.stderr


def test_params_write_a_shipped_vessel_to_start_ones_own_from(tmp_path):
    """`twin params --vessel blueboat --write-model my_design.json` writes the shipped file as it is (no
    checkout needed to copy it), which loads anywhere as the same twin and says what it wrote last."""
    from twin_command import twin

    out = tmp_path / "my_design.json"
    done = twin("params", "--vessel", "blueboat", "--write-model", out)
    assert done.returncode == 0 and done.stdout.strip().splitlines()[-1] == f"wrote {out}: blueboat as shipped"
    shipped, written = vessel_mod.load("blueboat"), vessel_mod.load(str(out))
    assert written.damping == shipped.damping and written.design == shipped.design
    assert written.thrusters == shipped.thrusters and written.added_mass == shipped.added_mass
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    run = twin("simulate", "--model", out, "--duration", "2", "--out", elsewhere / "run.csv", cwd=elsewhere)
    assert run.returncode == 0 and (elsewhere / "run.csv").is_file()
