"""Oil properties against the seed's Appendix 2 table and hand calculations."""

import math

import numpy as np
import pytest

from firmware_model.physics import oil

ROWS_T = [-20.0, 0.0, 20.0, 40.0, 60.0, 80.0, 100.0, 120.0, 140.0]
ROWS_RHO = [896.438, 885.902, 875.366, 864.830, 854.294, 843.758, 833.222, 822.686, 812.150]
ROWS_NU_CST = [9486.0, 1397.0, 337.6, 115.0, 49.9, 25.8, 15.2, 9.84, 6.84]
ROWS_PIEZO = {20.0: 24.0e-9, 40.0: 21.6e-9, 60.0: 19.3e-9, 80.0: 16.9e-9, 100.0: 14.7e-9, 120.0: 12.0e-9}


def _walther(nu_cst):
    return math.log10(math.log10(nu_cst + 0.7))


def test_table_rows_reproduced_exactly():
    T = np.array(ROWS_T)
    np.testing.assert_allclose(oil.kinematic_viscosity_m2_s(T), np.array(ROWS_NU_CST) * 1e-6, rtol=1e-12)
    np.testing.assert_allclose(oil.density_kg_m3(T), ROWS_RHO, rtol=1e-12)
    for t, a in ROWS_PIEZO.items():
        assert oil.piezo_viscosity_per_pa(t) == pytest.approx(a, rel=1e-12)


def test_viscosity_30c_walther_between_rows():
    nu30 = oil.kinematic_viscosity_m2_s(30.0) * 1e6
    # hand Walther: W linear in log10(T_K) between the 20 and 40 degC rows
    x20, x40, x30 = math.log10(293.15), math.log10(313.15), math.log10(303.15)
    w = _walther(337.6) + (_walther(115.0) - _walther(337.6)) * (x30 - x20) / (x40 - x20)
    expected = 10 ** (10**w) - 0.7
    assert nu30 == pytest.approx(expected, rel=1e-10)
    geometric = math.sqrt(115.0 * 337.6)  # 197.0 cSt (log-linear in T)
    arithmetic = 0.5 * (115.0 + 337.6)  # 226.3 cSt (linear in T)
    assert 115.0 < nu30 < 337.6
    assert nu30 < arithmetic
    assert abs(nu30 - geometric) < abs(nu30 - arithmetic)
    print(f"nu(30 degC) = {nu30:.1f} cSt (geometric mean {geometric:.1f}, arithmetic {arithmetic:.1f})")


def test_viscosity_monotone_positive_and_clipped():
    T = np.linspace(-60.0, 260.0, 2000)
    nu = oil.kinematic_viscosity_m2_s(T)
    assert np.all(nu > 0.0)
    assert np.all(np.diff(nu) <= 0.0)
    assert oil.kinematic_viscosity_m2_s(-100.0) == oil.kinematic_viscosity_m2_s(-40.0)
    assert oil.kinematic_viscosity_m2_s(500.0) == oil.kinematic_viscosity_m2_s(200.0)


def test_viscosity_extrapolation_uses_end_segments():
    # below -20 degC: the -20/0 degC Walther line; above 140: the 120/140 line
    def line(t_a, nu_a, t_b, nu_b, t):
        xa, xb, x = (math.log10(v + 273.15) for v in (t_a, t_b, t))
        w = _walther(nu_a) + (_walther(nu_b) - _walther(nu_a)) * (x - xa) / (xb - xa)
        return 10 ** (10**w) - 0.7

    assert oil.kinematic_viscosity_m2_s(-40.0) * 1e6 == pytest.approx(line(-20, 9486.0, 0, 1397.0, -40), rel=1e-9)
    assert oil.kinematic_viscosity_m2_s(200.0) * 1e6 == pytest.approx(line(120, 9.84, 140, 6.84, 200), rel=1e-9)


def test_density_linear():
    # table slope: (812.150 - 896.438) / 160 = -0.5268 kg/m3/K
    assert oil.density_kg_m3(50.0) == pytest.approx(885.902 - 0.5268 * 50.0, rel=1e-12)
    assert oil.density_kg_m3(-40.0) == pytest.approx(885.902 + 0.5268 * 40.0, rel=1e-12)


def test_piezo_interpolation_and_extrapolation():
    assert oil.piezo_viscosity_per_pa(30.0) == pytest.approx(22.8e-9, rel=1e-12)  # (24.0 + 21.6) / 2
    assert oil.piezo_viscosity_per_pa(10.0) == pytest.approx(25.2e-9, rel=1e-12)  # 24.0 + 0.12 * 10
    assert oil.piezo_viscosity_per_pa(130.0) == pytest.approx(10.65e-9, rel=1e-12)  # 12.0 - 0.135 * 10
    a = oil.piezo_viscosity_per_pa(np.linspace(-60.0, 300.0, 500))
    assert np.all(a >= oil.PIEZO_FLOOR_PER_PA) and np.all(np.diff(a) <= 0.0)


