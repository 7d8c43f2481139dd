"""Heat paths of the gearbox thermal network (seed section 3.3, Eq 43-81, Eq 6; the oil cooler of section 3.4 is
firmware_model.physics.cooler).

Pure, vectorised functions of floats or numpy arrays. Conductances are returned in W/K (``G_w_per_k``),
heat transfer coefficients in W/(m2 K), areas in m2; temperatures are degC and converted to kelvin only for
radiation.

Interpretations (see each function): Eq 46/47 bridge between Re = 2.5e5 and 3.2e5; Blok's fling-off
(Eq 54-55) held at psi = 1.5 beyond its range; pipe-flow transition 2300..1e4 (Eq 66/67); flow-stream
effectiveness for oil-system conductances.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from firmware_model.errors import ParameterError
from firmware_model.units import KELVIN_OFFSET_K, SIGMA_W_PER_M2K4

#: degC -> K (owned by firmware_model.units, as is SIGMA_W_PER_M2K4; both names kept here for their readers)
KELVIN_OFFSET = KELVIN_OFFSET_K

#: Eq 46/47 validity limits; between them the two correlations are bridged (see nusselt_rotating_cylinder)
RE_LAMINAR_MAX = 2.5e5
RE_TURBULENT_MIN = 3.2e5
#: Blok's fling-off correlation (Eq 54-55) is given for psi < 1.5
PSI_MAX = 1.5
#: pipe flow (Eq 66-67): laminar below, turbulent above, linear blend in Re between (Gnielinski/VDI practice)
RE_PIPE_LAMINAR_MAX = 2300.0
RE_PIPE_TURBULENT_MIN = 1.0e4
#: fully developed laminar Nusselt number of a channel of infinite aspect ratio (Eq 77)
NU_CHANNEL = 7.54
#: seed's nominal Hertzian contact width (Eq 45) [m] and contact-length share of the tooth width [-]
W_HZ_DEFAULT_M = 0.8e-3
CONTACT_LENGTH_FACTOR = 0.9
#: seed's nominal splash speed (Eq 59) [rpm]
N_NOM_RPM = 1000.0


def _pos(name, value):
    v = np.asarray(value, dtype=float)
    if np.any(~(v > 0.0)):
        raise ParameterError(f"{name} = {value} must be > 0")
    return v


# --- conduction ------------------------------------------------------------------------------------------


def linear_conductance_w_per_k(k_w_per_mk, area_m2, x1_m, x2_m):
    """Linear conduction conductance G = k A / |x2 - x1| [W/K] (Eq 43; Q = G (T2 - T1))."""
    dx = np.abs(np.asarray(x2_m, dtype=float) - np.asarray(x1_m, dtype=float))
    _pos("linear conduction distance |x2 - x1| [m]", dx)
    return np.asarray(k_w_per_mk, dtype=float) * np.asarray(area_m2, dtype=float) / dx  # Eq 43


def radial_conductance_w_per_k(k_w_per_mk, width_m, D_external_m, D_internal_m, sf=1.0):
    """Radial conduction conductance G = sf k 2 pi w / ln(D_ext / D_int) [W/K] (Eq 44).

    sf: the seed's scale factor (1 for solid material, 0.12..0.4 across bearings and splines).
    """
    D_e = np.asarray(D_external_m, dtype=float)
    D_i = _pos("radial conduction D_internal_m [m]", D_internal_m)
    if np.any(~(D_e > D_i)):
        raise ParameterError(
            f"radial conduction D_external_m = {D_external_m} must exceed D_internal_m = {D_internal_m} [m]"
        )
    return (
        sf * np.asarray(k_w_per_mk, dtype=float) * 2.0 * math.pi * np.asarray(width_m, dtype=float) / np.log(D_e / D_i)
    )


def gear_contact_conductance_w_per_k(tcc_w_per_m2k, w_t_m, w_hz_m=W_HZ_DEFAULT_M, length_factor=CONTACT_LENGTH_FACTOR):
    """Thermal contact conductance across a loaded mesh G = TCC (0.9 w_t) w_Hz [W/K] (Eq 45).

    The seed's worked example (0.8 mm, 40 mm, 1e5 W/(m2 K) -> 3.2 W/K) omits the 0.9 contact-length factor
    of Eq 45 itself (1e5 * 0.040 * 0.8e-3 = 3.2); with the factor the same data give 2.88 W/K. The default
    keeps Eq 45; ``length_factor=1.0`` reproduces the example.
    """
    return tcc_w_per_m2k * (length_factor * np.asarray(w_t_m, dtype=float)) * w_hz_m  # Eq 45


# --- convection: immersed rotating bodies ----------------------------------------------------------------


def nusselt_rotating_cylinder(re, pr):
    """Mean Nusselt number of a cylinder rotating in oil (Eq 46-47).

    Nu = 0.4 Re^0.5 Pr^(1/3) below Re = 2.5e5 (Eq 46), 0.238 Re^0.8 Pr^0.6 above 3.2e5 (Eq 47). The seed
    leaves the gap open; there the two correlations are blended geometrically with a weight linear in log Re,
    ``Nu = Nu46^(1-s) Nu47^s``, s = ln(Re/2.5e5)/ln(3.2e5/2.5e5): continuous and monotone in Re.
    """
    re = np.maximum(np.asarray(re, dtype=float), 0.0)
    pr = np.asarray(pr, dtype=float)
    nu46 = 0.4 * np.sqrt(re) * np.cbrt(pr)  # Eq 46
    nu47 = 0.238 * re**0.8 * pr**0.6  # Eq 47
    with np.errstate(divide="ignore"):
        s = np.clip(
            np.log(np.maximum(re, 1e-300) / RE_LAMINAR_MAX) / math.log(RE_TURBULENT_MIN / RE_LAMINAR_MAX), 0.0, 1.0
        )
    with np.errstate(divide="ignore", invalid="ignore"):
        blend = np.exp((1.0 - s) * np.log(nu46) + s * np.log(nu47))
    return np.where(re <= RE_LAMINAR_MAX, nu46, np.where(re >= RE_TURBULENT_MIN, nu47, blend))


def reynolds_gear(R_p_m, omega_rad_s, nu_m2_s):
    """Reynolds number of a wheel rotating in the sump Re = R_p^2 |omega| / nu (Eq 48)."""
    return (
        np.asarray(R_p_m, dtype=float) ** 2
        * np.abs(np.asarray(omega_rad_s, dtype=float))
        / np.asarray(nu_m2_s, dtype=float)
    )


def reynolds_bearing(Dm_m, omega_shaft_rad_s, nu_m2_s):
    """Reynolds number of an immersed bearing Re = Dm^2 |omega| / (4 nu) (Eq 52: length Dm/2, speed omega Dm/2)."""
    return (
        np.asarray(Dm_m, dtype=float) ** 2
        * np.abs(np.asarray(omega_shaft_rad_s, dtype=float))
        / (4.0 * np.asarray(nu_m2_s, dtype=float))
    )


def immersion_angles_rad(R_p_m, R_in_m, h_i_m):
    """Immersion angles theta (Eq 50) and phi (Eq 51) [rad]; phi = 0 when the oil does not reach R_in."""
    R_p = np.asarray(R_p_m, dtype=float)
    R_in = np.asarray(R_in_m, dtype=float)
    h_i = np.asarray(h_i_m, dtype=float)
    theta = 2.0 * np.arccos(np.clip(1.0 - h_i / R_p, -1.0, 1.0))  # Eq 50
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.where(R_in > 0.0, 1.0 - (R_in - (R_p - h_i)) / np.where(R_in > 0.0, R_in, 1.0), 1.0)
    phi = 2.0 * np.arccos(np.clip(c, -1.0, 1.0))  # Eq 51
    return theta, phi


def immersed_gear_area_m2(R_p_m, w_t_m, R_in_m, w_in_m, h_i_m, z, h_t_m, beta_rad):
    """Oil-wetted area of a dipping wheel [m2] (Eq 49-51): rim, inner rim, both sides, tooth flanks."""
    R_p = np.asarray(R_p_m, dtype=float)
    R_in = np.asarray(R_in_m, dtype=float)
    theta, phi = immersion_angles_rad(R_p, R_in, h_i_m)
    return (
        theta * R_p * w_t_m
        + phi * R_in * w_in_m
        + R_p**2 * (theta - np.sin(theta))
        - R_in**2 * (phi - np.sin(phi))
        + z * h_t_m * w_t_m * theta / (np.cos(beta_rad) * math.pi)
    )  # Eq 49


def immersed_bearing_area_m2(D_i_ring_m, D_o_ring_m, n_roller, D_roller_m, w_bearing_m, h_f):
    """Oil-wetted inner area of a dipping bearing pi (D_i + D_o + n D_r) w h_f [m2] (Eq 53)."""
    return (
        math.pi
        * (np.asarray(D_i_ring_m, dtype=float) + D_o_ring_m + n_roller * np.asarray(D_roller_m, dtype=float))
        * w_bearing_m
        * h_f
    )


class FlingOff(NamedTuple):
    hA_w_per_k: np.ndarray | float  # Eq 54-55
    psi: np.ndarray | float  # Eq 56, before holding
    in_range: np.ndarray | bool  # psi < 1.5 (Blok's range)


def fling_off_hA(z, w_t_m, h_t_m, R_p_m, h_i_m, omega_rad_s, k_w_per_mk, alpha_m2_s, nu_m2_s) -> FlingOff:
    """Blok's centrifugal fling-off conductance hA [W/K] of a dipping wheel (Eq 54-58).

    tau = (pi - gamma)/omega (Eq 57), gamma = acos(1 - h_i/R_p) (Eq 58), psi = (R_p alpha (tau omega)^2 /
    (nu h_t))^(1/4) (Eq 56; note tau omega = pi - gamma does not depend on speed). psi < 0.68: factor 1.14
    (Eq 54); 0.68 <= psi < 1.5: factor 1.55 - 0.6 psi (Eq 55). Outside Blok's range (psi >= 1.5, thin hot
    oil) psi is held at 1.5 (factor 0.65) and ``in_range`` is False. omega <= 0 gives 0.
    """
    w = np.abs(np.asarray(omega_rad_s, dtype=float))
    R_p = np.asarray(R_p_m, dtype=float)
    gamma = np.arccos(np.clip(1.0 - np.asarray(h_i_m, dtype=float) / R_p, -1.0, 1.0))  # Eq 58
    tau_w = math.pi - gamma  # Eq 57 times omega
    alpha = np.asarray(alpha_m2_s, dtype=float)
    psi = (R_p * alpha * tau_w**2 / (np.asarray(nu_m2_s, dtype=float) * h_t_m)) ** 0.25  # Eq 56
    in_range = psi < PSI_MAX
    psi_h = np.minimum(psi, PSI_MAX)
    factor = np.where(psi_h < 0.68, 1.14, 1.55 - 0.6 * psi_h)  # Eq 54 / 55
    # omega sqrt(tau) = sqrt(omega (pi - gamma))
    hA = (
        factor
        * z
        * w_t_m
        * h_t_m
        * np.asarray(k_w_per_mk, dtype=float)
        * np.sqrt(w * tau_w)
        / (math.pi * np.sqrt(alpha))
    )
    return FlingOff(hA, psi, in_range)


# --- convection: splashed parts, bearings, housing -------------------------------------------------------


def splash_h_w_per_m2k(speed_rpm, h_nom_w_per_m2k, N_nom_rpm=N_NOM_RPM):
    """Splash heat transfer coefficient h = h_nom (|N| / N_nom)^0.6 [W/(m2 K)] (Eq 59)."""
    return h_nom_w_per_m2k * (np.abs(np.asarray(speed_rpm, dtype=float)) / N_nom_rpm) ** 0.6


def wheel_area_covered_sides_m2(R_p_m, w_t_m, z, h_t_m, beta_rad):
    """Splashed area of a wheel with covered sides 2 (pi R_p w_t + z h_t w_t / cos beta) [m2] (Eq 60)."""
    return 2.0 * (math.pi * np.asarray(R_p_m, dtype=float) * w_t_m + z * h_t_m * w_t_m / np.cos(beta_rad))


def wheel_area_free_sides_m2(R_p_m, w_t_m, z, h_t_m, beta_rad, R_in_m):
    """Splashed area of a wheel with free sides: Eq 60 plus 2 pi (R_p^2 - R_in^2) [m2] (Eq 61)."""
    R_p = np.asarray(R_p_m, dtype=float)
    return wheel_area_covered_sides_m2(R_p, w_t_m, z, h_t_m, beta_rad) + 2.0 * math.pi * (
        R_p**2 - np.asarray(R_in_m, dtype=float) ** 2
    )


def cylinder_area_m2(D_m, L_m):
    """Lateral area of a cylinder pi D L [m2] (Eq 62, output shaft)."""
    return math.pi * np.asarray(D_m, dtype=float) * L_m


def harris_bearing_h_w_per_m2k(omega_shaft_rad_s, nu_m2_s, D_roller_m, Dm_m, k_w_per_mk, pr):
    """Harris's bearing-to-oil coefficient 0.0986 (|omega|/nu (1 - D_r/Dm))^(1/2) k Pr^(1/3) [W/(m2 K)] (Eq 63)."""
    w = np.abs(np.asarray(omega_shaft_rad_s, dtype=float))
    return (
        0.0986
        * np.sqrt(w / np.asarray(nu_m2_s, dtype=float) * (1.0 - D_roller_m / Dm_m))
        * np.asarray(k_w_per_mk, dtype=float)
        * np.cbrt(pr)
    )


