"""twin.diagnose.noise and twin.diagnose.locate on synthetic data with known structure."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.signal import lfilter

from twin.diagnose.locate import correlations, format_located, growth, locate, overall
from twin.diagnose.noise import estimate_noise, rate_sigma, white_noise
from twin.geodesy import geodetic_from_ned
from twin.prepare import prepare
from twin.recording import Recording, Stream

# ---------------------------------------------------------------- noise

SPEED = 1.5


def _recording(seed: int, *, gnss_m=0.05, heading_deg=0.3, gnss_dt=0.2, heading_dt=0.02, duration_s=300.0,
               repeat_at_10hz=False, turning=False, geodetic=False) -> Recording:
    """A boat at SPEED on course 40° (or weaving ±17° every 40 s), white sensor noise."""
    g = np.random.default_rng(seed)
    course = lambda t: np.radians(40.0) + (0.3 * np.sin(2 * np.pi * t / 40.0) if turning else 0.0 * t)  # noqa: E731
    tf = np.arange(0.0, duration_s + 1.0, 1e-3)
    n_true = np.cumsum(SPEED * np.cos(course(tf))) * 1e-3
    e_true = np.cumsum(SPEED * np.sin(course(tf))) * 1e-3
    t = np.arange(0.0, duration_s, gnss_dt)
    n = np.interp(t, tf, n_true) + g.normal(0, gnss_m, len(t))
    e = np.interp(t, tf, e_true) + g.normal(0, gnss_m, len(t))
    if repeat_at_10hz:  # every fix logged twice, as the BlueBoat files do
        t, n, e = np.arange(0.0, duration_s, gnss_dt / 2), np.repeat(n, 2), np.repeat(e, 2)
    rec = Recording(source="test", kind="synthetic")
    if geodetic:
        lat, lon = geodetic_from_ned(n, e, 37.41, -5.98, 0.0)[:2]
        rec.gnss = Stream(t, {"lat_deg": lat, "lon_deg": lon})
    else:
        rec.gnss = Stream(t, {"north_m": n, "east_m": e})
    th = np.arange(0.0, duration_s, heading_dt)
    rec.heading = Stream(th, {"psi_rad": course(th) + np.radians(g.normal(0, heading_deg, len(th)))})
    tp = np.arange(0.0, duration_s, 0.1)
    rec.pwm = Stream(tp, {"left_us": np.full(len(tp), 1700.0), "right_us": np.full(len(tp), 1700.0)})
    return rec


@pytest.mark.parametrize("kw", [{}, {"repeat_at_10hz": True}, {"turning": True, "gnss_m": 0.02},
                                {"gnss_dt": 0.1, "geodetic": True}, {"heading_dt": 0.1, "heading_deg": 1.0}])
def test_white_noise_recovered(kw):
    for seed in (0, 1):
        rec = _recording(seed, **kw)
        est = estimate_noise(rec, prepare(rec))
        assert est["gnss_m"] == pytest.approx(kw.get("gnss_m", 0.05), rel=0.15)
        assert est["heading_deg"] == pytest.approx(kw.get("heading_deg", 0.3), rel=0.15)
        assert est["gnss_rate_hz"] == pytest.approx(1 / kw.get("gnss_dt", 0.2), rel=1e-6)
        assert isinstance(est["method"], str) and all(isinstance(est[k], float) for k in ("u", "v", "r"))


@pytest.mark.parametrize("smoother,gnss_dt", [("savgol", 0.2), ("savgol", 0.1), ("none", 0.2), ("savgol", 1.0)])
def test_velocity_noise_matches_prepared(smoother, gnss_dt):
    """σ_u, σ_v, σ_r against the scatter of prepare()'s velocities about the truth on a
    straight constant-speed run (segment edges, where the filter is one-sided, left out)."""
    rec = _recording(3, gnss_dt=gnss_dt)
    prep = prepare(rec, smoother=smoother)
    est = estimate_noise(rec, prep)
    mid = slice(30, -30)
    assert est["u"] == pytest.approx(np.std(prep.u[mid] - SPEED), rel=0.25)
    assert est["v"] == pytest.approx(np.std(prep.v[mid]), rel=0.25)
    assert est["r"] == pytest.approx(np.std(prep.r[mid]), rel=0.25)


def test_white_noise_edge_cases():
    assert np.isnan(white_noise(np.arange(2.0), np.zeros(2)).sigma)
    assert np.isnan(white_noise(np.arange(5.0), np.zeros(5)).sigma)  # a run shorter than one block
    assert rate_sigma(0.1, 0.2, "none", 1.0, 2) == pytest.approx(0.1 / (np.sqrt(2) * 0.2))
    assert np.isnan(rate_sigma(float("nan"), 0.2, "savgol", 1.0, 2))


# ---------------------------------------------------------------- locate

NOISE = np.array([0.05, 0.05, 0.01])
W, N_W, DT = 80, 100, 0.1  # 80 windows of 10 s at 10 Hz


def _windows(seed: int, rho: float = 0.9):
    """Residuals of a correct twin (noise σ = NOISE, correlated along each window) and the
    context of 80 windows: speed, yaw rate, region, PWM constant per window, heading
    turning at the window's yaw rate, windows 12 s apart in one recording."""
    g = np.random.default_rng(seed)
    t_in = np.tile(np.arange(N_W) * DT, W)
    per_window = lambda x: np.repeat(x, N_W)  # noqa: E731
    r_deg = per_window(g.uniform(-20, 20, W))
    ctx = {"u_m_s": per_window(g.uniform(0, 2, W)) + 0.05 * g.standard_normal(W * N_W),
           "v_m_s": 0.05 * g.standard_normal(W * N_W), "r_rad_s": np.radians(r_deg),
           "heading_deg": np.mod(per_window(g.uniform(0, 360, W)) + r_deg * t_in, 360.0),
           "region": per_window(g.choice(["ff", "fr", "rf", "rr"], W, p=[0.7, 0.1, 0.1, 0.1])),
           "pwm_mean_us": per_window(g.uniform(1500, 1800, W)), "pwm_diff_us": per_window(g.uniform(-150, 150, W)),
           "since_input_step_s": np.mod(t_in + per_window(g.uniform(0, 5, W)), 5.0),
           "near_zero_pwm": per_window(g.random(W) < 0.2), "run_time_s": per_window(np.arange(W) * 12.0) + t_in,
           "time_in_window_s": t_in, "recording": np.zeros(W * N_W, int), "segment": per_window(np.arange(W) // 10)}
    e = lfilter([np.sqrt(1 - rho ** 2)], [1, -rho], g.standard_normal((W, N_W, 3)), axis=1)
    return (e * NOISE).reshape(-1, 3), np.repeat(np.arange(W), N_W), ctx


def _signals(ctx):
    psi = np.radians(ctx["heading_deg"])
    return {"u": ctx["u_m_s"], "v": ctx["v_m_s"], "r": ctx["r_rad_s"], "|r|": np.abs(ctx["r_rad_s"]),
            "sin psi": np.sin(psi), "cos psi": np.cos(psi), "pwm mean": ctx["pwm_mean_us"],
            "pwm diff": ctx["pwm_diff_us"], "u*r": ctx["u_m_s"] * ctx["r_rad_s"], "run time": ctx["run_time_s"]}


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_pure_noise_finds_nothing(seed):
    res, window, ctx = _windows(seed)
    assert locate(res, NOISE, window, ctx) == []
    assert max(e["z"] for e in locate(res, NOISE, window, ctx, z_min=0.0, top=1000)) < 3
    assert all(e["z"] < 3 for rows in correlations(res, window, _signals(ctx)).values() for e in rows)
    assert {g["verdict"] for g in growth(res.reshape(W, N_W, 3), np.arange(N_W) * DT, NOISE).values()} == {"none"}
    assert all(o["z_bias"] < 3 for o in overall(res, NOISE, window).values())


def test_heading_sector_bias_in_r():
    res, window, ctx = _windows(1)
    sector = (ctx["heading_deg"] >= 90) & (ctx["heading_deg"] < 135)
    res[sector, 2] += 3 * NOISE[2]
    top = locate(res, NOISE, window, ctx)[0]
    assert (top["dimension"], top["bin"], top["dof"], top["kind"]) == ("heading", "90-135°", "r", "bias")
    assert top["bias"] == pytest.approx(3 * NOISE[2], rel=0.2)
    assert top["share_of_residual"] > 3 * top["share_of_samples"]
    assert top["z"] >= 5


def test_v_error_proportional_to_speed():
    res, window, ctx = _windows(2)
    res[:, 1] += 0.1 * ctx["u_m_s"]
    top = locate(res, NOISE, window, ctx)[0]
    assert (top["dimension"], top["bin"], top["dof"], top["kind"]) == ("speed", "u>1.2", "v", "bias")
    best = correlations(res, window, _signals(ctx))["v"][0]
    assert best["signal"] == "u" and best["r"] > 0.6 and best["z"] >= 3


def test_spread_in_fast_turns():
    """An error of random sign per window, only in fast turns: a spread, not a bias."""
    res, window, ctx = _windows(3)
    fast = np.abs(np.degrees(ctx["r_rad_s"])) > 10
    sign = np.repeat(np.random.default_rng(9).choice([-1.0, 1.0], W), N_W)
    res[fast, 0] += 4 * NOISE[0] * sign[fast]
    top = locate(res, NOISE, window, ctx)[0]
    assert (top["dimension"], top["dof"], top["kind"]) == ("yaw_rate", "u", "spread")
    assert top["bin"] in ("r<-10°/s", "r>10°/s")


def test_growth_tells_dynamics_from_measurement():
    res, _, _ = _windows(4)
    res_w, t_in = res.reshape(W, N_W, 3), np.arange(N_W) * DT
    res_w[..., 0] += 0.04 * t_in * np.random.default_rng(5).choice([-1.0, 1.0], (W, 1))  # a missing force
    res_w[..., 2] += 3 * NOISE[2]  # a heading-rate offset from the start
    res_w[:, :5] = np.nan  # the first half second not compared
    g = growth(res_w, t_in, NOISE)
    assert g["u"]["verdict"] == "dynamics" and g["u"]["ratio"] > 3
    assert g["r"]["verdict"] == "measurement" and g["r"]["ratio"] == pytest.approx(1.0, abs=0.2)
    assert g["v"]["verdict"] == "none"


@pytest.mark.filterwarnings("error")
def test_degenerate_inputs():
    res, window, ctx = _windows(5)
    res[::7] = np.nan
    res[:, 1] = np.nan  # a DOF never compared
    ctx = dict(ctx, region=np.where(ctx["region"] == "ff", "ff", ""), near_zero_pwm=np.zeros(len(res), bool))
    del ctx["heading_deg"]
    one = window == 0
    for r, w, c in [(res, window, ctx), (res[one], window[one], {k: v[one] for k, v in ctx.items()}),
                    (res[:0], window[:0], {k: v[:0] for k, v in ctx.items()})]:
        assert locate(r, NOISE, w, c) == []
        cor = correlations(r, w, {"const": np.ones(len(r)), "u": c["u_m_s"]})
        assert all(e["z"] == 0 for rows in cor.values() for e in rows if e["signal"] == "const")
        overall(r, NOISE, w)
    g = growth(np.full((3, 10, 3), np.nan), np.arange(10.0), NOISE)
    assert {v["verdict"] for v in g.values()} == {"none"}
    growth(res[:N_W].reshape(1, N_W, 3), np.arange(N_W) * DT)  # one window, no noise given


def test_format_located_fits_100_columns():
    res, window, ctx = _windows(1)
    res[(ctx["heading_deg"] >= 90) & (ctx["heading_deg"] < 135), 2] += 3 * NOISE[2]
    res[:, 1] += 0.1 * ctx["u_m_s"]
    text = format_located(locate(res, NOISE, window, ctx))
    assert "90-135°" in text and "u>1.2" in text
    assert max(len(line) for line in text.splitlines()) <= 100
    assert "no bin" in format_located([])
    assert "region:" not in text  # a legend only where the table has a region's row
    row = {"dimension": "region", "bin": "rf", "dof": "r", "kind": "bias", "n": 40, "rms": 0.1, "bias": 0.05,
           "rms_over_noise": 4.0, "share_of_residual": 0.2, "share_of_samples": 0.1, "z": 5.0}
    legend = format_located([row]).splitlines()[-1]
    assert legend.startswith("region:") and "rf: the left astern, the right ahead" in legend and len(legend) <= 100


def test_a_z_short_of_the_bar_is_not_shown_on_it():
    """2.98 against z 3 reads 2.98, never 3.0 beside "z 3 needs more"; elsewhere one decimal."""
    from twin.diagnose.report import z_text

    assert [z_text(z) for z in (2.98, 3.0, 3.04, 2.9, 4.76, -0.13)] == ["2.98", "3.0", "3.04", "2.9", "4.8", "-0.1"]


def test_a_difference_either_way_counts_both_tails_and_an_excess_one():
    from scipy.stats import norm
    from scipy.stats import t as student_t

    from twin.diagnose.locate import _family_z

    p = student_t.sf(3.6, 40)
    assert _family_z(3.6, 40, 33, two_sided=True) == pytest.approx(norm.isf(2 * 33 * p), rel=1e-9)
    assert _family_z(3.6, 40, 33) == pytest.approx(norm.isf(33 * p), rel=1e-9)
    assert _family_z(3.6, 40, 33, two_sided=True) < _family_z(3.6, 40, 33)


def test_a_window_that_diverged_scores_as_failed_not_as_a_gap():
    from twin.fit.metrics import r2_mae
    from twin.fit.windows import Prediction, Window

    nu = np.zeros((2, 11, 3))
    nu[:, :, 0] = np.linspace(0.0, 1.0, 11)
    nu[1, 5:] = np.nan  # blew up at its 5th sample
    nu[0, 9:] = np.nan  # a shorter window: padding beyond its 8 steps
    pred = Prediction([Window(0, 0, 8), Window(0, 0, 10)], np.zeros_like(nu), nu, [(1, 0.5)])
    failed = pred.nu_failed_as_inf()
    assert np.isinf(failed[1, 5:]).all() and np.isnan(failed[0, 9:]).all() and np.isfinite(failed[0, :9]).all()
    meas = np.full_like(nu, 0.5)
    meas[0, 9:] = np.nan  # measured over each window's own length
    scored = r2_mae(failed[:, 1:], meas[:, 1:])
    assert scored["u"]["diverged"] == 6 and scored["u"]["r2"] is None  # samples 5-10 of the second window
    assert r2_mae(nu[:, 1:], meas[:, 1:])["u"]["diverged"] == 0  # as NaN they would have been skipped


def test_a_noise_that_cannot_be_estimated_is_refused_in_one_sentence(monkeypatch):
    from twin.diagnose import doctor
    from twin.errors import TwinError

    estimates = iter([{"u": float("nan"), "v": 0.01, "r": 0.002, "gnss_m": 0.02, "method": "m"},
                      {"u": 0.02, "v": 0.01, "r": 0.003, "gnss_m": 0.03, "method": "m"}])
    monkeypatch.setattr(doctor, "estimate_noise", lambda rec, prep: next(estimates))
    got = doctor._noise([None, None], [None, None])  # one log gives u, and that is its median
    assert got["u"] == 0.02 and got["r"] == pytest.approx(0.0025)
    monkeypatch.setattr(doctor, "estimate_noise", lambda rec, prep: {"u": float("nan"), "v": 0.01, "r": float("nan")})
    with pytest.raises(TwinError, match="the noise of u, r cannot be estimated from this recording"):
        doctor._noise([None], [None])


def test_the_residual_table_names_recordings_by_file_and_numbers_twins_of_a_name():
    """A recording's bin reads as its file name; two files of one name (other folders) keep apart by
    their number from 1, and a recording without a source by its number alone."""
    from twin.diagnose.doctor import _context
    from twin.fit.windows import Window

    preps = [prepare(replace(_recording(seed), source=src)) for seed, src in
             ((1, "a/log.csv"), (2, "b/log.csv"), (3, "c/other.csv"), (4, ""))]
    ctx, _, _ = _context(preps, [Window(i, 0, 5) for i in range(4)], 5)
    assert list(dict.fromkeys(ctx["recording_name"])) == ["log.csv (1)", "log.csv (2)", "other.csv", "4"]
    assert list(dict.fromkeys(ctx["recording"])) == [0, 1, 2, 3]
