"""Mechanical losses (seed section 3.2) against hand calculations."""

import math

import numpy as np
import pytest

from firmware_model.errors import ParameterError
from firmware_model.physics import losses as L
from firmware_model.physics.heat_lag import first_order_lag_step, heat_lag, heat_lag_step

DEG = math.pi / 180.0
MN = 4.5e-3
ALPHA_N = 20.0 * DEG
BETA = 20.0 * DEG
M_T = MN / math.cos(BETA)
A0 = (30 + 40) * M_T / 2.0
# 100 degC oil of the seed's table (Appendix 2)
RHO_100 = 833.222
MU_100 = 833.222 * 15.2e-6
PIEZO_100 = 14.7e-9
E_STEEL = 2.1e11


@pytest.fixture(scope="module")
def truck_pair():
    return L.mesh_geometry(30, 40, MN, ALPHA_N, BETA, A0, 0.040)


# --- geometry ----------------------------------------------------------------------------------------------


def test_mesh_geometry_hand_calc(truck_pair):
    m = truck_pair
    alpha_t = math.atan(math.tan(ALPHA_N) / math.cos(BETA))  # 21.17 deg
    R_p1, R_p2 = 15 * M_T, 20 * M_T
    R_b1, R_b2 = R_p1 * math.cos(alpha_t), R_p2 * math.cos(alpha_t)
    R_a1, R_a2 = R_p1 + MN, R_p2 + MN
    assert m.R_p1_m == pytest.approx(R_p1) and m.R_b2_m == pytest.approx(R_b2)
    assert m.R_a1_m == pytest.approx(R_a1) and m.R_f1_m == pytest.approx(R_p1 - 1.25 * MN)
    assert m.alpha_tw_rad == pytest.approx(alpha_t)  # reference centre distance
    # recession limited by the driver's tip, approach by the driven wheel's tip
    g_a = math.sqrt(R_a1**2 - R_b1**2) - R_p1 * math.sin(alpha_t)
    g_f = math.sqrt(R_a2**2 - R_b2**2) - R_p2 * math.sin(alpha_t)
    assert m.g_a_m == pytest.approx(g_a) and m.g_f_m == pytest.approx(g_f)
    assert m.L_a_m == pytest.approx(g_a + g_f)
    assert m.h_t_m == pytest.approx(2.25 * MN)
    assert m.eps_alpha == pytest.approx((g_a + g_f) / (math.pi * M_T * math.cos(alpha_t)))
    assert 1.4 < m.eps_alpha < 1.7
    # base helix: cos(beta_b) = cos(beta) cos(alpha_n) / cos(alpha_t)
    assert math.cos(m.beta_b_rad) == pytest.approx(math.cos(BETA) * math.cos(ALPHA_N) / math.cos(alpha_t))


def test_working_pressure_angle_eq17():
    a = A0 + 0.5e-3
    m = L.mesh_geometry(30, 40, MN, ALPHA_N, BETA, a, 0.040, x1=0.3, x2=-0.1)
    assert m.alpha_tw_rad == pytest.approx(math.acos((m.R_b1_m + m.R_b2_m) / a))
    assert m.R_w1_m + m.R_w2_m == pytest.approx(a)
    assert m.R_w2_m / m.R_w1_m == pytest.approx(40 / 30)
    assert m.R_a1_m == pytest.approx(15 * M_T + 1.3 * MN)