def bearing_internal_area_m2(D_i_ring_m, D_o_ring_m, n_roller, D_roller_m, w_bearing_m):
    """Equivalent internal area of a bearing pi (D_i + D_o + n D_r) w [m2] (Eq 64)."""
    return immersed_bearing_area_m2(D_i_ring_m, D_o_ring_m, n_roller, D_roller_m, w_bearing_m, 1.0)


# --- internal convection: oil system ---------------------------------------------------------------------


def pipe_reynolds(mdot_kg_s, mu_pa_s, D_m):
    """Pipe Reynolds number Re = 4 |mdot| / (pi mu D) (Eq 65)."""
    return 4.0 / math.pi * np.abs(np.asarray(mdot_kg_s, dtype=float)) / (np.asarray(mu_pa_s, dtype=float) * D_m)


def pipe_nusselt(re, pr, L_m, D_m, mu_ratio=1.0):
    """Pipe Nusselt number (Eq 66-67), mu_ratio = mu(bulk) / mu(surface).

    Laminar (Eq 66, Sieder-Tate with the 3.66 floor) for Re <= 2300, turbulent (Eq 67) for Re >= 1e4, and
    between them a linear blend in Re of the two correlations (the seed/Amesim transition is not given;
    2300..1e4 is the usual transitional range).
    """
    re = np.asarray(re, dtype=float)
    visc = np.asarray(mu_ratio, dtype=float) ** 0.14
    nu_lam = np.maximum(3.66, 1.86 * np.cbrt(re * pr / (L_m / D_m)) * visc)  # Eq 66
    nu_turb = 0.027 * re**0.8 * np.cbrt(pr) * visc  # Eq 67
    s = np.clip((re - RE_PIPE_LAMINAR_MAX) / (RE_PIPE_TURBULENT_MIN - RE_PIPE_LAMINAR_MAX), 0.0, 1.0)
    return (1.0 - s) * nu_lam + s * nu_turb


