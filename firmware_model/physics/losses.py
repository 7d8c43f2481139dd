"""Mechanical losses of the gearbox (seed section 3.2, Eq 7-42) as pure, vectorised functions.

All inputs are SI (N m, rad/s, m, Pa, Pa s, kg/m3, m2/s) except where a name says otherwise
(``speed_ls_rpm``). Every function broadcasts over numpy arrays of its load/speed/oil inputs; the gear
geometry is a frozen ``GearMesh`` built once by ``mesh_geometry``.

Where the seed's printed formulas are garbled or ambiguous (Eq 9, 10, 12/13, 16, 18, 20, 40), docs/physics.md,
"Mechanical losses", says how each is read here and why; the equation numbers stand in the code that implements them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from firmware_model.errors import ParameterError
from firmware_model.units import RPM_PER_RAD_S

#: gravitational acceleration [m/s2] (Eq 27)
G_M_S2 = 9.80665
#: clip band of the Benedict-Kelley slipping coefficient (Eq 9) [-]
F_G_MIN = 0.005
F_G_MAX = 0.15
#: Benedict-Kelley constants (Eq 9); BK_C is empirical, for F_nu in N/m, mu in Pa s, speeds in m/s
BK_A = 0.0127
BK_C = 0.02912
#: rolling-force constant of Eq 15 [Pa]
ROLL_C_PA = 9.0e7
#: below this torque on wheel 1 of one contact [N m] (assumed) the rolling loss (Eq 14-22) is the loss at this torque
#: scaled by T / ROLL_TORQUE_MIN_NM: Dowson-Higginson's film (Eq 18, load^-0.13) has no lower limit of load and grows
#: without bound as the load vanishes (a torque of 1e-40 N m gave 1.6e5 times the loss, and the onboard step's
#: temperatures ran to 280 degC or NaN on one such sample), while zero torque gives no loss; the ramp joins the two
#: continuously. 1 N m is a small fraction of any torque the engine signal resolves (J1939: 1 % of the reference
#: torque, ~30 N m at the engine, more at the wheels).
ROLL_TORQUE_MIN_NM = 1.0
#: ISO 53 basic rack: addendum and dedendum coefficients [-]
ADDENDUM_COEF = 1.0
DEDENDUM_COEF = 1.25
#: Palmgren oil-shear constant as printed in the seed (Eq 36-37), for nu in cSt, n in rpm, Dm in m -> N m
PALMGREN_SEED_C = 9.78e-2
#: Palmgren threshold of nu*n [cSt rpm] (Eq 36-37)
PALMGREN_NU_N_MIN = 2000.0
#: SKF's rolling frictional moment M_rr = R1 dm^a P^0.31 (nu n)^0.6 [N mm] (dm mm, load N, nu cSt, n rpm): the
#: exponents of the load and of nu n, and of dm by bearing kind (SKF General Catalogue, friction: the SKF model's
#: rolling term, its G_rr). Not in the seed: an optional term (bearing.R1_<kind>, none where absent).
SKF_RR_LOAD_EXP = 0.31
SKF_RR_NU_N_EXP = 0.6
SKF_RR_DM_EXP = {"cylindrical": 2.41, "tapered": 2.38, "spherical": 2.3}
#: ... times SKF's inlet shear heating reduction factor 1 / (1 + 1.84e-9 (n dm)^1.28 nu^0.64) (the same source), written
#: as 1 / (1 + c (n^2 nu)^0.64) with c = 1.84e-9 dm^1.28 (one power per step)
SKF_ISH_C = 1.84e-9
SKF_ISH_EXP = 0.64

#: share of planetary losses sent to sun (PS), planets (PP) and ring (PR) (section 3.2).
#: Looman's rule as used at Scania: the sun-planet (external) contacts lose twice as much as the
#: planet-ring (internal) contacts -> 2/3 and 1/3 of the losses; each contact's heat is split equally
#: between its two wheels: sun 1/2*2/3 = 1/3, planets 1/2*2/3 + 1/2*1/3 = 1/2, ring 1/2*1/3 = 1/6.
PLANETARY_HEAT_SPLIT = {"PS": 1.0 / 3.0, "PP": 1.0 / 2.0, "PR": 1.0 / 6.0}


@dataclass(frozen=True)
class GearMesh:
    """Geometry of one gear mesh, wheel 1 driving wheel 2. Lengths in m, angles in rad."""

    z1: int
    z2: int
    m_n_m: float
    alpha_n_rad: float
    beta_rad: float
    center_distance_m: float
    face_width_m: float
    internal: bool
    x1: float
    x2: float
    m_t_m: float  # transverse module
    alpha_t_rad: float  # transverse pressure angle
    beta_b_rad: float  # base helix angle
    R_p1_m: float  # reference pitch radii
    R_p2_m: float
    R_b1_m: float  # base radii
    R_b2_m: float
    R_a1_m: float  # tip radii (ring: inside its pitch circle)
    R_a2_m: float
    R_f1_m: float  # root radii (ring: outside its pitch circle)
    R_f2_m: float
    alpha_tw_rad: float  # working transverse pressure angle (Eq 17)
    R_w1_m: float  # working pitch radii
    R_w2_m: float
    g_f_m: float  # length of approach (limited by the driven wheel's tip)
    g_a_m: float  # length of recession (limited by the driving wheel's tip)
    L_a_m: float  # length of action (Eq 11)
    h_t_m: float  # tooth height (addendum + dedendum)
    eps_alpha: float  # transverse contact ratio L_a / p_bt [-]


def _check_mesh_inputs(z1: int, z2: int, m_n: float, a_n: float, beta: float, a: float, b: float, internal: bool):
    """One-sentence ParameterError for an impossible mesh (teeth, module, angles, width, centre distance)."""
    if z1 < 5 or z2 < 5:
        raise ParameterError(f"mesh teeth numbers z1 = {z1}, z2 = {z2} must both be >= 5 [-]")
    if not m_n > 0.0:
        raise ParameterError(f"mesh m_n_m = {m_n} must be > 0 [m]")
    if not 0.0 < a_n < math.pi / 2:
        raise ParameterError(f"mesh alpha_n_rad = {a_n} must be in (0, pi/2) [rad]")
    if not abs(beta) < math.pi / 2:
        raise ParameterError(f"mesh beta_rad = {beta} must be in (-pi/2, pi/2) [rad]")
    if not b > 0.0:
        raise ParameterError(f"mesh face_width_m = {b} must be > 0 [m]")
    if not a > 0.0:
        raise ParameterError(f"mesh center_distance_m = {a} must be > 0 [m]")
    if internal and z2 <= z1:
        raise ParameterError(f"internal mesh ring z2 = {z2} must exceed planet z1 = {z1} [-]")


def _path_of_contact(R_b1, R_b2, R_a1, R_a2, base_span, a, sign):
    """Working pressure angle, working radii and the lengths of approach and recession (Eq 12-13, 17) of a mesh
    whose wheels have base radii ``R_b*`` and tip radii ``R_a*``; ``sign`` is -1 for an internal mesh."""
    alpha_tw = math.acos(base_span / a)  # Eq 17
    R_w1 = R_b1 / math.cos(alpha_tw)
    R_w2 = R_b2 / math.cos(alpha_tw)
    sin_tw = math.sin(alpha_tw)
    # Eq 12-13 reconstructed with their square roots (docs/physics.md says which tip limits which)
    g_a = math.sqrt(R_a1**2 - R_b1**2) - R_w1 * sin_tw
    g_f = sign * (math.sqrt(R_a2**2 - R_b2**2) - R_w2 * sin_tw)
    if g_f <= 0.0 or g_a <= 0.0:
        raise ParameterError(
            f"mesh lengths of approach {g_f:.6g} m and recession {g_a:.6g} m must both be > 0 "
            "(tips do not reach the line of action)"
        )
    # curvature radii at the ends of contact must stay positive (no involute interference)
    rho1_start = R_w1 * sin_tw - g_f
    rho2_end = R_w2 * sin_tw - sign * g_a
    if rho1_start <= 0.0 or rho2_end <= 0.0:
        raise ParameterError(
            "mesh path of contact runs past a base-circle tangent point (involute interference: too few teeth on "
            "the pinion for its pressure angle and helix without a profile shift, which the model does not take); "
            "give the pinion more teeth or check the centre distance"
        )
    return alpha_tw, R_w1, R_w2, g_f, g_a


def mesh_geometry(
    z1, z2, m_n_m, alpha_n_rad, beta_rad, center_distance_m, face_width_m, internal=False, x1=0.0, x2=0.0
) -> GearMesh:
    """Build the geometry of a mesh (Eq 11-13, 17), wheel 1 driving wheel 2.

    ``internal=True`` is a planet (1, external teeth) meshing with a ring (2, internal teeth).
    Tooth proportions follow the ISO 53 basic rack with profile shift x: addendum ``m_n (1 + x)``,
    dedendum ``m_n (1.25 - x)``, tooth height ``2.25 m_n`` (no tip shortening). For the ring the addendum
    is measured inwards: ``R_a2 = R_p2 - m_n (1 + x2)``, ``R_f2 = R_p2 + m_n (1.25 - x2)``.
    Raises ParameterError when the geometry is impossible.
    """
    z1 = int(z1)
    z2 = int(z2)
    m_n = float(m_n_m)
    a_n = float(alpha_n_rad)
    beta = float(beta_rad)
    a = float(center_distance_m)
    b = float(face_width_m)
    x1 = float(x1)
    x2 = float(x2)
    _check_mesh_inputs(z1, z2, m_n, a_n, beta, a, b, internal)
    beta = abs(beta)
    m_t = m_n / math.cos(beta)
    alpha_t = math.atan(math.tan(a_n) / math.cos(beta))
    beta_b = math.asin(math.sin(beta) * math.cos(a_n))
    R_p1 = 0.5 * z1 * m_t
    R_p2 = 0.5 * z2 * m_t
    R_b1 = R_p1 * math.cos(alpha_t)
    R_b2 = R_p2 * math.cos(alpha_t)
    R_a1 = R_p1 + m_n * (ADDENDUM_COEF + x1)
    R_f1 = R_p1 - m_n * (DEDENDUM_COEF - x1)
    if internal:
        R_a2 = R_p2 - m_n * (ADDENDUM_COEF + x2)
        R_f2 = R_p2 + m_n * (DEDENDUM_COEF - x2)
        base_span = R_b2 - R_b1  # Eq 17, internal form
        sign = -1.0
    else:
        R_a2 = R_p2 + m_n * (ADDENDUM_COEF + x2)
        R_f2 = R_p2 - m_n * (DEDENDUM_COEF - x2)
        base_span = R_b1 + R_b2  # Eq 17
        sign = 1.0
    if base_span >= a:
        raise ParameterError(
            f"mesh base radii {'difference' if internal else 'sum'} {base_span:.6g} m must be below the "
            f"centre distance {a:.6g} m"
        )
    if R_a2 <= R_b2 or R_a1 <= R_b1:
        raise ParameterError("mesh tip radius must lie outside the base circle on both wheels")
    alpha_tw, R_w1, R_w2, g_f, g_a = _path_of_contact(R_b1, R_b2, R_a1, R_a2, base_span, a, sign)
    L_a = g_f + g_a  # Eq 11
    p_bt = math.pi * m_t * math.cos(alpha_t)
    given = (z1, z2, m_n, a_n, beta, a, b, bool(internal), x1, x2)
    circles = (m_t, alpha_t, beta_b, R_p1, R_p2, R_b1, R_b2, R_a1, R_a2, R_f1, R_f2)
    contact = (alpha_tw, R_w1, R_w2, g_f, g_a, L_a, m_n * (ADDENDUM_COEF + DEDENDUM_COEF), L_a / p_bt)
    return GearMesh(*given, *circles, *contact)


@lru_cache(maxsize=256)
def _line_nodes(g_f, g_a, n):
    """Gauss-Legendre nodes d (signed distance from the pitch point) and weights / L_a, split at d = 0."""
    t, w = np.polynomial.legendre.leggauss(n)
    d = np.concatenate((-g_f * 0.5 * (1.0 - t), g_a * 0.5 * (1.0 + t)))
    L_a = g_f + g_a
    wt = np.concatenate((w * 0.5 * g_f, w * 0.5 * g_a)) / L_a
    d.setflags(write=False)
    wt.setflags(write=False)
    return d, wt


def _mesh_kinematics(mesh, n_points):
    d, wt = _line_nodes(mesh.g_f_m, mesh.g_a_m, int(n_points))
    s = -1.0 if mesh.internal else 1.0
    u = mesh.z2 / mesh.z1
    vg_per_w2 = np.abs(d) * (u + s)  # Eq 10 (exact form)
    vr_per_w2 = 2.0 * mesh.R_w2_m * math.sin(mesh.alpha_tw_rad) + d * (u - s)  # Eq 16 (exact form)
    return d, wt, s, vg_per_w2, vr_per_w2


def _normal_force(mesh, torque1_nm):
    F_t = np.abs(torque1_nm) / mesh.R_w1_m
    F_n = F_t / (math.cos(mesh.alpha_n_rad) * math.cos(mesh.beta_rad))  # Eq 8
    F_nu = F_n * math.cos(mesh.beta_b_rad) / mesh.face_width_m  # per unit contact length
    return F_n, F_nu


def gear_slip_loss_w(mesh: GearMesh, torque1_nm, omega2_rad_s, rho_kg_m3, mu_pa_s, n_points=20):
    """Sliding (friction) power loss of a loaded mesh [W], Eq 7-10 integrated along the line of action.

    ``torque1_nm``: torque on the driving wheel 1 (sign ignored); ``omega2_rad_s``: speed of the driven
    wheel 2 (sign ignored); ``mu_pa_s``: dynamic viscosity of the oil. ``n_points``: Gauss-Legendre points
    on each side of the pitch point. Zero torque or speed gives 0. Broadcasts over torque/speed/oil.
    For a planetary mesh pass the speed relative to the carrier.
    """
    _, wt, _, vg_per_w2, vr_per_w2 = _mesh_kinematics(mesh, n_points)
    T = np.asarray(torque1_nm, dtype=float)[..., None]
    w2 = np.abs(np.asarray(omega2_rad_s, dtype=float))[..., None]
    rho = np.asarray(rho_kg_m3, dtype=float)[..., None]
    mu = np.asarray(mu_pa_s, dtype=float)[..., None]
    F_n, F_nu = _normal_force(mesh, T)
    V_g = w2 * vg_per_w2
    V_r = w2 * vr_per_w2
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        nu = mu / rho
        f_g = BK_A * np.log10(BK_C * F_nu / (rho * nu * V_g * V_r * V_r))  # Eq 9 (rho nu = mu)
    f_g = np.where(np.isnan(f_g), F_G_MIN, np.clip(f_g, F_G_MIN, F_G_MAX))  # NaN -> F_G_MIN; +-inf clipped
    P = np.sum(wt * F_n * f_g * V_g, axis=-1)  # Eq 7
    return np.where((T[..., 0] == 0.0) | (w2[..., 0] == 0.0), 0.0, P)


def gear_slip_coefficient(mesh: GearMesh, torque1_nm, omega2_rad_s, rho_kg_m3, mu_pa_s, n_points=20):
    """Load-weighted mean Benedict-Kelley coefficient over the line of action [-] (diagnostic): P_g / (F_n mean V_g)."""
    _, wt, _, vg_per_w2, _ = _mesh_kinematics(mesh, n_points)
    P = gear_slip_loss_w(mesh, torque1_nm, omega2_rad_s, rho_kg_m3, mu_pa_s, n_points)
    F_n, _ = _normal_force(mesh, np.asarray(torque1_nm, dtype=float))
    vg_mean = np.abs(np.asarray(omega2_rad_s, dtype=float)) * float(np.sum(wt * vg_per_w2))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(F_n * vg_mean > 0.0, P / (F_n * vg_mean), 0.0)


def equivalent_modulus_pa(E1_pa, E2_pa, nu1, nu2):
    """Equivalent (reduced) modulus E' = 2 / ((1 - nu1^2)/E1 + (1 - nu2^2)/E2) [Pa] (Eq 19)."""
    return 2.0 / ((1.0 - nu1 * nu1) / E1_pa + (1.0 - nu2 * nu2) / E2_pa)