def test_assumed_thermal_properties_at_100c():
    assert oil.thermal_conductivity_w_per_mk(100.0) == pytest.approx(0.134 - 7e-5 * 100.0)
    assert oil.specific_heat_j_per_kgk(100.0) == pytest.approx(1880.0 + 370.0)
    alpha = 0.127 / (833.222 * 2250.0)
    assert oil.thermal_diffusivity_m2_s(100.0) == pytest.approx(alpha, rel=1e-12)
    assert oil.prandtl(100.0) == pytest.approx(15.2e-6 / alpha, rel=1e-10)
    assert oil.dynamic_viscosity_pa_s(100.0) == pytest.approx(833.222 * 15.2e-6, rel=1e-12)


def test_oil_properties_matches_individual_functions_and_broadcasts():
    T = np.array([[-30.0, 25.0, 77.7], [101.0, 150.0, 199.0]])
    p = oil.oil_properties(T)
    assert p.nu_m2_s.shape == T.shape
    np.testing.assert_allclose(p.rho_kg_m3, oil.density_kg_m3(T))
    np.testing.assert_allclose(p.nu_m2_s, oil.kinematic_viscosity_m2_s(T))
    np.testing.assert_allclose(p.mu_pa_s, oil.dynamic_viscosity_pa_s(T))
    np.testing.assert_allclose(p.piezo_per_pa, oil.piezo_viscosity_per_pa(T))
    np.testing.assert_allclose(p.k_w_per_mk, oil.thermal_conductivity_w_per_mk(T))
    np.testing.assert_allclose(p.cp_j_per_kgk, oil.specific_heat_j_per_kgk(T))
    np.testing.assert_allclose(p.alpha_m2_s, oil.thermal_diffusivity_m2_s(T))
    np.testing.assert_allclose(p.pr, oil.prandtl(T))
    s = oil.oil_properties(90.0)
    assert float(s.mu_pa_s) == pytest.approx(float(oil.dynamic_viscosity_pa_s(90.0)))


# --- an oil from its data sheet (Oil.grade, a description's [oil]) ------------------------------------------------


def test_grade_passes_through_its_data_sheet_points_and_is_one_walther_line():
    g = oil.Oil.grade(320.0, 24.0, 900.0)
    assert g.kinematic_viscosity_m2_s(40.0) * 1e6 == pytest.approx(320.0, rel=1e-12)
    assert g.kinematic_viscosity_m2_s(100.0) * 1e6 == pytest.approx(24.0, rel=1e-12)
    # ASTM D341 by hand: W linear in log10(T_K) through the two points, also outside them
    x40, x100 = math.log10(313.15), math.log10(373.15)
    for t in (0.0, 60.0, 140.0):
        x = math.log10(t + 273.15)
        w = _walther(320.0) + (_walther(24.0) - _walther(320.0)) * (x - x40) / (x100 - x40)
        assert g.kinematic_viscosity_m2_s(t) * 1e6 == pytest.approx(10 ** (10**w) - 0.7, rel=1e-10)
    # a VG 320 is thicker than the seed's oil everywhere in the working range, and falls more steeply
    T = np.linspace(0.0, 120.0, 13)
    assert np.all(g.kinematic_viscosity_m2_s(T) > oil.kinematic_viscosity_m2_s(T))
    assert g.density_kg_m3(15.0) == pytest.approx(900.0, rel=1e-12)
    assert g.name == "ISO VG 320 (its data sheet)" and "250 mm2/s" in oil.Oil.grade(250.0, 20.0, 900.0).name
    # ASTM D1250 table 54D: alpha_15 = 0.6278 / rho_15, the slope the same for every density
    for rho15 in (860.0, 900.0, 940.0):
        d = oil.Oil.grade(320.0, 24.0, rho15)
        alpha15 = -(d.density_kg_m3(16.0) - d.density_kg_m3(14.0)) / 2.0 / rho15
        assert alpha15 == pytest.approx(0.6278 / rho15, rel=1e-9)
    # within 0.15 % of the standard's exponential form, rho_15 exp(-a dT (1 + 0.8 a dT)), up to 100 degC
    a, dT = 0.6278 / 900.0, 85.0
    assert float(g.density_kg_m3(100.0)) == pytest.approx(900.0 * math.exp(-a * dT * (1.0 + 0.8 * a * dT)), rel=1.5e-3)


def test_grade_piezo_is_the_seed_shape_scaled():
    g = oil.Oil.grade(320.0, 24.0, 900.0, 25.0e-9)
    assert g.piezo_viscosity_per_pa(40.0) == pytest.approx(25.0e-9, rel=1e-12)
    assert g.piezo_viscosity_per_pa(80.0) == pytest.approx(16.9e-9 * 25.0 / 21.6, rel=1e-12)
    # beyond the clip (200 degC) the seed's extrapolation, scaled, never under the floor
    assert g.piezo_viscosity_per_pa(400.0) == pytest.approx(oil.piezo_viscosity_per_pa(200.0) * 25.0 / 21.6, rel=1e-12)
    assert g.piezo_viscosity_per_pa(400.0) >= oil.PIEZO_FLOOR_PER_PA
    assert oil.Oil.grade(320.0, 24.0, 900.0).piezo_viscosity_per_pa(40.0) == oil.piezo_viscosity_per_pa(40.0)