def h_from_nusselt_w_per_m2k(nusselt, k_w_per_mk, D_m):
    """Convection coefficient h = Nu k / D [W/(m2 K)] (Eq 68, Eq 78)."""
    return np.asarray(nusselt, dtype=float) * k_w_per_mk / D_m


class Channel(NamedTuple):
    """Cross-section of one oil channel of a bearing."""

    area_m2: np.ndarray | float  # flow area
    perimeter_m: np.ndarray | float  # wetted perimeter


def _needle_channel(r1_m, r2_m, r_r_m, n_roller) -> Channel:
    """The annular gap r1..r2 between two rollers minus the roller's segment: the inner (Eq 69, 70, 73) and the
    outer (Eq 71, 72, 74) channels have the same form."""
    gap = np.asarray(r2_m, dtype=float) - r1_m
    a = np.arccos(np.clip((r_r_m - gap) / r_r_m, -1.0, 1.0))  # Eq 73 / 74
    area = math.pi / n_roller * (np.asarray(r2_m, dtype=float) ** 2 - np.asarray(r1_m, dtype=float) ** 2) - (
        a * r_r_m**2 - r_r_m * np.sin(a) * (r_r_m - gap)
    )  # Eq 69 / 71
    perim = 2.0 * math.pi / n_roller * (np.asarray(r1_m, dtype=float) + r2_m) + 2.0 * r_r_m * (
        a - np.sin(a)
    )  # Eq 70 / 72
    return Channel(area, perim)