def gear_rolling_loss_w(
    mesh: GearMesh, torque1_nm, omega2_rad_s, mu_pa_s, piezo_per_pa, E1_pa, E2_pa, nu1, nu2, n_points=20
):
    """Rolling (EHL film) power loss of a loaded mesh [W], Eq 14-22 (order of 1..10 W, negligible).

    Zero torque or speed gives 0; below ROLL_TORQUE_MIN_NM the loss at that torque scaled by T / ROLL_TORQUE_MIN_NM
    (Eq 18 alone grows without bound as the load vanishes). Broadcasts over torque/speed/oil. Planetary meshes:
    carrier-relative speed.
    """
    d, wt, s, _, vr_per_w2 = _mesh_kinematics(mesh, n_points)
    T = np.asarray(torque1_nm, dtype=float)[..., None]
    w2 = np.abs(np.asarray(omega2_rad_s, dtype=float))[..., None]
    mu = np.asarray(mu_pa_s, dtype=float)[..., None]
    ap = np.asarray(piezo_per_pa, dtype=float)[..., None]
    E_eq = equivalent_modulus_pa(E1_pa, E2_pa, nu1, nu2)  # Eq 19
    _, F_nu = _normal_force(mesh, T)
    F_nu = np.maximum(F_nu, _normal_force(mesh, np.asarray(ROLL_TORQUE_MIN_NM))[1])  # the film at T_min below it
    V_r = w2 * vr_per_w2  # Eq 16
    c = math.cos(mesh.alpha_t_rad) / (math.cos(mesh.beta_rad) * math.cos(mesh.alpha_n_rad))  # = 1/cos(beta_b)
    sin_tw = math.sin(mesh.alpha_tw_rad)
    X1 = c * (mesh.R_w1_m * sin_tw + d)  # Eq 21
    X2 = c * (mesh.R_w2_m * sin_tw - s * d)  # Eq 22 (internal: concave ring, rho2 grows with d)
    X_eq = X1 * X2 / (X2 + s * X1)  # Eq 20 (internal: X1 X2 / (X2 - X1))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        e_h = (
            X_eq
            * 2.65
            * (mu * V_r / (2.0 * E_eq * X_eq)) ** 0.7
            * (ap * E_eq) ** 0.54
            * (F_nu / (E_eq * X_eq)) ** -0.13
        )  # Eq 18
        F_r = ROLL_C_PA * e_h * mesh.face_width_m / math.cos(mesh.beta_rad)  # Eq 15
        P = np.sum(wt * F_r * V_r, axis=-1)  # Eq 14
    P = P * np.minimum(np.abs(T[..., 0]) / ROLL_TORQUE_MIN_NM, 1.0)  # ROLL_TORQUE_MIN_NM: the ramp to 0
    return np.where((T[..., 0] == 0.0) | (w2[..., 0] == 0.0), 0.0, P)