def test_internal_mesh_geometry():
    a = (60 - 20) * M_T / 2.0
    m = L.mesh_geometry(20, 60, MN, ALPHA_N, BETA, a, 0.030, internal=True)
    assert m.R_a2_m == pytest.approx(30 * M_T - MN)  # ring tip inside its pitch circle
    assert m.R_f2_m == pytest.approx(30 * M_T + 1.25 * MN)
    assert m.alpha_tw_rad == pytest.approx(math.acos((m.R_b2_m - m.R_b1_m) / a))
    assert m.R_w2_m - m.R_w1_m == pytest.approx(a)
    g_f = m.R_w2_m * math.sin(m.alpha_tw_rad) - math.sqrt(m.R_a2_m**2 - m.R_b2_m**2)
    assert m.g_f_m == pytest.approx(g_f) and g_f > 0 and m.g_a_m > 0


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(z1=30, z2=40, center_distance_m=0.5 * A0),  # base radii sum >= centre distance
        dict(z1=30, z2=40, center_distance_m=A0 + 20e-3),  # tips no longer reach the line of action
        dict(z1=30, z2=20, center_distance_m=A0, internal=True),  # ring smaller than planet
        dict(z1=3, z2=40, center_distance_m=A0),
    ],
)
def test_impossible_geometry_raises(kwargs):
    base = dict(m_n_m=MN, alpha_n_rad=ALPHA_N, beta_rad=BETA, face_width_m=0.04)
    with pytest.raises(ParameterError):
        L.mesh_geometry(**{**base, **kwargs})


# --- slipping and rolling ------------------------------------------------------------------------------------


def _reference_slip(m, T1, w2, mu, n=20000):
    """Independent midpoint integration of Eq 7-10 written with omega1 kinematics (external mesh)."""
    w1 = w2 * m.z2 / m.z1
    F_n = T1 / m.R_w1_m / (math.cos(m.alpha_n_rad) * math.cos(m.beta_rad))
    F_nu = F_n / (m.face_width_m / math.cos(m.beta_b_rad))
    s_m = (np.arange(n) + 0.5) / n * m.L_a_m
    d = s_m - m.g_f_m
    rho1 = m.R_w1_m * math.sin(m.alpha_tw_rad) + d
    rho2 = m.R_w2_m * math.sin(m.alpha_tw_rad) - d
    V_g = np.abs(d) * (w1 + w2)
    V_r = w1 * rho1 + w2 * rho2
    f = np.clip(0.0127 * np.log10(0.02912 * F_nu / (mu * V_g * V_r**2)), 0.005, 0.15)
    return float(np.mean(F_n * f * V_g))


def test_slip_loss_realistic_truck_pair(truck_pair):
    w1 = 1300.0 * math.pi / 30.0
    w2 = w1 * 30.0 / 40.0
    P = float(L.gear_slip_loss_w(truck_pair, 2500.0, w2, RHO_100, MU_100))
    share = P / (2500.0 * w1)
    f_mean = float(L.gear_slip_coefficient(truck_pair, 2500.0, w2, RHO_100, MU_100))
    print(f"slip loss {P:.0f} W = {100 * share:.3f} % of {2500 * w1 / 1e3:.0f} kW, mean f_g = {f_mean:.4f}")
    assert 0.003 <= share <= 0.015
    assert L.F_G_MIN <= f_mean <= L.F_G_MAX
    assert P == pytest.approx(_reference_slip(truck_pair, 2500.0, w2, MU_100), rel=1e-4)


def test_slip_loss_converges_and_is_finite(truck_pair):
    w2 = 100.0
    vals = [float(L.gear_slip_loss_w(truck_pair, 1000.0, w2, RHO_100, MU_100, n_points=n)) for n in (3, 10, 20, 80)]
    assert all(math.isfinite(v) for v in vals)
    assert vals[1] == pytest.approx(vals[3], rel=1e-4)
    assert vals[2] == pytest.approx(vals[3], rel=1e-5)


