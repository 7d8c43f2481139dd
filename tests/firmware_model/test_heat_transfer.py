"""Heat paths (seed sections 3.3, 3.4) against hand calculations."""

import math

import numpy as np
import pytest

from firmware_model.errors import ParameterError
from firmware_model.physics import heat_transfer as H

SIGMA = 5.670374419e-8


def test_linear_conduction_eq43():
    assert H.linear_conductance_w_per_k(45.0, 2e-3, 0.10, 0.25) == pytest.approx(45.0 * 2e-3 / 0.15)
    with pytest.raises(ParameterError):
        H.linear_conductance_w_per_k(45.0, 2e-3, 0.1, 0.1)


def test_radial_conduction_eq44():
    hand = 45.0 * 2 * math.pi * 0.03 / math.log(0.12 / 0.05)
    assert H.radial_conductance_w_per_k(45.0, 0.03, 0.12, 0.05) == pytest.approx(hand)
    assert H.radial_conductance_w_per_k(45.0, 0.03, 0.12, 0.05, sf=0.12) == pytest.approx(0.12 * hand)
    with pytest.raises(ParameterError):
        H.radial_conductance_w_per_k(45.0, 0.03, 0.05, 0.05)


def test_gear_contact_eq45_seed_example():
    # seed: 0.8 mm contact width, 40 mm wheel width, TCC 1e5 W/(m2 K) -> "3.2 W/K" = 1e5 * 0.040 * 0.8e-3
    assert H.gear_contact_conductance_w_per_k(1e5, 0.040, 0.8e-3, length_factor=1.0) == pytest.approx(3.2, rel=1e-12)
    # Eq 45 itself has the 0.9 contact-length factor: 1e5 * 0.9 * 0.040 * 0.8e-3 = 2.88 W/K
    assert H.gear_contact_conductance_w_per_k(1e5, 0.040) == pytest.approx(2.88, rel=1e-12)


def test_nusselt_rotating_cylinder_branches_and_continuity():
    pr = 200.0
    assert H.nusselt_rotating_cylinder(1e4, pr) == pytest.approx(0.4 * 100.0 * 200.0 ** (1 / 3))
    assert H.nusselt_rotating_cylinder(1e6, pr) == pytest.approx(0.238 * 1e6**0.8 * 200.0**0.6)
    for re_edge in (2.5e5, 3.2e5):
        lo = H.nusselt_rotating_cylinder(re_edge * (1 - 1e-9), pr)
        hi = H.nusselt_rotating_cylinder(re_edge * (1 + 1e-9), pr)
        assert lo == pytest.approx(hi, rel=1e-6)
    re = np.geomspace(1e3, 1e7, 4000)
    nu = H.nusselt_rotating_cylinder(re, pr)
    assert np.all(np.diff(nu) > 0)
    # geometric mid-point of the gap
    mid = math.sqrt(2.5e5 * 3.2e5)
    expect = math.sqrt(0.4 * mid**0.5 * pr ** (1 / 3) * 0.238 * mid**0.8 * pr**0.6)
    assert H.nusselt_rotating_cylinder(mid, pr) == pytest.approx(expect, rel=1e-9)
    assert H.nusselt_rotating_cylinder(0.0, pr) == 0.0


def test_reynolds_eq48_eq52():
    assert H.reynolds_gear(0.1, 150.0, 15e-6) == pytest.approx(0.01 * 150 / 15e-6)
    assert H.reynolds_bearing(0.08, 150.0, 15e-6) == pytest.approx((0.04**2) * 150 / 15e-6)


def test_immersed_gear_area_eq49():
    R_p, w_t, R_in, w_in, z, h_t, beta = 0.1, 0.04, 0.06, 0.02, 40, 0.01, 0.35
    # half immersion of the pitch circle: theta = pi; oil reaches 0.06 - 0.0 = 0.06 -> phi = pi
    h_i = 0.1
    A = H.immersed_gear_area_m2(R_p, w_t, R_in, w_in, h_i, z, h_t, beta)
    hand = (
        math.pi * R_p * w_t
        + math.pi * R_in * w_in
        + R_p**2 * math.pi
        - R_in**2 * math.pi
        + z * h_t * w_t * math.pi / (math.cos(beta) * math.pi)
    )
    assert A == pytest.approx(hand)
    # shallow dip (20 mm) does not reach R_in: phi = 0
    theta = 2 * math.acos(1 - 0.02 / R_p)
    A2 = H.immersed_gear_area_m2(R_p, w_t, R_in, w_in, 0.02, z, h_t, beta)
    hand2 = theta * R_p * w_t + R_p**2 * (theta - math.sin(theta)) + z * h_t * w_t * theta / (math.cos(beta) * math.pi)
    assert A2 == pytest.approx(hand2)
    th, ph = H.immersion_angles_rad(R_p, R_in, 0.06)  # oil 20 mm into the inner radius
    assert ph == pytest.approx(2 * math.acos(1 - 0.02 / 0.06))