class ChurningResult(NamedTuple):
    """Churning loss of one immersed wheel (Eq 23-34). Regime 0 and valid False where omega <= 0."""

    power_w: np.ndarray | float
    C_side_nm: np.ndarray | float
    C_teeth_nm: np.ndarray | float
    cmd_regime: np.ndarray | int  # 28, 29 or 30
    cma_regime: np.ndarray | int  # 31 or 32
    valid: np.ndarray | bool  # inside the ranges of Eq 33 and Eq 34


#: reference tooth height h_t0 of the Cma correlation [m]: the seed's "widths only defined up to 14.4 mm"
#: is Eq 34's ``w_t / h_t0 < 1.8`` with h_t0 = 8 mm
CHURN_H_T0_M = 8.0e-3


def churning_loss(
    omega_rad_s, R_a_m, R_p_m, h_t_m, w_t_m, h_i_m, V_p_m3, V_0_m3, rho_kg_m3, nu_m2_s, h_t0_m=CHURN_H_T0_M
) -> ChurningResult:
    """Churning loss of a wheel dipping in the sump, Eq 23-34.

    omega_rad_s: wheel speed (the caller passes the magnitude; omega <= 0 gives zero loss), R_a_m tip radius,
    R_p_m pitch radius, h_t_m tooth height, w_t_m tooth (face) width, h_i_m immersion depth, V_p_m3 immersed
    volume, V_0_m3 sump oil volume, h_t0_m reference tooth height of the correlation.
    Eq 28 exponent of Fr_side read as ``-(0.464 + 0.037 R_a / h_i)``; Eq 33's R_t read as the tip radius.
    """
    w = np.asarray(omega_rad_s, dtype=float)
    on = w > 0.0
    ws = np.where(on, w, 1.0)
    R_a = np.asarray(R_a_m, dtype=float)
    R_p = np.asarray(R_p_m, dtype=float)
    h_t = np.asarray(h_t_m, dtype=float)
    w_t = np.asarray(w_t_m, dtype=float)
    h_i = np.asarray(h_i_m, dtype=float)
    vr = np.asarray(V_p_m3, dtype=float) / np.asarray(V_0_m3, dtype=float)
    nu = np.asarray(nu_m2_s, dtype=float)
    rho = np.asarray(rho_kg_m3, dtype=float)
    # Eq 27
    re_s = ws * R_a * R_a / nu
    fr_s = ws * ws * R_a / G_M_S2
    re_t = ws * R_p * h_t / nu
    fr_t = ws * ws * R_p * R_p / (G_M_S2 * h_t)
    hr = h_i / R_a
    wr = w_t / R_a
    # Eq 28-30
    lam = re_s**-0.6 * fr_s**-0.25
    cmd28 = 0.97 * re_s**-0.31 * fr_s ** -(0.464 + 0.037 / hr) * vr**-0.576 * wr**-0.124 * hr**0.74
    cmd29 = 2.63 * lam * vr**-0.73 * wr**-0.4 * hr**1.5
    cmd30 = 4.57 * lam * vr**-0.5 * wr**-0.4 * hr**1.5
    turb_s = re_s >= 2250.0
    low = lam < 8.7e-3
    cmd = np.where(turb_s, cmd28, np.where(low, cmd29, cmd30))
    cmd_regime = np.where(turb_s, 28, np.where(low, 29, 30))
    # Eq 31-32
    htr = h_t / h_t0_m
    wtr = w_t / h_t0_m
    hi_t = re_t**0.23 * fr_t**0.32 >= 12.0
    cma31 = 5623.0 * re_t**-0.88 * fr_t**-0.78 * htr**-1.5 * wtr**-0.36
    cma32 = 616.6 * re_t**-0.64 * fr_t**-0.46 * htr**-1.66 * wtr**-0.46
    cma = np.where(hi_t, cma31, cma32)
    cma_regime = np.where(hi_t, 31, 32)
    # Eq 24-25, 23
    C_side = np.where(on, rho * ws * ws * w_t * R_a**4 * cmd, 0.0)
    C_teeth = np.where(on, rho * ws * ws * w_t * R_p**3 * h_t * cma, 0.0)
    P = (C_side + C_teeth) * np.where(on, w, 0.0)
    # Eq 33-34 (strict inequalities as printed)
    valid = (
        on
        & (10.0 < re_s)
        & (re_s < 36000.0)
        & (1.6 < fr_s)
        & (fr_s < 1400.0)
        & (0.025 < hr)
        & (hr < 1.0)
        & (0.006 < wr)
        & (wr < 1.0)
        & (0.1 < vr)
        & (vr < 0.25)
        & (7.0 < re_t)
        & (re_t < 2110.0)
        & (22.0 < fr_t)
        & (fr_t < 3112.0)
        & (0.45 < wtr)
        & (wtr < 1.8)
        & (1.0 < htr)
        & (htr < 1.6)
    )
    return ChurningResult(P, C_side, C_teeth, np.where(on, cmd_regime, 0), np.where(on, cma_regime, 0), valid)