def test_slip_loss_zero_sign_and_broadcast(truck_pair):
    assert L.gear_slip_loss_w(truck_pair, 0.0, 100.0, RHO_100, MU_100) == 0.0
    assert L.gear_slip_loss_w(truck_pair, 1000.0, 0.0, RHO_100, MU_100) == 0.0
    assert L.gear_slip_loss_w(truck_pair, -1000.0, -100.0, RHO_100, MU_100) == pytest.approx(
        L.gear_slip_loss_w(truck_pair, 1000.0, 100.0, RHO_100, MU_100)
    )
    T = np.array([[0.0], [500.0], [2500.0]])
    w = np.array([0.0, 50.0, 100.0, 200.0])
    P = L.gear_slip_loss_w(truck_pair, T, w, RHO_100, MU_100)
    assert P.shape == (3, 4)
    assert np.all(P[0] == 0.0) and np.all(P[:, 0] == 0.0)
    assert np.all(np.diff(P[1:, 1:], axis=1) > 0) and np.all(np.diff(P[1:, 1:], axis=0) > 0)
    # slightly faster than linear in load, slightly slower than linear in speed (seed, section 3.2)
    assert P[2, 2] / P[1, 2] > 5.0
    assert P[2, 3] / P[2, 2] < 2.0
    # thinner (hotter) oil loses more
    assert L.gear_slip_loss_w(truck_pair, 2500.0, 100.0, 854.294, 854.294 * 49.9e-6) < P[2, 2]


def _reference_rolling(m, T1, w2, mu, piezo, n=20000):
    """Independent midpoint integration of Eq 14-22 with omega1 kinematics (external mesh)."""
    w1 = w2 * m.z2 / m.z1
    E = 2.0 / (2.0 * (1.0 - 0.3**2) / E_STEEL)
    F_n = T1 / m.R_w1_m / (math.cos(m.alpha_n_rad) * math.cos(m.beta_rad))
    F_nu = F_n * math.cos(m.beta_b_rad) / m.face_width_m
    d = (np.arange(n) + 0.5) / n * m.L_a_m - m.g_f_m
    rho1 = m.R_w1_m * math.sin(m.alpha_tw_rad) + d
    rho2 = m.R_w2_m * math.sin(m.alpha_tw_rad) - d
    V_r = w1 * rho1 + w2 * rho2
    c = math.cos(m.alpha_t_rad) / (math.cos(m.beta_rad) * math.cos(m.alpha_n_rad))
    X = (c * rho1) * (c * rho2) / (c * rho1 + c * rho2)
    e_h = X * 2.65 * (mu * V_r / (2 * E * X)) ** 0.7 * (piezo * E) ** 0.54 * (F_nu / (E * X)) ** -0.13
    F_r = 9e7 * e_h * m.face_width_m / math.cos(m.beta_rad)
    return float(np.mean(F_r * V_r))


def test_rolling_loss_order_of_magnitude(truck_pair):
    w2 = 1300.0 * math.pi / 30.0 * 0.75
    P = float(L.gear_rolling_loss_w(truck_pair, 2500.0, w2, MU_100, PIEZO_100, E_STEEL, E_STEEL, 0.3, 0.3))
    print(f"rolling loss {P:.2f} W")
    assert 0.1 < P < 30.0  # seed: "on the order of 1 W"
    assert P == pytest.approx(_reference_rolling(truck_pair, 2500.0, w2, MU_100, PIEZO_100), rel=1e-4)
    assert L.gear_rolling_loss_w(truck_pair, 0.0, w2, MU_100, PIEZO_100, E_STEEL, E_STEEL, 0.3, 0.3) == 0.0
    P2 = L.gear_rolling_loss_w(
        truck_pair, 2500.0, np.array([w2, 2 * w2]), MU_100, PIEZO_100, E_STEEL, E_STEEL, 0.3, 0.3
    )
    assert P2[1] / P2[0] > 2.0  # faster than linear in speed


def test_equivalent_modulus_eq19():
    assert L.equivalent_modulus_pa(2.1e11, 2.1e11, 0.3, 0.3) == pytest.approx(2.1e11 / 0.91)


