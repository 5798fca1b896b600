"""Sea state and the 6-DOF hull (physics/waves.py, physics/seakeeping.py, engine/sixdof.py,
verify/sea.py): each test asserts physics with numbers, against closed forms or published figures."""
import math

import numpy as np
import pytest
import trimesh

import twin.vessel as vessel_mod
from twin.engine import sixdof
from twin.engine.mjcf import compile_vessel
from twin.errors import TwinError
from twin.physics import seakeeping as sk
from twin.physics import sections
from twin.physics import waves
from twin.physics.hydrostatics import pressure_load
from twin.verify import sea as checks


@pytest.fixture(scope="module")
def yellowfish():
    return vessel_mod.load("yellowfish")


@pytest.fixture(scope="module")
def blueboat():
    return vessel_mod.load("blueboat")


@pytest.fixture(scope="module")
def barge(tmp_path_factory):
    return checks.barge(tmp_path_factory.mktemp("barge"))


# ---------------------------------------------------------------- waves


def test_jonswap_carries_the_significant_height_and_pm_is_gamma_one():
    w = np.linspace(0.05, 30.0, 200001)
    for gamma in (1.0, 3.3):
        m0 = np.trapezoid(waves.jonswap(w, 2.0, 8.0, gamma), w)
        assert 4 * math.sqrt(m0) == pytest.approx(2.0, rel=0.01)
    assert np.allclose(waves.pierson_moskowitz(w, 2.0, 8.0), waves.jonswap(w, 2.0, 8.0, 1.0))
    wp = 2 * math.pi / 8.0
    assert w[np.argmax(waves.jonswap(w, 2.0, 8.0))] == pytest.approx(wp, rel=1e-3)  # the peak at Tp


def test_spreading_integrates_to_one_and_draws_are_seeded():
    th = np.linspace(-math.pi / 2, math.pi / 2, 20001)
    for n in (1.0, 2.0, 10.0, 400.0):  # 400: beyond where the gammas alone overflow
        assert np.trapezoid(waves.spreading(th, n), th) == pytest.approx(1.0, abs=1e-6)
    sea = waves.Sea(0.4, 3.0, 45.0, spread=4.0, seed=7)
    a, b = waves.components(sea), waves.components(sea)
    assert np.array_equal(a.phase_rad, b.phase_rad) and np.array_equal(a.beta_rad, b.beta_rad)
    assert a.hs_m == pytest.approx(0.4, rel=1e-12)
    other = waves.components(waves.Sea(0.4, 3.0, 45.0, spread=4.0, seed=8))
    assert not np.array_equal(a.phase_rad, other.phase_rad)
    mean_dir = math.degrees(math.atan2(np.sum(a.amplitude_m ** 2 * np.sin(a.beta_rad)),
                                       np.sum(a.amplitude_m ** 2 * np.cos(a.beta_rad))))
    assert abs((mean_dir - 225.0 + 180) % 360 - 180) < 15  # travels towards 225° (from 45°)


def test_grid_fields_equal_the_direct_sums():
    c = waves.components(waves.Sea(0.3, 2.5, 30.0, spread=2.0, seed=3))
    weights = waves.field_weights(c, (0.0, 0.25, 0.5), 0.04)
    nx, ny, dx, dy, psi = 9, 7, 0.11, 0.13, 0.4
    fields = np.empty((7, nx * ny))
    phase = np.empty((2, len(c)))
    waves.grid_fields(c.pack(), weights, 1.7, 3.0, -2.0, math.cos(psi), math.sin(psi), dx, dy, nx, ny, fields, phase,
                      4, 3)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    x = 3.0 + i.ravel() * dx * math.cos(psi) - j.ravel() * dy * math.sin(psi)
    y = -2.0 + i.ravel() * dx * math.sin(psi) + j.ravel() * dy * math.cos(psi)
    assert np.max(np.abs(fields[0] - waves.elevation(c, x, y, 1.7))) < 1e-12
    head = np.sum(c.amplitude_m * np.exp(-c.k_rad_m * 0.5) * np.cos(waves.phases(c, x, y, 1.7)), axis=-1)
    assert np.max(np.abs(fields[2] - head)) < 1e-12  # the head at a fixed depth, which the hull stretches
    acc = waves.acceleration(c, x, y, np.full(x.shape, 0.04), 1.7)
    assert np.max(np.abs(fields[3] - acc[:, 2])) < 1e-12 and np.max(np.abs(fields[5] - acc[:, 0])) < 1e-12
    vel = waves.velocity(c, x, y, np.full(x.shape, 0.04), 1.7)
    assert np.max(np.abs(fields[4] - vel[:, 2])) < 1e-12
    th = waves.phases(c, x[3 * nx + 4], y[3 * nx + 4], 1.7)
    assert np.allclose(phase, [np.cos(th), np.sin(th)], atol=1e-12)