def bearing_p1_n(Fr_n, Fa_n, e, X1, Y1, X2, Y2):
    """Equivalent bearing load P1 [N], Eq 40, literally: X1 Fr + Y1 Fa if Fa/Fr >= e, else X2 Fr + Y2 Fa.

    Forces are taken as magnitudes. Fr = 0 is Fa/Fr = +inf (first branch); the ratio test is done as
    ``Fa >= e Fr`` so there is no division. See the module docstring for the swap against SKF's convention.
    """
    Fr = np.abs(np.asarray(Fr_n, dtype=float))
    Fa = np.abs(np.asarray(Fa_n, dtype=float))
    return np.where(Fa >= e * Fr, X1 * Fr + Y1 * Fa, X2 * Fr + Y2 * Fa)


def _palmgren_oil_torque_nm(f0, Dm_m, nu_m2_s, omega_rad_s):
    # Eq 36-37: T_oil = 9.78e-2 f0 Dm^3 max(nu n, 2000)^(2/3), nu in cSt, n in rpm, Dm in m, T in N m.
    # Palmgren: M0 = 1e-7 f0 (nu n)^(2/3) dm^3 N mm (dm in mm) = 0.1 f0 (nu n)^(2/3) Dm^3 N m; the seed's
    # constant is 2.2 % below Palmgren's 0.1 and is kept as printed.
    nu_n = (np.asarray(nu_m2_s, dtype=float) * 1e6) * (np.abs(np.asarray(omega_rad_s, dtype=float)) * RPM_PER_RAD_S)
    return (
        PALMGREN_SEED_C * f0 * np.asarray(Dm_m, dtype=float) ** 3 * np.maximum(nu_n, PALMGREN_NU_N_MIN) ** (2.0 / 3.0)
    )