def needle_channel_inner(r1i_m, r2i_m, r_r_m, n_roller) -> Channel:
    """Flow area [m2] and wetted perimeter [m] of one inner needle-bearing channel (Eq 69, 70, 73)."""
    return _needle_channel(r1i_m, r2i_m, r_r_m, n_roller)


def needle_channel_outer(r1o_m, r2o_m, r_r_m, n_roller) -> Channel:
    """Flow area [m2] and wetted perimeter [m] of one outer needle-bearing channel (Eq 71, 72, 74)."""
    return _needle_channel(r1o_m, r2o_m, r_r_m, n_roller)


def shaft_bearing_channel(r_i_m, r_o_m, r_r_m, n_roller) -> Channel:
    """Flow area [m2] and wetted perimeter [m] of one shaft-bearing channel (Eq 75, 76)."""
    r_i = np.asarray(r_i_m, dtype=float)
    r_o = np.asarray(r_o_m, dtype=float)
    area = math.pi / n_roller * (r_o**2 - r_i**2) - math.pi * r_r_m**2  # Eq 75
    perim = 2.0 * math.pi / n_roller * (r_i + r_o) + 2.0 * math.pi * r_r_m  # Eq 76
    if np.any(~(area > 0.0)):
        raise ParameterError("shaft bearing channel flow area (Eq 75) must be > 0; check r_i, r_o, r_r and n_roller")
    return Channel(area, perim)