def test_pressure_is_zero_on_the_surface_and_its_gradient_is_the_waters_acceleration():
    c = waves.components(waves.Sea(0.2, 3.0, 0.0, regular=True))
    x = np.linspace(0, 14, 50)
    zeta = waves.elevation(c, x, 0 * x, 0.3)
    assert np.ptp(zeta) > 0.19  # crests and troughs both
    assert np.max(np.abs(waves.pressure(c, x, 0 * x, -zeta + 1e-9, 0.3))) < 1e-3  # Pa, under crests and troughs
    # just below the surface: ρ(g − ω²ζ) = ρg(1 − kζ) in deep water, the water's vertical acceleration
    dz = 1e-4
    gradient = (waves.pressure(c, x, 0 * x, -zeta + dz, 0.3) - waves.pressure(c, x, 0 * x, -zeta, 0.3)) / dz
    assert gradient == pytest.approx(1000 * 9.81 * (1 - c.k_rad_m[0] * zeta), rel=1e-3)
    assert waves.pressure(c, 0.0, 0.0, 50.0, 0.0) == pytest.approx(1000 * 9.81 * 50, rel=1e-9)  # deep: hydrostatic


def test_a_box_riding_a_wave_feels_the_pressure_at_its_depth_below_the_local_surface():
    # a 0.2-m box, its bottom 5 cm below the surface under a crest and a trough of a 14-m wave (a 0.2 m):
    # lifted by ρgA(d − ζ(1 − e^(−kd))); decayed from the mean level instead, the trough's would be 31 % more
    c = waves.components(waves.Sea(0.4, 3.0, 0.0, regular=True))
    a, k, d, zh = c.amplitude_m[0], c.k_rad_m[0], 0.05, 0.2
    box = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    verts, faces = np.array(box.vertices) + [0.0, 0.0, d - 0.1], np.array(box.faces, dtype=float)
    weights = waves.field_weights(c, (0.0, zh / 2, zh), 0.04)
    nx = ny = 5
    ts = np.linspace(0.0, 3.0, 601)
    zeta_origin = waves.elevation(c, 0.0 * ts, 0.0 * ts, ts)
    for t in (ts[np.argmax(zeta_origin)], ts[np.argmin(zeta_origin)]):
        zeta = float(waves.elevation(c, 0.0, 0.0, t))
        fields, phase = np.empty((7, nx * ny)), np.empty((2, len(c)))
        waves.grid_fields(c.pack(), weights, t, -0.2, -0.2, 1.0, 0.0, 0.1, 0.1, nx, ny, fields, phase, 2, 2)
        out = np.zeros(6)
        pressure_load(verts, faces, 0.0, 0.0, -zeta, np.eye(3), fields, -0.2, -0.2, 1.0, 0.0, 0.1, 0.1, nx, ny, zh,
                      9810.0, np.empty((len(verts), 5)), out)
        lift = 9810.0 * 0.04 * (d - zeta * (1.0 - math.exp(-k * d)))
        assert abs(abs(zeta) - a) < 1e-3 and -out[2] == pytest.approx(lift, rel=0.01), (zeta, out[2], lift)