@pytest.mark.parametrize(
    "args, words",
    [
        ((24.0, 320.0, 900.0), "above its viscosity at 100 degC"),
        ((320.0, float("nan"), 900.0), "above its viscosity at 100 degC"),
        ((320.0, 0.0, 900.0), "both positive"),
        ((320.0, 24.0, 9.0), "density at 15 degC"),
        ((320.0, 24.0, 900.0, 25.0), "piezo-viscosity"),
        # a unit slip (320 written as m2/s: 3.2e8 mm2/s), and its thin counterpart
        ((3.2e8, 2.4e7, 900.0), "outside the ISO 3448 grades"),
        ((0.001, 0.0001, 900.0), "outside the ISO 3448 grades"),
        ((320.0, 1.0, 900.0), "under the 2 mm2/s"),  # below Walther's range
        ((320.0, 300.0, 900.0), "thins less with temperature than any oil"),
        ((40.0, 2.5, 900.0), "thins more with temperature than any oil"),
    ],
)
def test_grade_refuses_values_no_oil_has(args, words):
    with pytest.raises(oil.InputError, match=words):
        oil.Oil.grade(*args)


@pytest.mark.parametrize("nu40, nu100", [(32.0, 5.4), (220.0, 19.0), (320.0, 24.0), (320.0, 35.0), (320.0, 20.0)])
def test_grade_takes_real_oils(nu40, nu100):
    # mineral VG 32 to VG 320, a PAO (high index) and a low-index mineral VG 320: within the slope's band
    assert oil.GRADE_SLOPE[0] < oil.walther_slope(nu40, 40.0, nu100, 100.0) < oil.GRADE_SLOPE[1]
    assert oil.Oil.grade(nu40, nu100, 880.0).kinematic_viscosity_m2_s(40.0) == pytest.approx(nu40 * 1e-6)


def test_two_points_give_the_seed_tables_other_rows():
    # an outside check of the two-point line: the seed's Appendix 2 table (its oil's rows from -20 to 140 degC) from
    # its 40 and 100 degC rows alone, within 0.2 % at every other row
    g = oil.Oil.grade(float(oil.TABLE_NU_CST[3]), float(oil.TABLE_NU_CST[6]), 878.0)
    nu = g.kinematic_viscosity_m2_s(oil.TABLE_T_C) * 1e6
    np.testing.assert_allclose(nu, oil.TABLE_NU_CST, rtol=2e-3)


def test_coldest_use_temperature():
    # SAE J306's 150 Pa s: where the VG 320 reaches it, the oil is that thick (and thicker below)
    g = oil.Oil.grade(320.0, 24.0, 900.0)
    t = g.temperature_at_mu_c(oil.COLDEST_USE_MU_PA_S)
    assert -25.0 < t < -18.0
    assert g.dynamic_viscosity_pa_s(t) == pytest.approx(oil.COLDEST_USE_MU_PA_S, rel=1e-6)
    assert g.dynamic_viscosity_pa_s(t - 1.0) > oil.COLDEST_USE_MU_PA_S
    # an oil that never gets that thick within the model's range: its coldest end
    assert oil.SEED_OIL.temperature_at_mu_c(oil.COLDEST_USE_MU_PA_S) == oil.T_MIN_C


def test_a_low_piezo_oil_keeps_the_seed_shape():
    # the floor scales with the oil: a 10 /GPa oil is the seed's shape scaled at every temperature
    g = oil.Oil.grade(320.0, 24.0, 900.0, 10.0e-9)
    T = np.array([20.0, 80.0, 140.0, 200.0])
    np.testing.assert_allclose(g.piezo_viscosity_per_pa(T), oil.piezo_viscosity_per_pa(T) * 10.0 / 21.6, rtol=1e-12)


def test_oil_of_a_parameter_set():
    assert oil.oil_of({}) is oil.SEED_OIL
    g = oil.oil_of({"oil.nu_40": 220e-6, "oil.nu_100": 19e-6})
    assert g.kinematic_viscosity_m2_s(40.0) == pytest.approx(220e-6, rel=1e-12)
    assert g.density_kg_m3(15.0) == pytest.approx(float(oil.density_kg_m3(15.0)), rel=1e-12)  # the seed's density
    with pytest.raises(oil.InputError, match="both oil.nu_40 and oil.nu_100"):
        oil.oil_of({"oil.nu_40": 220e-6})
    with pytest.raises(oil.InputError, match="needs the viscosity too"):
        oil.oil_of({"oil.rho_15": 880.0})


def test_seed_oil_functions_are_the_seed_oils_properties_bit_for_bit():
    T = np.linspace(-50.0, 210.0, 53)
    p = oil.SEED_OIL.properties(T)
    for name, fn in (
        ("rho_kg_m3", oil.density_kg_m3),
        ("nu_m2_s", oil.kinematic_viscosity_m2_s),
        ("mu_pa_s", oil.dynamic_viscosity_pa_s),
        ("piezo_per_pa", oil.piezo_viscosity_per_pa),
    ):
        np.testing.assert_array_equal(getattr(p, name), fn(T), err_msg=name)