def test_bearing_areas_eq53_eq64():
    A = H.bearing_internal_area_m2(0.06, 0.11, 18, 0.012, 0.03)
    assert A == pytest.approx(math.pi * (0.06 + 0.11 + 18 * 0.012) * 0.03)
    assert H.immersed_bearing_area_m2(0.06, 0.11, 18, 0.012, 0.03, 0.3) == pytest.approx(0.3 * A)


def test_fling_off_eq54_58():
    z, w_t, h_t, R_p, h_i, w, k, alpha, nu = 40, 0.04, 0.01, 0.1, 0.03, 150.0, 0.13, 7e-8, 50e-6
    gamma = math.acos(1 - h_i / R_p)
    tau = (math.pi - gamma) / w
    psi = (R_p * alpha * (tau * w) ** 2 / (nu * h_t)) ** 0.25
    assert psi < 0.68
    hA = 1.14 * z * w_t * h_t * k * w * math.sqrt(tau) / (math.pi * math.sqrt(alpha))
    r = H.fling_off_hA(z, w_t, h_t, R_p, h_i, w, k, alpha, nu)
    assert r.psi == pytest.approx(psi) and bool(r.in_range)
    assert r.hA_w_per_k == pytest.approx(hA)
    # thinner oil: 0.68 < psi < 1.5 -> Eq 55
    nu2 = 5e-6
    psi2 = (R_p * alpha * (tau * w) ** 2 / (nu2 * h_t)) ** 0.25
    assert 0.68 < psi2 < 1.5
    r2 = H.fling_off_hA(z, w_t, h_t, R_p, h_i, w, k, alpha, nu2)
    assert r2.hA_w_per_k == pytest.approx((1.55 - 0.6 * psi2) / 1.14 * hA)
    # outside Blok's range: psi held at 1.5 and flagged
    r3 = H.fling_off_hA(z, w_t, h_t, R_p, h_i, w, k, alpha, 1e-7)
    assert r3.psi > 1.5 and not bool(r3.in_range)
    assert r3.hA_w_per_k == pytest.approx((1.55 - 0.6 * 1.5) / 1.14 * hA)
    assert H.fling_off_hA(z, w_t, h_t, R_p, h_i, 0.0, k, alpha, nu).hA_w_per_k == 0.0


def test_splash_and_areas_eq59_62():
    assert H.splash_h_w_per_m2k(1000.0, 325.0) == pytest.approx(325.0)
    assert H.splash_h_w_per_m2k(2000.0, 325.0, 1000.0) == pytest.approx(325.0 * 2**0.6)
    assert H.splash_h_w_per_m2k(0.0, 325.0) == 0.0
    Ac = H.wheel_area_covered_sides_m2(0.08, 0.03, 35, 0.01, 0.3)
    assert Ac == pytest.approx(2 * (math.pi * 0.08 * 0.03 + 35 * 0.01 * 0.03 / math.cos(0.3)))
    Af = H.wheel_area_free_sides_m2(0.08, 0.03, 35, 0.01, 0.3, 0.05)
    assert Af == pytest.approx(Ac + 2 * math.pi * (0.08**2 - 0.05**2))
    assert H.cylinder_area_m2(0.07, 0.2) == pytest.approx(math.pi * 0.07 * 0.2)


def test_harris_eq63():
    h = H.harris_bearing_h_w_per_m2k(150.0, 15e-6, 0.012, 0.085, 0.127, 224.0)
    assert h == pytest.approx(0.0986 * math.sqrt(150 / 15e-6 * (1 - 0.012 / 0.085)) * 0.127 * 224 ** (1 / 3))
    assert 50 < h < 1000