def bearing_torque_nm(f0, f1, f2, Dm_m, nu_m2_s, omega_rad_s, P0_n, P1_n, Fa_n):
    """Shaft bearing loss torque magnitude [N m], Eq 35-39 (Palmgren). Loss power = torque * |omega|.

    Oil term Eq 36-37: Palmgren's ``M0 = 1e-7 f0 (nu n)^(2/3) dm^3`` [N mm] with nu in cSt, n in rpm, dm in mm,
    written by the seed as ``9.78e-2 f0 Dm^3 (nu n)^(2/3)`` with Dm in m and the 2000 threshold on nu n in
    cSt rpm; SI inputs are converted inside. Below the threshold (Eq 37) the torque stays at its floor, also at
    standstill (the loss power is then zero because omega is). Load terms: Eq 38 ``f1 (P0 + P1) Dm``,
    Eq 39 ``f2 |Fa| Dm``.
    """
    T_oil = _palmgren_oil_torque_nm(f0, Dm_m, nu_m2_s, omega_rad_s)  # Eq 36-37
    T_rad = f1 * (np.asarray(P0_n, dtype=float) + np.asarray(P1_n, dtype=float)) * Dm_m  # Eq 38
    T_ax = f2 * np.abs(np.asarray(Fa_n, dtype=float)) * Dm_m  # Eq 39
    return T_oil + T_rad + T_ax  # Eq 35


