"""The stability proof of the onboard model's explicit step (docs/sensor.md, "Stability"), checked when the tables
are built (firmware_model.onboard.reduce.build_reduced).

Forward Euler on ``C dT/dt = -K T + b`` is stable (and monotone: every new temperature is a convex combination of
the old ones and the sources, so no overshoot) when ``dt <= C_i / sum_j G_ij`` for every node i (Gershgorin:
every eigenvalue of ``C^-1 K`` lies in ``[0, 2 max_i sum_j G_ij / C_i]``). :func:`check_stability` bounds every
link's conductance over the whole operating range (every gear, 0..max engine speed, oil -40..150 degC) from the
laws themselves (power laws are monotone in speed, bilinear tables stay inside their corner values, the oil-
temperature columns are piecewise linear), adds the cooler (a conductance of at most hA to the air, the thermostat's
opening a coefficient in 0..1 taken at its bound as the oil-dependent conductances are) and its inlet-temperature
coupling, and raises
:class:`~firmware_model.errors.StabilityError` naming the node when ``dt > margin x C_i / max sum_j G_ij``.
"""

from __future__ import annotations

import numpy as np

from firmware_model.components import STEP_S
from firmware_model.effects import CATALOG
from firmware_model.errors import ParameterError, StabilityError
from firmware_model.network import MIN_SPEED_RAD_S
from firmware_model.onboard.evaluate import (
    LN_M2_S_PER_CST,
    PUMP_CODES,
    RAD_T_RANGE_C,
    T2_STRIDE,
    T_GRID_C,
    ReducedParams,
    cyl_nusselt,
    flow_per_drive,
    pump_drive,
    radiation_w_per_k,
)
from firmware_model.onboard.kernel_interface import (
    EFFECT_HOUSING_AIR_H,
    EFFECT_PLANET_OIL_H,
    EFFECT_TEETH_OIL_H,
    P_CP,
    P_K,
    P_LN_NU_CST,
    P_LN_PR,
    P_RHO,
    TTL_FRESH_S,
)
from firmware_model.physics.conductance_matrix import node_conductance_w_per_k
from firmware_model.physics.cooler import COOLER_KINDS, cooler_hA_bound_w_per_k, cooler_params
from firmware_model.units import KELVIN_OFFSET_K, RAD_S_PER_RPM

#: the stability check requires dt <= STABILITY_MARGIN x min_i C_i / max sum_j G_ij
STABILITY_MARGIN = 0.8
#: oil temperature range over which stability is guaranteed [degC]
OIL_RANGE_C = (-40.0, 150.0)
#: the largest step a held replay takes [s] (derived; docs/sensor.md "A coarser step for held tables"): an early
#: warning judges a time to limit at most TTL_FRESH_S + dt / 2 old (step.py), so at a step of at most 2 TTL_FRESH_S
#: the one refresh per row, one step before the row's end, is still judged; the drive inputs' hold time grows with
#: the step (VirtualSensor.with_step), so one step without speed or torque is still "held"
HELD_STEP_CAP_S = 2.0 * TTL_FRESH_S