def test_pipe_flow_eq65_68():
    assert H.pipe_reynolds(0.02, 0.0127, 0.01) == pytest.approx(4 / math.pi * 0.02 / (0.0127 * 0.01))
    # laminar floor and Graetz branch
    assert H.pipe_nusselt(10.0, 200.0, 1.0, 0.01) == pytest.approx(max(3.66, 1.86 * (10 * 200 / 100) ** (1 / 3)))
    assert H.pipe_nusselt(1.0, 1.0, 1.0, 0.01) == pytest.approx(3.66)
    assert H.pipe_nusselt(1000.0, 200.0, 0.2, 0.01, mu_ratio=1.5) == pytest.approx(
        1.86 * (1000 * 200 / 20) ** (1 / 3) * 1.5**0.14
    )
    assert H.pipe_nusselt(2e4, 100.0, 1.0, 0.01) == pytest.approx(0.027 * 2e4**0.8 * 100 ** (1 / 3))
    for re_edge in (2300.0, 1e4):
        assert H.pipe_nusselt(re_edge * (1 - 1e-9), 100.0, 1.0, 0.01) == pytest.approx(
            H.pipe_nusselt(re_edge * (1 + 1e-9), 100.0, 1.0, 0.01), rel=1e-6
        )
    assert H.h_from_nusselt_w_per_m2k(3.66, 0.127, 0.01) == pytest.approx(3.66 * 0.127 / 0.01)


def test_bearing_channels_eq69_80():
    # needle: gap equal to the roller radius -> alpha = pi/2, the roller takes half a disc
    n, r1, r2, rr = 20, 0.030, 0.0325, 0.0025
    A, P = H.needle_channel_inner(r1, r2, rr, n)
    assert A == pytest.approx(math.pi / n * (r2**2 - r1**2) - math.pi / 2 * rr**2)
    assert P == pytest.approx(2 * math.pi / n * (r1 + r2) + 2 * rr * (math.pi / 2 - 1))
    Ao, Po = H.needle_channel_outer(0.034, 0.035, rr, n)  # gap 1 mm -> beta = acos(1.5/2.5)
    b = math.acos(1.5 / 2.5)
    assert Ao == pytest.approx(math.pi / n * (0.035**2 - 0.034**2) - (b * rr**2 - rr * math.sin(b) * 1.5e-3))
    assert Po == pytest.approx(2 * math.pi / n * 0.069 + 2 * rr * (b - math.sin(b)))
    As, Ps = H.shaft_bearing_channel(0.04, 0.055, 0.006, 16)
    assert As == pytest.approx(math.pi / 16 * (0.055**2 - 0.04**2) - math.pi * 0.006**2)
    assert Ps == pytest.approx(2 * math.pi / 16 * 0.095 + 2 * math.pi * 0.006)
    D_h = H.hydraulic_diameter_m(As, Ps)
    assert D_h == pytest.approx(4 * As / Ps)
    assert H.channel_h_w_per_m2k(0.127, D_h) == pytest.approx(7.54 * 0.127 / D_h)
    assert H.channel_heat_area_m2(Ps, 0.02, 16) == pytest.approx(Ps * 0.02 * 16)
    with pytest.raises(ParameterError):
        H.shaft_bearing_channel(0.04, 0.041, 0.006, 16)


def test_radiation_eq81_seed_value_and_eq6():
    # seed: 0.5 * 5.67e-8 * (383.15^2 + 363.15^2)(383.15 + 363.15) = 5.9 W/(m2 K)
    seed_hand = 0.5 * 5.67e-8 * (383.15**2 + 363.15**2) * (383.15 + 363.15)
    assert round(seed_hand, 1) == 5.9
    h = H.radiation_h_w_per_m2k(0.5, 110.0, 90.0)
    assert round(float(h), 1) == 5.9
    assert h == pytest.approx(seed_hand * SIGMA / 5.67e-8, rel=1e-12)
    # Eq 6 with the linearised coefficient is exact: h (T1 - T2) = eps sigma (T1^4 - T2^4)
    Q = H.radiation_heat_w(0.8, 2.4, 80.0, 25.0)
    assert Q == pytest.approx(0.8 * SIGMA * 2.4 * (353.15**4 - 298.15**4))
    assert Q == pytest.approx(H.radiation_h_w_per_m2k(0.8, 80.0, 25.0) * 2.4 * 55.0, rel=1e-12)


def test_oil_system_conductance_effectiveness():
    hA, cp = 50.0, 2000.0
    assert H.oil_system_conductance_w_per_k(hA, 0.01, cp) == pytest.approx(20.0 * (1 - math.exp(-2.5)))
    assert H.oil_system_conductance_w_per_k(hA, 100.0, cp) == pytest.approx(hA, rel=1e-3)
    assert H.oil_system_conductance_w_per_k(hA, 1e-5, cp) == pytest.approx(1e-5 * cp, rel=1e-6)
    assert H.oil_system_conductance_w_per_k(hA, 0.0, cp) == 0.0