def test_the_pressure_over_a_hull_mesh_in_an_irregular_sea_is_the_reference_pressure_integrated():
    # a box piercing the surface of a seeded short-crested sea, trimmed, heeled and yawed: the engine's
    # integration (wave grid, depth interpolation, clipping at the local surface) against waves.pressure
    # at each face's centroid of a fine mesh
    c = waves.components(waves.parse_sea("0.3,2.5,30,4", 1))
    box = trimesh.creation.box(extents=(0.6, 0.3, 0.2))
    for _ in range(5):
        box = box.subdivide()
    verts, faces = np.array(box.vertices), np.array(box.faces)
    zh, nx, step = 0.3, 41, 0.025
    weights = waves.field_weights(c, (0.0, zh / 2, zh), 0.05)
    for t, (px, py, pz), angles in ((3.1, (1.0, 2.0, 0.0), (0.3, 0.05, -0.04)),
                                    (7.4, (-2.0, 0.5, 0.03), (2.0, -0.08, 0.1))):
        R = sk.rotation(*angles)
        ox, oy = px - step * (nx // 2), py - step * (nx // 2)
        fields, phase = np.empty((7, nx * nx)), np.empty((2, len(c)))
        waves.grid_fields(c.pack(), weights, t, ox, oy, 1.0, 0.0, step, step, nx, nx, fields, phase, 0, 0)
        out = np.zeros(6)
        pressure_load(verts, faces.astype(float), px, py, pz, R, fields, ox, oy, 1.0, 0.0, step, step, nx, nx, zh,
                      1000.0 * waves.G, np.empty((len(verts), 5)), out)
        tri = verts[faces] @ R.T
        centre = tri.mean(axis=1)
        area = 0.5 * np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # outward normal × area
        p = waves.pressure(c, px + centre[:, 0], py + centre[:, 1], pz + centre[:, 2], t)
        force = -(p[:, None] * area).sum(axis=0)
        moment = -(p[:, None] * np.cross(centre, area)).sum(axis=0)
        assert 0.0 < np.mean(p > 0) < 1.0  # the box pierces the surface
        assert out[:3] == pytest.approx(force, abs=0.01 * abs(force[2])), (out[:3], force)
        assert out[3:] == pytest.approx(moment, abs=0.003 * abs(force[2])), (out[3:], moment)


def test_bad_seas_are_refused_on_one_line():
    for text, words in (("1.0,1.0,30", "steeper than breaking"), ("0.3,2.5", "expects HS,TP,DIR"),
                        ("0.3,-2,0", "positive"), ("0.3,2.5,0,0.5", "spreading"), ("regular,0.3,2.5", "expects")):
        with pytest.raises(TwinError, match=words):
            waves.parse_sea(text)


def test_a_period_the_engine_cannot_resolve_and_a_vessel_without_meshes(yellowfish):
    hull = sixdof.hull_model(yellowfish)
    with pytest.raises(TwinError, match="shorter than the .* the twin resolves"):
        sixdof.sea_components(hull, waves.Sea(0.02, 0.4, 0.0, regular=True), 0.02)
    with pytest.raises(TwinError, match="no hull meshes"):
        sixdof.hull_model(vessel_mod.load("cybership1"))


# ---------------------------------------------------------------- hydrostatics and the hull


def test_pressure_integration_is_archimedes_at_any_attitude(yellowfish):
    hull = sixdof.hull_model(yellowfish)
    v = np.vstack([m[0] for m in hull.meshes])
    f = np.vstack([hull.meshes[0][1], hull.meshes[1][1] + len(hull.meshes[0][0])])
    R = sk.rotation(0.3, 0.04, -0.06)
    out = np.zeros(6)
    pressure_load(v, f, 1.0, 2.0, 0.03, R, np.zeros((7, 1)), 0, 0, 1, 0, 1, 1, 0, 0, 0.1, 9810.0,
                  np.empty((len(v), 5)), out)
    vol, centre = 0.0, np.zeros(3)
    for vv, ff in hull.meshes:
        a, c = sk.submerged_volume(vv @ R.T + [0, 0, 0.03], ff, 0.0)
        vol, centre = vol + a, centre + a * c
    centre /= vol
    assert out[2] == pytest.approx(-9810.0 * vol, rel=1e-12)
    assert np.max(np.abs(out[:2])) < 1e-9 * abs(out[2])
    assert out[3:] == pytest.approx(np.cross(centre, [0, 0, out[2]]), rel=1e-10, abs=1e-10)


def test_hydrodynamic_mesh_floats_the_vessel_as_the_full_mesh(yellowfish):
    from twin.physics.hydrostatics import submerged_volume, waterline_for_mass

    hull = sixdof.hull_model(yellowfish)
    full = sixdof._mass_properties(yellowfish)[3]
    z_full = waterline_for_mass(full, hull.mass_kg)["waterline_z_m"]
    resampled = [sk.hydro_mesh(v, f) for v, f in full]
    assert abs(waterline_for_mass(resampled, hull.mass_kg)["waterline_z_m"] - z_full) < 1e-3
    # placed: the full mesh's waterline and centre of buoyancy
    assert abs(waterline_for_mass(hull.meshes, hull.mass_kg)["waterline_z_m"] - z_full) < 1e-9
    for (hv, hf), (fv, ff) in zip(hull.meshes, full):
        assert np.allclose(submerged_volume(hv, hf, z_full)[1][:2], submerged_volume(fv, ff, z_full)[1][:2], atol=1e-9)
    assert sum(len(ff) for _, ff in hull.meshes) < 0.2 * sum(len(ff) for _, ff in full)


def test_rest_equals_validates_free_floating_draft_and_trim(yellowfish):
    r = checks.rest(yellowfish)
    assert abs(r["engine_down_mm"] - r["validate_down_mm"]) <= 1.0
    assert abs(r["engine_trim_deg"] - r["validate_trim_deg"]) <= 0.1
    assert abs(r["engine_heel_deg"] - r["validate_heel_deg"]) <= 0.1


def test_lewis_form_of_a_semicircle_and_of_a_box():
    # a semicircle: ρπr²/2 exactly. A box section B = 2T: its double body is a square, whose added mass
    # moving across a side is 1.51 ρπ(B/2)² [DNV-RP-C205 Table D-1], so C = a33/(ρπB²/8) = 1.51 at
    # infinite frequency; the Lewis form (a smooth section of the same B, T and area) comes within 6 %
    assert sk.lewis_heave(2.0, 1.0, math.pi / 4, 1000.0) == pytest.approx(1000 * math.pi / 2, rel=1e-5)
    c = sk.lewis_heave(2.0, 1.0, 1.0, 1000.0) / (1000 * math.pi * 4 / 8)
    assert c == pytest.approx(1.51, rel=0.06)


def _semicircle(radius_m: float, panels: int = sections.PANELS):
    th = np.linspace(0.0, math.pi / 2, panels + 1)
    return radius_m * np.cos(th), -radius_m * np.sin(th)


# a heaving semicircle by Ursell's multipole method [Ursell-1949], computed apart from this library: K R,
# a33/(ρπR²/2), b33/(ρω πR²/2), Ā
SEMICIRCLE = ((0.2, 0.9875, 1.3752, 0.2940), (0.6, 0.6144, 0.6961, 0.6274), (1.0, 0.6050, 0.3963, 0.7890))


def test_a_heaving_semicircle_radiates_as_the_multipole_solution_and_its_energy_say():
    rho, radius = 1000.0, 1.0
    half_disc = rho * math.pi * radius ** 2 / 2
    for kr, a33, b33, ratio in SEMICIRCLE:
        omega = math.sqrt(kr * waves.G / radius)
        r = sections.heave_radiation(*_semicircle(radius), omega, rho)
        assert r.a33 / half_disc == pytest.approx(a33, rel=0.025)
        assert r.b33 / (omega * half_disc) == pytest.approx(b33, rel=0.015)
        assert r.amplitude_ratio == pytest.approx(ratio, rel=0.015)
        # the damping from the pressure on the hull is the energy its two waves carry away
        assert r.b33 == pytest.approx(rho * waves.G ** 2 * r.amplitude_ratio ** 2 / omega ** 3, rel=0.02)
    slow_omega = math.sqrt(0.02 * waves.G)
    slow = sections.heave_radiation(*_semicircle(radius), slow_omega, rho)
    # long waves: Ā → ω²B/g (the Froude-Krylov force and the Haskind relation), twice the ω²B/(2g) of a
    # flux shared between the two waves
    assert slow.amplitude_ratio == pytest.approx(slow_omega ** 2 * 2 * radius / waves.G, rel=0.06)
    coarse, fine = (sections.heave_radiation(*_semicircle(radius, n), waves.G ** 0.5, rho).b33 for n in (20, 40))
    assert coarse == pytest.approx(fine, rel=0.01)
    with pytest.raises(TwinError, match="positive frequency"):
        sections.heave_radiation(*_semicircle(radius), 0.0)
    x, y = _semicircle(radius)
    with pytest.raises(TwinError, match="half contour"):
        sections.heave_radiation(x, -y, 3.0)  # above the surface


def test_a_lewis_contour_spans_its_beam_and_draft_and_holds_its_area():
    x, y = sections.lewis_contour(0.227, 0.066, 0.8, panels=400)
    assert (x[0], y[0]) == pytest.approx((0.1135, 0.0), abs=1e-9) and (x[-1], y[-1]) == pytest.approx((0.0, -0.066))
    area = 2.0 * abs(np.trapezoid(-y, x))  # both halves
    assert area == pytest.approx(0.8 * 0.227 * 0.066, rel=0.01)


def _conformal(a1: float, a3: float) -> bool:
    """Whether the Lewis map z = M(ζ + a1/ζ + a3/ζ³) has no critical point outside the unit circle
    (its contour is then not re-entrant): the roots of ζ⁴ − a1ζ² − 3a3 all inside it."""
    return bool(np.all(np.abs(np.roots([1.0, 0.0, -a1, 0.0, -3.0 * a3])) < 1.0))


def test_the_lewis_form_keeps_every_area_its_mapping_allows_and_no_other():
    # a V section of B = 2T and σ 0.55 is a valid Lewis form, kept as it is; a flat section of
    # B = 10T and σ 0.5 is not (its map folds), and is held to the nearest valid form
    x, y = sections.lewis_contour(0.2, 0.1, 0.55, panels=400)
    assert _conformal(*sections.lewis_form(0.2, 0.1, 0.55)[:2])
    assert 2.0 * abs(np.trapezoid(-y, x)) == pytest.approx(0.55 * 0.2 * 0.1, rel=0.01)
    # the check itself: B = 10T, σ 0.5 by the formulas unheld (a1 0.735, a3 0.102) folds
    assert not _conformal(0.7345, 0.1018)
    for h0 in (0.3, 0.5, 1.0, 2.0, 5.0, 8.0):
        for sigma in np.linspace(0.2, 1.6, 29):
            assert _conformal(*sections.lewis_form(2.0 * h0, 1.0, float(sigma))[:2]), (h0, sigma)


@pytest.mark.parametrize("which", ["yellowfish", "blueboat"])
def test_the_strips_heave_damping_at_the_natural_frequency(which, request):
    hull = sixdof.hull_model(request.getfixturevalue(which))
    wet = np.array([s.beam > 0 and s.draft > 0 for s in hull.strips])
    b33 = hull.radiation.b33
    assert np.all(b33[wet] > 0) and np.all(b33[~wet] == 0)
    # each section's own damping at the heave natural frequency: 0.7-2 times ρωB²/4, a quarter of the
    # long-wave limit ρωB² (a section's Ā saturates below it as ω√(B/2g) nears 1)
    beams = np.array([s.beam for s in hull.strips])[wet]
    ratio = b33[wet] / (1000.0 * hull.omega_heave * beams ** 2 / 4)
    assert np.all((ratio > 0.7) & (ratio < 2.0)), ratio


@pytest.mark.parametrize("which", ["yellowfish", "blueboat", "barge"])
def test_natural_periods_equal_the_closed_forms(which, request):
    result = checks.natural_periods(request.getfixturevalue(which))
    for mode, r in result.items():
        assert abs(r["error"]) <= 0.03, (mode, r)


def test_undamped_roll_decay_conserves_energy(yellowfish):
    r = checks.roll_energy(yellowfish)
    assert r["relative"] < 2e-3  # of the roll's energy, over 10 s (13 periods)
    assert r["roll_amplitude_end_deg"] == pytest.approx(3.0, rel=0.02)


@pytest.mark.parametrize("which", ["yellowfish", "blueboat"])
def test_the_shipped_hulls_float_level(which, request):
    z, trim, heel = sixdof.hull_model(request.getfixturevalue(which)).equilibrium
    assert abs(math.degrees(trim)) < 1e-3 and abs(math.degrees(heel)) < 1e-3


@pytest.mark.parametrize("which", ["yellowfish", "blueboat"])
def test_the_wave_pressure_levels_reach_below_the_keel_at_rest(which, request):
    # the head is interpolated between levels down to zh and held below it: the hull must lie within them
    vessel = request.getfixturevalue(which)
    hull = sixdof.hull_model(vessel)
    keel = max(float(m[0][:, 2].max()) for m in hull.meshes) + hull.equilibrium[0]  # m below the surface
    assert 0.05 < keel < 0.15
    zh = sixdof.sea_view(sixdof.compile_six(compile_vessel(vessel), waves.parse_sea("regular,0.1,4,0", 1)).model)[sk._ZH]
    assert 1.4 * keel < zh < 1.6 * keel


@pytest.mark.parametrize("which", ["yellowfish", "blueboat"])
def test_calm_water_six_dof_follows_the_three_dof_twin(which, request):
    """The BlueBoat trims 1.5° bow up at 20 N a thruster: its thrusters tilt with it and its centre of
    gravity moves over the yaw axis, which the level horizontal model takes off."""
    r = checks.calm_water(request.getfixturevalue(which))
    assert r["position_err_m"] < 0.01 and r["heading_err_deg"] < 0.1


# ---------------------------------------------------------------- the barge in waves


def test_barge_heave_rao_against_the_linear_strip_solution(barge):
    rows = checks.barge_rao(barge, "heave", [6.0, 2.5, 1.73])
    assert rows[0]["engine"] == pytest.approx(1.0, abs=0.01)  # long waves: the box follows the surface
    for r in rows:
        assert r["engine"] == pytest.approx(r["reference"], rel=0.03), r
    hull = sixdof.hull_model(barge)
    assert rows[2]["period_s"] == pytest.approx(hull.periods["heave"], rel=0.01)  # at resonance


def test_barge_roll_rao_long_wave_limit_and_below_resonance(barge):
    rows = checks.barge_rao(barge, "roll", [8.0, 2.2])
    for r in rows:
        assert r["engine"] == pytest.approx(r["reference"], rel=0.02), r
    assert checks.roll_rao_closed_form(sixdof.hull_model(barge), 60.0) == pytest.approx(1.0, abs=0.002)
    assert rows[1]["engine"] > 1.8  # amplified near the 1.73-s roll period


def test_mean_drift_against_the_short_wave_asymptote_and_the_barrier_reflection(barge):
    rows = checks.drift(barge)
    for r in rows:
        assert r["engine"] == pytest.approx(r["with_reflection"], rel=0.01, abs=0.002), r
    short = [r for r in rows if r["kT"] > 1.5]
    assert all(r["engine"] == pytest.approx(1.0, abs=0.01) for r in short)  # a wall-sided body: ½ρga² per length
    assert rows[2]["engine"] < 0.02  # long waves pass under the box


@pytest.mark.parametrize("which", ["barge", "blueboat", "yellowfish"])
def test_a_free_hull_in_a_long_wave_heaves_with_the_surface_and_pitches_with_its_slope(which, request):

    vessel = request.getfixturevalue(which)
    six = sixdof.compile_six(compile_vessel(vessel), waves.parse_sea("regular,0.1,8,30"))
    a, w, k, cb, sb, phase = six.components.pack()[0]
    t, q, _ = sixdof.free_run(six, 120.0, sample_every=2, eta0=(0.0, 0.0, math.atan2(sb, cb) + math.pi))
    keep = t >= 60.0  # λ 100 m over a hull of 1-2 m: quasi-static, the start long damped out
    theta = k * (cb * q[keep, 0] + sb * q[keep, 1]) - w * t[keep] + phase
    basis = np.column_stack([np.cos(theta), np.sin(theta), np.ones(keep.sum())])
    heave = np.linalg.lstsq(basis, q[keep, 2], rcond=None)[0]
    pitch = np.linalg.lstsq(basis, q[keep, 4], rcond=None)[0]
    # down positive: the hull rises on the crest (η = a cos θ); bow up where the surface ahead rises
    assert heave[0] == pytest.approx(-a, rel=0.02) and abs(heave[1]) < 0.02 * a
    assert pitch[1] == pytest.approx(k * a, rel=0.05) and abs(pitch[0]) < 0.1 * k * a


def test_a_free_hull_drifts_along_the_waves_near_their_stokes_drift(yellowfish, blueboat):
    drifts = {}
    for v in (yellowfish, blueboat):  # long waves (λ 25 m and 39 m): a small hull rides the orbits
        excess = []
        for sea, stokes in (("regular,0.25,4,30", 0.0061), ("regular,0.39,5,30", 0.0076)):
            long = drifts[v.name, sea] = checks.free_drift(v, waves.parse_sea(sea))
            assert long["stokes_m_s"] == pytest.approx(stokes, abs=3e-4)
            # along the waves, the Stokes drift and a little more: the hull's own wave loads add to it
            assert stokes < long["along_m_s"] < 3.0 * stokes, long
            assert abs(long["across_m_s"]) < 0.003, long
            excess.append(long["along_m_s"] / long["stokes_m_s"] - 1.0)
        assert excess[1] < excess[0]  # and less of it as the waves lengthen
    # in swell of 100 m (80 of its lengths) the light BlueBoat goes with the water, not against it
    swell = checks.free_drift(blueboat, waves.parse_sea("regular,0.999,8,30"))
    assert swell["stokes_m_s"] < swell["along_m_s"] < 1.5 * swell["stokes_m_s"], swell
    # averaged over its first 150 s the BlueBoat still carries its start from rest: well short of its drift
    early = checks.free_drift(blueboat, waves.parse_sea("regular,0.25,4,30"), duration_s=150.0, settle_s=20.0)
    settled = drifts[blueboat.name, "regular,0.25,4,30"]
    assert early["along_m_s"] < 0.5 * settled["along_m_s"], (early, settled)
    short = checks.free_drift(blueboat, waves.parse_sea("0.3,2.5,30,4", 1))
    # the waves' way, not along the hull's own heading (in waves this short the drift has no reference)
    assert short["stokes_m_s"] < short["along_m_s"] < 5.0 * short["stokes_m_s"], short
    assert abs(short["across_m_s"]) < 0.1 * short["along_m_s"], short


def test_a_known_seas_drift_is_the_stokes_drift_a_flow_the_3dof_twin_goes_with(blueboat, tmp_path):
    from dataclasses import replace

    from twin.drive import InputSeries
    from twin.engine.sim import simulate

    sea = waves.parse_sea("regular,0.25,4,30")
    n, e = sixdof.known_sea_drift(blueboat, sea)
    omega = 2 * math.pi / 4.0
    k = omega ** 2 / waves.G
    depth = sixdof.strip_depth_m(sixdof.hull_model(blueboat))
    assert math.hypot(n, e) == pytest.approx(omega * k * 0.125 ** 2 * math.exp(-2 * k * depth), rel=1e-9)
    assert math.degrees(math.atan2(e, n)) % 360 == pytest.approx(210.0)  # where the waves go
    drifting = blueboat.with_environment(replace(blueboat.environment, wave_drift_ned=(n, e)))
    t = np.arange(0.0, 401.0)
    idle = InputSeries(t, np.zeros((len(t), 2)), "thrust")
    run = simulate(compile_vessel(drifting), idle, 400.0, sample_dt_s=1.0)
    drift = (run.eta[-1, :2] - run.eta[-101, :2]) / (run.t[-1] - run.t[-101])
    # a free twin goes with the water (its heading still turning slowly in the flow)
    assert math.hypot(*drift) == pytest.approx(math.hypot(n, e), rel=0.03)
    assert abs(math.degrees(math.atan2(drift[1], drift[0]) - math.atan2(e, n))) < 5.0
    vessel_mod.save(drifting, tmp_path / "known.json")
    assert vessel_mod.load(str(tmp_path / "known.json")).environment.wave_drift_ned == pytest.approx((n, e))
    vessel_mod.save(blueboat, tmp_path / "plain.json")
    assert "wave_" not in (tmp_path / "plain.json").read_text()  # files without a sea stay as they were
    assert sixdof.without_known_sea(drifting).environment.wave_drift_ned == (0.0, 0.0)
    with pytest.raises(TwinError, match="known flow"):  # the 6-DOF twin takes the sea itself, not twice
        sixdof.compile_six(compile_vessel(drifting), sea)


def test_a_known_load_is_read_by_heading_and_speed_alike_in_both_engines(yellowfish):
    from dataclasses import replace

    from twin.drive import InputSeries
    from twin.engine.sim import simulate

    table = np.zeros((sk.KNOWN_HEADINGS, 3, 3))
    table[0, :, 0] = (-1.0, -4.0, -6.0)  # head seas: the added resistance grows with speed
    table[2, :, 1] = (-2.0, -2.0, -3.0)  # from starboard: pushed to port
    block = sk.pack_known_load(math.radians(30.0), (0.0, 1.0, 2.0), table)
    head = math.radians(30.0)
    assert sk.known_load(block, head, 0.5) == pytest.approx((-2.5, 0.0, 0.0))
    assert sk.known_load(block, head, 5.0) == pytest.approx((-6.0, 0.0, 0.0))  # held at the ends
    assert sk.known_load(block, head, -1.0) == pytest.approx((-1.0, 0.0, 0.0))  # astern as at rest
    assert sk.known_load(block, head - math.radians(67.5), 1.0) == pytest.approx((0.0, -1.0, 0.0))  # 45°-90°
    with pytest.raises(ValueError):
        sk.pack_known_load(0.0, (1.0, 0.0), np.zeros((sk.KNOWN_HEADINGS, 2, 3)))
    loaded = yellowfish.with_environment(replace(yellowfish.environment, wave_load=tuple(block)))
    t = np.arange(0.0, 31.0)
    idle = InputSeries(t, np.zeros((len(t), 2)), "thrust")
    runs = [simulate(compile_vessel(loaded), idle, 30.0, eta0=(0.0, 0.0, head), backend=b) for b in ("native", "python")]
    assert np.max(np.abs(runs[0].eta - runs[1].eta)) < 1e-6
    back = runs[0].eta[-1, :2] @ np.array([math.cos(head), math.sin(head)])
    assert back < -1.0  # pushed astern by the head seas' load
    assert abs(runs[0].eta[-1, 2] - head) < 1e-9  # no moment in pure head seas


def test_the_mean_load_of_regular_waves_on_the_hull(blueboat):
    block = sixdof.mean_sea_load(blueboat, waves.parse_sea("regular,0.15,2.5,30"), speeds_m_s=(0.0, 1.0, 2.0),
                                 run_s=10.0)
    speeds, table = sk.known_table(block)
    assert tuple(speeds) == (0.0, 1.0, 2.0)
    head, beam = table[0], table[2]
    assert head[1, 0] < head[0, 0] - 0.2 and head[2, 0] < head[1, 0]  # an added resistance growing with speed
    assert abs(beam[0, 1]) < 0.01 and abs(head[0, 1]) < 1e-3  # at rest the Stokes flow carries the hull's drift
    assert np.allclose(table[6], table[2] * [1.0, -1.0, -1.0])  # from port: the mirror of from starboard


def test_identify_takes_the_sea_a_log_was_made_in_and_bad_seas_are_one_line(tmp_path):
    from twin_command import twin

    sea = "regular,0.15,2.5,30"  # the guide (sea-state) runs evaluate and diagnose with it
    done = twin("dataset", "--vessel", "yellowfish", "--segments", "2", "--seed", "3", "--noise", "none",
                "--sea", sea, "--manoeuvres", "forward_varying,circle_varying", "--out", tmp_path / "waves.csv")
    assert done.returncode == 0, done.stderr
    done = twin("identify", tmp_path / "waves.csv", "--vessel", "yellowfish", "--sea", sea, "--params", "Xu",
                "--max-evaluations", "2", "--out", tmp_path / "twin.json")
    assert done.returncode == 0, done.stderr
    assert "its Stokes drift at the hull, 0.009 m/s towards 210°, a known flow" in done.stdout
    assert "its mean load on the hull" in done.stdout
    assert "wave_" not in (tmp_path / "twin.json").read_text()  # the twin, not the recording's sea
    done = twin("evaluate", tmp_path / "waves.csv", "--vessel", "yellowfish", "--sea", sea, "--stride", "10",
                "--json", tmp_path / "e.json")
    assert done.returncode == 0, done.stderr
    drift = __import__("json").loads((tmp_path / "e.json").read_text())["sea_drift_ned_m_s"]
    assert math.hypot(*drift) == pytest.approx(0.0086, abs=5e-4)
    for command in ("evaluate", "diagnose"):
        for args, words in ((("--vessel", "cybership1", "--sea", sea), "no hull meshes"),
                            (("--vessel", "yellowfish", "--sea", "1.0,1.0,30"), "steeper than breaking")):
            done = twin(command, tmp_path / "waves.csv", *args)
            assert done.returncode == 2 and words in done.stderr and len(done.stderr.strip().splitlines()) == 1


def test_a_log_made_in_waves_keeps_its_sea_and_info_says_it_with_the_roll_and_pitch(tmp_path):
    """The sea a dataset was made in is kept in the MCAP's meta and `twin info` says it, with how far
    the hull rolled and pitched (the guide, sea-state, promises both)."""
    from twin_command import twin

    done = twin("dataset", "--vessel", "yellowfish", "--segments", "1", "--sea", "0.2,2.5,60,4", "--out",
                tmp_path / "waves.mcap")
    assert done.returncode == 0, done.stderr
    done = twin("info", tmp_path / "waves.mcap")
    assert done.returncode == 0, done.stderr
    assert "  sea      JONSWAP, Hs 0.2 m, Tp 2.5 s, from 60°, spreading cos^4 (seed 0)" in done.stdout
    tilt = [line for line in done.stdout.splitlines() if line.strip().startswith("attitude")]
    roll, pitch = (float(x) for x in __import__("re").findall(r"within ±([0-9.]+)°", tilt[0]))
    assert 1.0 < roll < 30.0 and 1.0 < pitch < 30.0  # a 1.3-m hull in 0.2-m waves rocks, and stays up


SHARED = __import__("pathlib").Path(__file__).resolve().parents[1].parent / "shared" / "data" / "ardupilot"


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared absent")
def test_logs_roll_and_pitch_are_read_beside_the_heading():
    from twin.formats import read_recording

    tlog = read_recording(SHARED / "ardusub_small.tlog")  # ATTITUDE, rad
    assert len(tlog.attitude) == len(tlog.heading) > 5000
    assert 0.01 < np.max(np.abs(tlog.attitude["roll_rad"])) < 0.2  # a BlueROV2 rolls a few degrees
    df = read_recording(SHARED / "ardusub_small.BIN")  # ATT, degrees → rad
    assert len(df.attitude) == len(df.heading) and np.max(np.abs(df.attitude["pitch_rad"])) < 0.02
    assert tlog.summary()["streams"]["attitude"]["samples"] == len(tlog.attitude)


# ---------------------------------------------------------------- many twins in a sea


def test_montecarlo_in_a_sea_draws_each_twin_its_own_sea_from_its_seed(yellowfish):
    from dataclasses import replace

    from twin.engine.sim import simulate
    from twin.scale import montecarlo as mc
    from twin.scale.draws import Variation, parse_factor

    sea = waves.parse_sea("0.3,2.5,30,4", seed=5)
    mission = mc.scenario_mission(yellowfish, "step", 10.0, 0.5, sea=sea)
    variation = Variation(factors=(parse_factor("Xu=0.999..1.001", yellowfish),))
    a = mc.run(yellowfish, mission, 4, seed=1, variation=variation, batch_size=2)
    b = mc.run(yellowfish, mission, 4, seed=1, variation=variation, batch_size=2)
    assert np.array_equal(a.sample_tracks, b.sample_tracks)  # seeded
    calm = mc.run(yellowfish, replace(mission, sea=None), 4, seed=1, variation=variation, batch_size=2)
    spread_sea = np.max(np.ptp(a.sample_tracks[:, -1, :2], axis=0))
    spread_calm = np.max(np.ptp(calm.sample_tracks[:, -1, :2], axis=0))
    assert spread_sea > 0.05 and spread_sea > 20 * spread_calm  # the seas differ, not the Xu factors
    seeds = [s.seed for b_ in mc.plan(4, 2, 1) for s in mc.sea_draws(sea, b_)]
    assert len(set(seeds)) == 4
    # the nominal twin runs its own 6-DOF hull in the mission's realisation of the sea
    run = simulate(compile_vessel(yellowfish), mission.inputs, 10.0, sample_dt_s=0.5, sea=sea)
    assert np.max(np.abs(a.nominal[:, :3] - run.eta)) < 1e-6


def test_dataset_shards_in_a_sea_give_each_vessel_its_own_realisation(yellowfish, tmp_path):
    from twin.formats import read_recording
    from twin.scale import datasets
    from twin.scale.draws import Variation, parse_factor

    settings = datasets.Settings(2, per_shard=2, segments=1, manoeuvres=("forward_constant",), seed=4,
                                 variation=Variation(factors=(parse_factor("Xu=0.9..1.1", yellowfish),)),
                                 sea=waves.parse_sea("0.2,2.5,60,4"))
    index = datasets.generate_shards(yellowfish, settings, tmp_path / "shards")
    seas = [e["sea"] for e in index.entries]
    assert seas[0]["seed"] == index.entries[0]["seed"] and seas[0]["seed"] != seas[1]["seed"]
    assert index.index["settings"]["sea"]["hs_m"] == 0.2
    rec = read_recording(tmp_path / "shards" / index.entries[0]["file"])
    assert 0.2 < np.degrees(np.std(rec.attitude["pitch_rad"])) < 5  # the hull pitched in the waves


def test_logs_written_from_a_run_in_a_sea_carry_its_roll_and_pitch(yellowfish, tmp_path):
    from twin.engine.sim import simulate
    from twin.formats import read_recording, write_recording, write_run
    from twin.drive import get

    run = simulate(compile_vessel(yellowfish), get("step", 0), 8.0, sample_dt_s=0.02,
                   sea=waves.parse_sea("0.3,2.5,45,4", seed=2))
    six = run.meta["six_dof"]
    assert np.degrees(np.ptp(six["pitch_rad"])) > 0.5  # the hull moves: there is something to log
    for suffix, tol_deg in ((".tlog", 1e-5), (".bin", 0.006)):  # float32 rad; int16 centidegrees
        write_run(run, tmp_path / f"run{suffix}")
        rec = read_recording(tmp_path / f"run{suffix}")
        att = rec.attitude
        assert len(att) == len(rec.heading) > 300
        t = att.t - att.t[0]
        for col in ("roll_rad", "pitch_rad"):
            assert np.degrees(np.max(np.abs(att[col] - np.interp(t, run.t, six[col])))) < tol_deg, (suffix, col)
        # and a recording written on to another format keeps them
        write_recording(rec, tmp_path / f"again{suffix}.mcap")
        again = read_recording(tmp_path / f"again{suffix}.mcap")
        assert np.allclose(again.attitude["pitch_rad"], att["pitch_rad"], atol=1e-12)
    calm = simulate(compile_vessel(yellowfish), get("step", 0), 4.0, sample_dt_s=0.02)
    write_run(calm, tmp_path / "calm.tlog")
    assert np.max(np.abs(read_recording(tmp_path / "calm.tlog").attitude["roll_rad"])) == 0.0  # a level hull