def test_internal_mesh_losses_finite_and_smaller_slip():
    a = (60 - 20) * M_T / 2.0
    ring = L.mesh_geometry(20, 60, MN, ALPHA_N, BETA, a, 0.030, internal=True)
    a_e = (20 + 20) * M_T / 2.0
    ext = L.mesh_geometry(20, 20, MN, ALPHA_N, BETA, a_e, 0.030)
    Pi = float(L.gear_slip_loss_w(ring, 500.0, 50.0, RHO_100, MU_100))
    Pr = float(L.gear_rolling_loss_w(ring, 500.0, 50.0, MU_100, PIEZO_100, E_STEEL, E_STEEL, 0.3, 0.3))
    assert math.isfinite(Pi) and Pi > 0 and math.isfinite(Pr) and Pr > 0
    # per unit transmitted power the internal contact slides less (|w1 - w2| instead of w1 + w2)
    share_i = Pi / (500.0 * 50.0 * 3)
    share_e = float(L.gear_slip_loss_w(ext, 500.0, 50.0, RHO_100, MU_100)) / (500.0 * 50.0)
    assert share_i < share_e


# --- churning ------------------------------------------------------------------------------------------------

G = 9.80665


def _hand_cmd(regime, re, fr, vr, wr, hr):
    if regime == 28:
        return 0.97 * re**-0.31 * fr ** -(0.464 + 0.037 / hr) * vr**-0.576 * wr**-0.124 * hr**0.74
    c, e = (2.63, -0.73) if regime == 29 else (4.57, -0.5)
    return c * re**-0.6 * fr**-0.25 * vr**e * wr**-0.4 * hr**1.5


def _hand_cma(regime, re, fr, htr, wtr):
    if regime == 31:
        return 5623.0 * re**-0.88 * fr**-0.78 * htr**-1.5 * wtr**-0.36
    return 616.6 * re**-0.64 * fr**-0.46 * htr**-1.66 * wtr**-0.46


@pytest.mark.parametrize(
    "omega, nu, cmd_regime, cma_regime, valid",
    [
        (100.0, 5e-5, 28, 31, True),  # Re_side 5000, Fr_t 206, Re_t 900: inside Eq 33-34
        (math.sqrt(100.0 * G / 0.05), None, 29, 31, True),  # Re_side 2000, Fr_side 100, Re_t 1800
        (20.0, 1e-3, 30, 32, False),  # Re_side 50, Fr_side 2.04; Fr_t 8.3 < 22 (Eq 34)
    ],
)
def test_churning_regimes_by_hand(omega, nu, cmd_regime, cma_regime, valid):
    R_a, R_p, h_t, w_t, h_i, V_p, V_0, rho, h_t0 = 0.05, 0.045, 0.010, 0.010, 0.020, 1.5e-3, 10e-3, 850.0, 8e-3
    if nu is None:
        nu = omega * R_a**2 / 2000.0
    r = L.churning_loss(omega, R_a, R_p, h_t, w_t, h_i, V_p, V_0, rho, nu, h_t0)
    re_s, fr_s = omega * R_a**2 / nu, omega**2 * R_a / G
    re_t, fr_t = omega * R_p * h_t / nu, omega**2 * R_p**2 / (G * h_t)
    assert int(r.cmd_regime) == cmd_regime and int(r.cma_regime) == cma_regime
    cmd = _hand_cmd(cmd_regime, re_s, fr_s, V_p / V_0, w_t / R_a, h_i / R_a)
    cma = _hand_cma(cma_regime, re_t, fr_t, h_t / h_t0, w_t / h_t0)
    C_side = rho * omega**2 * w_t * R_a**4 * cmd
    C_teeth = rho * omega**2 * w_t * R_p**3 * h_t * cma
    assert float(r.C_side_nm) == pytest.approx(C_side, rel=1e-12)
    assert float(r.C_teeth_nm) == pytest.approx(C_teeth, rel=1e-12)
    assert float(r.power_w) == pytest.approx((C_side + C_teeth) * omega, rel=1e-12)
    assert bool(r.valid) == valid