def skf_rolling_coef(R1, Dm_m, P1_per_nm, kind: str):
    """The coefficient c of SKF's rolling frictional moment as ``M_rr = c |T|^0.31 (nu n)^0.6`` [N m] for a bearing
    whose equivalent load is P1_per_nm [N per N m of input torque] (Eq 40's P1 in place of SKF's load of each kind:
    Fr for cylindrical bearings, Fr + R2 Y Fa for tapered ones), nu in cSt, n in rpm: 1e-3 R1 dm^a P1^0.31 with dm
    in mm (SKF_RR_DM_EXP)."""
    if kind not in SKF_RR_DM_EXP:
        raise ParameterError(f"bearing.R1_{kind}: SKF's rolling term is known for {', '.join(SKF_RR_DM_EXP)} bearings")
    P1 = np.abs(np.asarray(P1_per_nm, dtype=float))
    return 1e-3 * R1 * (Dm_m * 1e3) ** SKF_RR_DM_EXP[kind] * P1**SKF_RR_LOAD_EXP


def skf_inlet_shear_coef(Dm_m):
    """c of SKF's inlet shear heating reduction factor ``1 / (1 + c (n^2 nu)^0.64)`` (n rpm, nu cSt) of a bearing of
    mean diameter Dm_m: 1.84e-9 dm^1.28 with dm in mm."""
    return SKF_ISH_C * (np.asarray(Dm_m, dtype=float) * 1e3) ** (2.0 * SKF_ISH_EXP)