def max_conductances(rp: ReducedParams) -> dict:
    """Upper bounds over the operating range (every gear, 0..max speed, oil OIL_RANGE_C, effects at the top of their
    plausible ranges) of every link's conductance and of the cooler's slope, from the laws themselves: power laws
    grow with speed (exponents >= 0), bilinear tables stay within their corner values, oil-temperature columns are
    piecewise linear, NTU streams are below both hA and mdot cp, radiation grows with temperature."""
    omega_in_max_rad_s = rp.max_speed_rpm * RAD_S_PER_RPM
    jT = (T_GRID_C >= OIL_RANGE_C[0] - 1e-9) & (T_GRID_C <= OIL_RANGE_C[1] + 1e-9)
    jT = np.convolve(jT.astype(int), [1, 1, 1], mode="same") > 0  # neighbours bound the interpolation
    G = np.array(rp.G_const_w_per_k, dtype=float)
    phi_max = np.max(rp.pw_phi[jT], axis=0)
    eff_max = {
        EFFECT_TEETH_OIL_H: CATALOG["teeth_oil_h_scale"].high,
        EFFECT_PLANET_OIL_H: CATALOG["planet_oil_h_scale"].high,
        EFFECT_HOUSING_AIR_H: CATALOG["housing_air_h_scale"].high,
    }
    if np.any(rp.pw_exp < 0):
        raise ParameterError("a conductance law has a negative speed exponent; the stability bound needs >= 0")
    for t in range(len(rp.pw_link)):
        ph = phi_max[rp.pw_col[t]] if rp.pw_col[t] >= 0 else 1.0
        coef_max = np.max(rp.pw_gear_coef[:, t])
        G[rp.pw_link[t]] += coef_max * omega_in_max_rad_s ** rp.pw_exp[t] * ph * eff_max.get(int(rp.pw_effect[t]), 1.0)
    jT2 = jT[::T2_STRIDE]
    for t in range(len(rp.t2_link)):
        G[rp.t2_link[t]] += np.max(rp.t2_table[t][:, jT2])
    prop = rp.prop[jT]
    # the pump's largest drive: its shaft at the top input speed (pump_drive is linear in it), a motor pump's 1
    # (whatever speed it may stop below)
    motor = rp.pump_code == PUMP_CODES["motor"]
    drive_max = 1.0 if motor else np.max(pump_drive(rp, slice(None), 1.0)) * omega_in_max_rad_s
    for t in range(len(rp.ef_link)):
        planet = eff_max[EFFECT_PLANET_OIL_H] if rp.ef_effect[t] == EFFECT_PLANET_OIL_H else 1.0
        hA = rp.ef_alpha[t] * np.max(prop[:, P_K]) + rp.ef_beta[t] * planet
        m = rp.ef_mcp[t] * np.max(prop[:, P_RHO] * prop[:, P_CP]) * drive_max
        G[rp.ef_link[t]] += min(hA, m)
    if len(rp.cyl_link):
        # monotone in speed (Re); over the oil range sampled every 0.25 K of the interpolated properties, +2 %
        Td = np.arange(OIL_RANGE_C[0], OIL_RANGE_C[1] + 1e-9, 0.25)
        x = (Td - T_GRID_C[0]) / (T_GRID_C[1] - T_GRID_C[0])
        i = np.minimum(x.astype(np.int64), T_GRID_C.size - 2)
        f = (x - i)[:, None]
        pr = rp.prop[i] * (1.0 - f) + rp.prop[i + 1] * f
        omega_c_max_rad_s = np.max(rp.cyl_speed_coef, axis=0) * omega_in_max_rad_s
        ln_omega_c = np.log(np.maximum(omega_c_max_rad_s, MIN_SPEED_RAD_S))
        ln_re = rp.cyl_ln_rp2 + ln_omega_c - (pr[:, P_LN_NU_CST, None] + LN_M2_S_PER_CST)
        Gc = rp.cyl_c * pr[:, P_K, None] * cyl_nusselt(ln_re, pr[:, P_LN_PR, None])
        np.add.at(G, rp.cyl_link, 1.02 * Gc.max(axis=0))
    if rp.rad_link.size:
        G[rp.rad_link] = radiation_w_per_k(rp.rad_area_eps, RAD_T_RANGE_C[1] + KELVIN_OFFSET_K, 250.0 + KELVIN_OFFSET_K)
    # cooler: its largest conductance hA (the highest flows, effectiveness scale at its maximum; the opening <= 1)
    hA = 0.0  # no cooler (cooler_code 0): the housing sheds the heat
    if rp.cooler_code:
        hA = cooler_hA_bound_w_per_k(
            cooler_params(rp.cooler),
            COOLER_KINDS[rp.cooler_code],
            drive_max,
            omega_in_max_rad_s,
            CATALOG["cooler_effectiveness_scale"].high,
            motor_pump=rp.pump_code == PUMP_CODES["motor"],
        )
    # the sump heater: Q = heater_w x (heater_set - T) / band on its band, a conductance of heater_w / band to a
    # temperature, taken into the cooler's bound (the net heat's slope; physics.cooler.heater_slope_w_per_k)
    c = cooler_params(rp.cooler)
    if c.heater_w > 0.0:
        hA += c.heater_w / c.heater_band_k
    return {"G": G, "cooler_hA": float(hA)}