def test_churning_zero_speed_and_vector():
    w = np.array([-10.0, 0.0, 100.0, 200.0])
    r = L.churning_loss(w, 0.05, 0.045, 0.01, 0.01, 0.02, 1.5e-3, 10e-3, 850.0, 5e-5)
    assert r.power_w.shape == (4,)
    assert np.all(r.power_w[:2] == 0.0) and np.all(r.cmd_regime[:2] == 0) and not np.any(r.valid[:2])
    assert r.power_w[3] > r.power_w[2] > 0.0


def test_churning_layshaft_wheel_realistic():
    # layshaft wheel like the truck pair's 40-tooth wheel: R_a 100 mm, 40 mm wide, dipping 40 mm in 12 l of oil
    R_a, R_p, h_t, w_t, h_i, V_0 = 0.1003, 0.0958, 0.0101, 0.040, 0.040, 12e-3
    th = 2 * math.acos(1 - h_i / R_a)
    V_p = R_a**2 * (th - math.sin(th)) / 2 * w_t
    n = np.array([1000.0, 1500.0, 2000.0])
    r = L.churning_loss(n * math.pi / 30, R_a, R_p, h_t, w_t, h_i, V_p, V_0, RHO_100, 15.2e-6)
    print("churning at 1000/1500/2000 rpm, 100 degC:", np.round(r.power_w, 1), "W")
    assert np.all((r.power_w > 5.0) & (r.power_w < 2000.0))
    assert np.all(np.diff(r.power_w) > 0)


# --- bearings, synchronizer, pump -------------------------------------------------------------------------


def test_bearing_p1_both_branches():
    e, X1, Y1, X2, Y2 = 0.55, 1.0, 0.0, 1.2, 1.0
    assert L.bearing_p1_n(1000.0, 600.0, e, X1, Y1, X2, Y2) == pytest.approx(1000.0)  # Fa/Fr >= e
    assert L.bearing_p1_n(1000.0, 100.0, e, X1, Y1, X2, Y2) == pytest.approx(1.2 * 1000 + 100)  # Fa/Fr < e
    assert L.bearing_p1_n(1000.0, 550.0, e, X1, Y1, X2, Y2) == pytest.approx(1000.0)  # boundary
    assert L.bearing_p1_n(0.0, 500.0, 0.22, 1.0, 0.5, 0.56, 2.0) == pytest.approx(250.0)  # Fr = 0
    assert L.bearing_p1_n(0.0, 0.0, e, X1, Y1, X2, Y2) == 0.0
    P = L.bearing_p1_n(np.array([1000.0, 1000.0]), np.array([600.0, 100.0]), e, X1, Y1, X2, Y2)
    np.testing.assert_allclose(P, [1000.0, 1300.0])


def test_bearing_oil_torque_equals_palmgren():
    f0, Dm, nu_cst = 4.0, 0.080, 15.2
    for n_rpm in (1500.0, 3000.0):
        # Palmgren: M0 = 1e-7 f0 (nu n)^(2/3) dm^3 [N mm], nu cSt, n rpm, dm mm
        M0 = 1e-7 * f0 * (nu_cst * n_rpm) ** (2 / 3) * (Dm * 1e3) ** 3 / 1e3
        T = float(L.bearing_torque_nm(f0, 0.0, 0.0, Dm, nu_cst * 1e-6, n_rpm * math.pi / 30, 0.0, 0.0, 0.0))
        assert T == pytest.approx(0.978 * M0, rel=1e-9)  # the seed's 9.78e-2 vs Palmgren's 0.1
        assert T == pytest.approx(M0, rel=0.025)
    # below nu n = 2000: Palmgren's floor 160e-7 f0 dm^3 (160 ~ 2000^(2/3) = 158.7)
    M0_floor = 1e-7 * f0 * 2000.0 ** (2 / 3) * (Dm * 1e3) ** 3 / 1e3
    T_low = float(L.bearing_torque_nm(f0, 0.0, 0.0, Dm, nu_cst * 1e-6, 50.0 * math.pi / 30, 0.0, 0.0, 0.0))
    assert T_low == pytest.approx(0.978 * M0_floor, rel=1e-9)
    assert M0_floor == pytest.approx(160e-7 * f0 * 80.0**3 / 1e3, rel=0.01)