def skf_rolling_torque_nm(coef, ish_coef, torque_nm, nu_m2_s, omega_rad_s):
    """SKF's rolling frictional moment [N m] of :func:`skf_rolling_coef`'s bearing at input torque ``torque_nm``:
    ``coef |T|^0.31 (nu n)^0.6`` times the inlet shear heating reduction ``1 / (1 + ish_coef (n^2 nu)^0.64)``
    (:func:`skf_inlet_shear_coef`: thick cold oil heats in the rollers' inlet and carries less of the rolling),
    nu in cSt and n in rpm (converted here); zero at rest or without load. It grows with the load as its 0.31th
    power where Palmgren's load term (Eq 38) grows linearly."""
    nu_cst = np.asarray(nu_m2_s, dtype=float) * 1e6
    n_rpm = np.abs(np.asarray(omega_rad_s, dtype=float)) * RPM_PER_RAD_S
    T = np.abs(np.asarray(torque_nm, dtype=float))
    return (
        coef
        * T**SKF_RR_LOAD_EXP
        * (nu_cst * n_rpm) ** SKF_RR_NU_N_EXP
        / (1.0 + ish_coef * (n_rpm * n_rpm * nu_cst) ** SKF_ISH_EXP)
    )


def needle_bearing_torque_nm(f0, Dm_m, nu_m2_s, rel_omega_rad_s):
    """Idle-wheel (needle) bearing loss torque magnitude [N m]: oil shear only, Eq 36-37 on the relative speed.

    The wheel bearings carry no gear load in the seed's model, so only Palmgren's M0 is used. At zero relative
    speed (wheel locked to its shaft) the torque is the Eq 37 floor and the loss power ``torque * |rel_omega|``
    is zero.
    """
    return _palmgren_oil_torque_nm(f0, Dm_m, nu_m2_s, rel_omega_rad_s)