def check_stability(rp: ReducedParams) -> dict:
    """Prove dt <= margin x C_i / max sum_j G_ij for every node (module doc); raise StabilityError naming the node."""
    h = rp.helpers
    mc = max_conductances(rp)
    n = rp.n
    rowsum = node_conductance_w_per_k(mc["G"], h.topology)
    hA = mc["cooler_hA"]
    # the cooler on the sump, and its inlet-temperature drop dT_in = Q / (mdot cp): a stream term moves G_s dT_in
    # from its component to the sump and |d(G_s dT_in)/dT_oil| <= G_s hA / (mdot cp) <= frac_s hA
    extra = np.zeros(n)
    extra[rp.i_oil] += hA
    fracs = np.concatenate([rp.t2_frac[h.t2_streams], rp.ef_mcp / flow_per_drive(rp)])
    nodes = np.argmin(h.stream_scatter, axis=1)
    np.add.at(extra, nodes, fracs * hA)
    extra[rp.i_oil] += fracs.sum() * hA
    total = rowsum + extra
    dt_max = rp.margin * h.C / total
    i = int(np.argmin(dt_max))
    info = {
        "dt_max_s": dt_max,
        "max_sum_G_w_per_k": total,
        "limiting_node": rp.nodes[i],
        "C_j_per_k": float(h.C[i]),
        "margin": rp.margin,
        "tau_min_s": float(h.C[i] / total[i]),
    }
    if rp.dt_s > dt_max[i]:
        raise StabilityError(
            f"node {rp.nodes[i]} (C = {h.C[i]:.4g} J/K) has a maximum total conductance of {total[i]:.4g} W/K over "
            f"the operating range (every gear, 0..{rp.max_speed_rpm:.0f} rpm, oil {OIL_RANGE_C[0]:g}.."
            f"{OIL_RANGE_C[1]:g} degC): the explicit step dt = {rp.dt_s:g} s exceeds margin {rp.margin:g} x "
            f"C / sum G = {dt_max[i]:.4g} s; merge the node with a neighbour or raise its thermal mass"
        )
    return info


def held_step_s(stability: dict, period_s, cap_s: float = HELD_STEP_CAP_S, base_s: float = STEP_S) -> float:
    """The step [s] of a table held over rows of ``period_s`` (a fixed-ratio drive's SCADA): the largest multiple
    ``k base_s`` of the vehicle step that the proof ``stability`` (:func:`check_stability`'s, margin included) holds
    for at every node, at most ``cap_s``, that divides the row period (every row an integer number of steps, the
    frame times on the base grid). ``base_s`` when none larger does, or the period is not a positive multiple of
    ``base_s`` (an irregular table, a missing or bad period)."""
    try:
        period = float(period_s)
    except (TypeError, ValueError):
        return base_s
    dt_max = float(np.min(stability["dt_max_s"])) if stability and len(stability.get("dt_max_s", ())) else 0.0
    if not (np.isfinite(period) and period > base_s and np.isfinite(dt_max)):
        return base_s
    m = period / base_s  # the period in base steps: an integer, else base_s
    if abs(m - round(m)) > 1e-9 * m:
        return base_s
    m = int(round(m))
    k_max = int(np.floor(min(dt_max, cap_s) / base_s + 1e-9))
    for k in range(min(k_max, m), 1, -1):
        if m % k == 0 and k * base_s <= dt_max:
            return round(k * base_s, 9)
    return base_s