def test_bearing_load_terms():
    T = L.bearing_torque_nm(0.0, 4e-4, 2e-3, 0.08, 15e-6, 100.0, 100.0, 5000.0, -800.0)
    assert T == pytest.approx(4e-4 * 5100.0 * 0.08 + 2e-3 * 800.0 * 0.08)


def test_skf_rolling_moment_is_skfs_formula():
    """SKF's rolling frictional moment phi_ish R1 dm^2.41 Fr^0.31 (nu n)^0.6 [N mm] of a cylindrical roller bearing,
    phi_ish = 1 / (1 + 1.84e-9 (n dm)^1.28 nu^0.64), in its own units, from the coefficients per N m of input torque
    and of the bearing's size: it grows as the load's 0.31th power."""
    R1, Dm, P1_per_nm, n_rpm = 1.1e-6, 0.18, 0.07, 1500.0
    c, ish = L.skf_rolling_coef(R1, Dm, P1_per_nm, "cylindrical"), L.skf_inlet_shear_coef(Dm)
    for T_nm, nu_cst in ((1e4, 108.0), (1e6, 108.0), (1e6, 1337.0)):
        Fr_n = P1_per_nm * T_nm
        phi_ish = 1.0 / (1.0 + 1.84e-9 * (n_rpm * 180.0) ** 1.28 * nu_cst**0.64)
        M_rr_nmm = phi_ish * R1 * 180.0**2.41 * Fr_n**0.31 * (nu_cst * n_rpm) ** 0.6
        T = float(L.skf_rolling_torque_nm(c, ish, T_nm, nu_cst * 1e-6, n_rpm * math.pi / 30))
        assert T == pytest.approx(M_rr_nmm / 1e3, rel=1e-12)
        assert 0.3 < phi_ish < 0.9  # a large, fast bearing: cold thick oil (1337 cSt) carries a third of it
    T1, T2 = (float(L.skf_rolling_torque_nm(c, ish, T_nm, 1e-4, 150.0)) for T_nm in (1e5, 2e5))
    assert T2 / T1 == pytest.approx(2.0**0.31)  # Palmgren's load term (Eq 38) would double
    assert float(L.skf_rolling_torque_nm(c, ish, 0.0, 1e-4, 150.0)) == 0.0
    assert float(L.skf_rolling_torque_nm(c, ish, 1e5, 1e-4, 0.0)) == 0.0
    assert float(L.skf_rolling_torque_nm(c, ish, -1e5, 1e-4, -150.0)) == T1  # magnitudes
    # tapered: dm^2.38; a ball bearing's rolling term has another load exponent (0.54): not this one
    assert L.skf_rolling_coef(R1, Dm, P1_per_nm, "tapered") == pytest.approx(c * 180.0 ** (2.38 - 2.41))
    with pytest.raises(ParameterError, match="bearing.R1_ball"):
        L.skf_rolling_coef(R1, Dm, P1_per_nm, "ball")


def test_needle_bearing_relative_speed():
    f0, Dm, nu = 3.0, 0.06, 25.8e-6
    T = L.needle_bearing_torque_nm(f0, Dm, nu, np.array([0.0, 100.0, -100.0]))
    n = 100.0 * 30 / math.pi
    assert T[1] == pytest.approx(9.78e-2 * f0 * Dm**3 * (25.8 * n) ** (2 / 3))
    assert T[2] == T[1]
    assert T[0] * 0.0 == 0.0 and T[0] < T[1]  # floor torque, zero power at zero relative speed