def sync_ring_drag_torque_nm(n_ring, mu_pa_s, R_ring_m, w_ring_m, J_ax_m, theta_ring_rad, rel_omega_rad_s):
    """Oil-shear drag torque between open synchronizer cone rings [N m], Eq 41 times the relative speed.

    Eq 41 as printed, ``n 2 pi mu R^3 w / (J_ax sin theta)``, has units N m s (a damping coefficient: Couette
    shear over the cone area 2 pi R w, gap normal to the cone J_ax sin theta); the torque is that times the
    relative speed and carries its sign (it opposes the relative motion). Loss power = torque * rel_omega >= 0.
    """
    c = (
        n_ring
        * 2.0
        * math.pi
        * np.asarray(mu_pa_s, dtype=float)
        * np.asarray(R_ring_m, dtype=float) ** 3
        * w_ring_m
        / (J_ax_m * np.sin(theta_ring_rad))
    )  # Eq 41 [N m s]
    return c * np.asarray(rel_omega_rad_s, dtype=float)


def pump_torque_nm(speed_ls_rpm, k_nm_per_rpm):
    """Oil pump loss torque [N m] = k * layshaft speed, Eq 42 (the seed's coefficient is censored: a parameter).

    Loss power = torque * omega_ls = k n omega >= 0 for k >= 0 in either direction.
    """
    return k_nm_per_rpm * np.asarray(speed_ls_rpm, dtype=float)


def planetary_heat_split(Q_w):
    """Split planetary losses [W] into (sun, planets, ring) heat [W] as 1/3, 1/2, 1/6 (section 3.2)."""
    Q = np.asarray(Q_w, dtype=float)
    return Q * PLANETARY_HEAT_SPLIT["PS"], Q * PLANETARY_HEAT_SPLIT["PP"], Q * PLANETARY_HEAT_SPLIT["PR"]