def hydraulic_diameter_m(area_m2, perimeter_m):
    """Hydraulic diameter D_h = 4 A / P [m] (Eq 79)."""
    return 4.0 * np.asarray(area_m2, dtype=float) / np.asarray(perimeter_m, dtype=float)


def channel_h_w_per_m2k(k_w_per_mk, D_h_m):
    """Fully developed laminar channel flow h = 7.54 k / D_h [W/(m2 K)] (Eq 77-78)."""
    return NU_CHANNEL * np.asarray(k_w_per_mk, dtype=float) / np.asarray(D_h_m, dtype=float)


def channel_heat_area_m2(perimeter_m, L_roller_m, n_roller):
    """Bearing-to-oil exchange area P L_roller n_roller [m2] (Eq 80)."""
    return np.asarray(perimeter_m, dtype=float) * L_roller_m * n_roller


def oil_system_conductance_w_per_k(hA_w_per_k, mdot_kg_s, cp_j_per_kgk):
    """Effective conductance of a wall to a flowing oil stream entering at the sump temperature [W/K].

    A stream of capacity C = mdot cp passing a wall of conductance hA at uniform wall temperature leaves
    with effectiveness 1 - exp(-hA/C) (NTU method), so Q = C (1 - exp(-hA/C)) (T_wall - T_in):
    hA_eff -> hA for a large flow and -> C for a small one (the stream cannot absorb more than C dT).
    mdot = 0 gives 0.
    """
    hA = np.asarray(hA_w_per_k, dtype=float)
    C = np.abs(np.asarray(mdot_kg_s, dtype=float)) * cp_j_per_kgk
    with np.errstate(divide="ignore", invalid="ignore"):
        eff = np.where(C > 0.0, C * -np.expm1(-hA / np.where(C > 0.0, C, 1.0)), 0.0)
    return eff


# --- radiation -------------------------------------------------------------------------------------------


def radiation_h_w_per_m2k(eps, T1_c, T2_c):
    """Linearised radiation coefficient eps sigma (T1^2 + T2^2)(T1 + T2), T in K [W/(m2 K)] (Eq 81)."""
    T1 = np.asarray(T1_c, dtype=float) + KELVIN_OFFSET
    T2 = np.asarray(T2_c, dtype=float) + KELVIN_OFFSET
    return eps * SIGMA_W_PER_M2K4 * (T1 * T1 + T2 * T2) * (T1 + T2)  # Eq 81


def radiation_heat_w(eps, area_m2, T1_c, T2_c):
    """Net radiation from a body at T1 enclosed by surroundings at T2: eps sigma A (T1^4 - T2^4) [W] (Eq 6)."""
    T1 = np.asarray(T1_c, dtype=float) + KELVIN_OFFSET
    T2 = np.asarray(T2_c, dtype=float) + KELVIN_OFFSET
    return eps * SIGMA_W_PER_M2K4 * np.asarray(area_m2, dtype=float) * (T1**4 - T2**4)  # Eq 6