def test_sync_ring_drag_eq41():
    n, mu, R, w, J, th, dw = 2, 0.0127, 0.06, 0.010, 0.3e-3, 7.0 * DEG, 100.0
    T = L.sync_ring_drag_torque_nm(n, mu, R, w, J, th, dw)
    hand = 2 * 2 * math.pi * 0.0127 * 0.06**3 * 0.010 / (0.3e-3 * math.sin(7 * DEG)) * 100.0
    assert T == pytest.approx(hand)
    assert L.sync_ring_drag_torque_nm(n, mu, R, w, J, th, -dw) == pytest.approx(-hand)


def test_pump_torque_eq42():
    assert L.pump_torque_nm(1000.0, 2e-4) == pytest.approx(0.2)
    np.testing.assert_allclose(L.pump_torque_nm(np.array([0.0, 500.0]), 2e-4), [0.0, 0.1])


# --- heat split and lag ---------------------------------------------------------------------------------------


def test_planetary_split():
    s = L.PLANETARY_HEAT_SPLIT
    assert s["PS"] == pytest.approx(1 / 3) and s["PP"] == pytest.approx(1 / 2) and s["PR"] == pytest.approx(1 / 6)
    assert sum(s.values()) == pytest.approx(1.0, abs=1e-15)
    # derivation: 2/3 of the losses at sun-planet, 1/3 at planet-ring, each contact halved
    assert s["PS"] == pytest.approx(0.5 * 2 / 3) and s["PP"] == pytest.approx(0.5 * 2 / 3 + 0.5 * 1 / 3)
    ps, pp, pr = L.planetary_heat_split(np.array([600.0, 0.0]))
    np.testing.assert_allclose(ps, [200.0, 0.0])
    np.testing.assert_allclose(pp, [300.0, 0.0])
    np.testing.assert_allclose(pr, [100.0, 0.0])


def test_first_order_lag_exact():
    tau, dt, u, y0 = 2.0, 0.37, 5.0, -1.0
    y = y0
    for _ in range(20):
        y = first_order_lag_step(y, u, dt, tau)
    assert y == pytest.approx(u + (y0 - u) * math.exp(-20 * dt / tau), rel=1e-12)
    one = first_order_lag_step(y0, u, 2 * dt, tau)
    two = first_order_lag_step(first_order_lag_step(y0, u, dt, tau), u, dt, tau)
    assert one == pytest.approx(two, rel=1e-12)
    v = first_order_lag_step(np.array([0.0, 0.0, 1.0]), np.array([1.0, 1.0, 3.0]), 0.1, np.array([0.0, 1.0, 1e9]))
    np.testing.assert_allclose(v, [1.0, 1.0 - math.exp(-0.1), 1.0 + 2.0 * (1 - math.exp(-1e-10))], rtol=1e-12)


def test_heat_lag_step_is_exact_and_books_every_joule():
    """The lag's state follows the exact first-order response; the delivered heat is the input minus what the lag
    stores (tau dy / dt), so delivered energy + tau y = input energy; tau <= 0 delivers the input."""
    tau, dt = 1.0, 0.1
    lag = heat_lag(tau, dt)
    rng = np.random.default_rng(5)
    y, stored_in, delivered = np.zeros(3), 0.0, 0.0
    for _ in range(500):
        u = rng.uniform(0.0, 2000.0, 3)
        ref = first_order_lag_step(y, u, dt, tau)
        y_new, d = heat_lag_step(y, u, lag)
        np.testing.assert_allclose(y_new, ref, rtol=1e-12)
        stored_in += u.sum() * dt
        delivered += d.sum() * dt
        y = y_new
    assert delivered + tau * y.sum() == pytest.approx(stored_in, rel=1e-12)
    none = heat_lag(0.0, dt)
    assert heat_lag_step(np.array([5.0]), np.array([7.0]), none).delivered_w[0] == 7.0
