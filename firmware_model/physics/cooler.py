"""The oil cooler (seed section 3.4, Eq 82-83): one model for the reference plant and the onboard sensor.

Kinds: ``none``; ``liquid`` (plate oil/coolant cooler, can also heat the oil); ``air`` (oil/air cooler behind a
thermostat, recirculated air warmer than ambient at low vehicle speed). The cooler's effective conductance follows
its data sheet from the reference flows: ``hA = hA_ref (inner flow ratio)^exp_inner (outer flow ratio)^exp_outer``,
the inner (oil) flow linear in the layshaft speed, the outer flow linear in engine speed (liquid) or a fan share plus
the ram air of the vehicle speed (air). :func:`oil_cooler_heat` is the whole model; the plant
(tools.plant.reference) and the onboard model (firmware_model.onboard.evaluate.cooler_heat) both call it.

Every function takes floats or numpy arrays and does its arithmetic in what it is given (Python floats stay
scalars), so both callers keep their own last bits.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from firmware_model.errors import ParameterError

#: kinds the cooler model knows; the index is the onboard model's cooler code (0 none, 1 liquid, 2 air)
COOLER_KINDS = ("none", "liquid", "air")
#: recirculated air at the air cooler is warmer than ambient at low vehicle speed (seed 3.4: +9 K at 15 km/h,
#: +2 K at 50 km/h, < 1 K at 85 km/h): vehicle speed [km/h] -> excess temperature [K]
AIR_RECIRC_V_KMH = np.array([0.0, 15.0, 50.0, 85.0, 200.0])
AIR_RECIRC_DT_K = np.array([12.0, 9.0, 2.0, 0.5, 0.0])
#: vehicle speed of the air cooler's reference outer flow [km/h], and the largest outer flow (x reference)
AIR_REF_SPEED_KMH = 85.0
AIR_FLOW_MAX_REL = 1.5
#: vehicle speed the cooler model takes when none is known [km/h]
DEFAULT_VEHICLE_SPEED_KMH = 50.0
#: the oil-system inlet drop (sump minus cooler outlet, Q / (mdot cp)) is clipped to +- this [K]
INLET_DROP_MAX_K = 30.0
#: parameter names (``cooler.<name>``) of the cooler model, in the order of CoolerParams
COOLER_KEYS = (
    "liquid_hA_ref",
    "liquid_Qmax_cool",
    "liquid_Qmax_heat",
    "air_hA_ref",
    "air_Qmax_cool",
    "thermostat_open",
    "thermostat_full",
    "ref_ls_speed",
    "ref_engine_speed",
    "exp_inner",
    "exp_outer",
    "air_flow_min_frac",
    "thermostat_sump",
    "heater_w",
    "heater_set",
    "heater_band",
    "measured_balance",
)
#: CoolerParams fields a stored copy may lack (it was stored before they existed) and what they then are: the
#: thermostat at the return (Eq 82), no heater
COOLER_LATER_KEYS = {
    "thermostat_sump": 0.0,
    "heater_w": 0.0,
    "heater_set": 0.0,
    "heater_band": 1.0,
    "measured_balance": 0.0,
}


class CoolerParams(NamedTuple):
    """The cooler's data sheet (SI; parameter names in COOLER_KEYS)."""

    liquid_hA_ref_w_per_k: float
    liquid_Q_max_cool_w: float
    liquid_Q_max_heat_w: float
    air_hA_ref_w_per_k: float
    air_Q_max_cool_w: float
    thermostat_open_c: float
    thermostat_full_c: float
    ref_ls_speed_rad_s: float  # layshaft speed of the reference inner (oil) flow
    ref_engine_speed_rad_s: float  # engine speed of the liquid cooler's reference outer (coolant) flow
    exp_inner: float
    exp_outer: float
    air_flow_min_frac: float  # air outer flow at standstill (fan) relative to the reference
    thermostat_sump: float = 0.0  # 1: the thermostat reads the sump (before the cooler); 0: the return (Eq 82)
    heater_w: float = 0.0  # the sump heater's power (0: none)
    heater_set_c: float = 0.0  # it is off above this sump temperature ...
    heater_band_k: float = 1.0  # ... and at full power below heater_set - heater_band
    measured_balance: float = 0.0  # 1: with the sump measured the cooler takes what its balance leaves (0: the law)


class CoolerHeat(NamedTuple):
    Q_w: np.ndarray | float  # heat from the sump to the cooler (positive cools the oil)
    hA_w_per_k: np.ndarray | float  # the cooler's effective conductance at these flows


def cooler_values(p) -> dict:
    """{name: SI value} of the cooler parameters (COOLER_KEYS) of a parameter set. A gearbox's file may leave out the
    keys of a cooler it does not have (MM82: the liquid cooler's, the layshaft and engine reference speeds; HR225:
    all): those are NaN, and a model that reads one gives NaN, never a silent number. ``thermostat_sump`` and the
    heater's are the description's (``topology.oil``): 1.0 where its thermostat reads the sump
    (``thermostat_senses``), else 0; the heater's power, set point and band (none: 0 W)."""
    from firmware_model.description import description_of

    oil = description_of(p).oil
    out = {k: p.values.get(f"cooler.{k}", math.nan) for k in COOLER_KEYS if k not in COOLER_LATER_KEYS}
    out["thermostat_sump"] = 1.0 if oil.thermostat_senses == "sump" else 0.0
    out["measured_balance"] = 1.0 if oil.measured_cooler == "balance" else 0.0
    return {**out, **heater_values(p)}


def heater_values(p) -> dict:
    """The sump heater's CoolerParams values of a parameter set's description (``topology.oil.heater``,
    ``heater_set``, ``heater_band``; none: 0 W), whatever the cooler."""
    from firmware_model.description import description_of

    oil = description_of(p).oil
    if not oil.heater_w > 0.0:
        return {k: COOLER_LATER_KEYS[k] for k in ("heater_w", "heater_set", "heater_band")}
    return {"heater_w": oil.heater_w, "heater_set": oil.heater_set_c, "heater_band": oil.heater_band_k}


def cooler_params(values: dict) -> CoolerParams:
    """CoolerParams from {name: SI value} (cooler_values, or the onboard model's stored copy; a copy stored before
    a key of COOLER_LATER_KEYS existed takes its value there)."""
    return CoolerParams(*(values[k] if k in values else COOLER_LATER_KEYS[k] for k in COOLER_KEYS))


def heater_heat_w(c: CoolerParams, T_oil_c):
    """Heat of the sump heater into the oil [W]: its full power at or below heater_set - heater_band, none at or
    above heater_set, linear between (a thermostat's on/off cycles over its hysteresis, averaged over them). The
    heater heats the sump whether the pump runs or not; as a cooler's heat it is monotone in the sump temperature
    (here falling), so the sump's heat balance stays a contraction (docs/sensor.md, "Stability proof")."""
    if not c.heater_w > 0.0:
        return 0.0 * np.asarray(T_oil_c, dtype=float) if np.ndim(T_oil_c) else 0.0
    x = (c.heater_set_c - np.asarray(T_oil_c, dtype=float)) / c.heater_band_k
    on = np.clip(x, 0.0, 1.0)
    return c.heater_w * (on if np.ndim(on) else float(on))


def heater_slope_w_per_k(c: CoolerParams, T_oil_c) -> float:
    """d(-heater heat)/dT_oil [W/K] at the sump temperature: heater_w / heater_band inside the band, else 0 (the
    net cooler's slope is the cooler's plus this)."""
    if not c.heater_w > 0.0:
        return 0.0
    x = (c.heater_set_c - float(T_oil_c)) / c.heater_band_k
    return c.heater_w / c.heater_band_k if 0.0 < x < 1.0 else 0.0


# --- Eq 82-83 ----------------------------------------------------------------------------------------------


def thermostat_fraction(T_c, T_open_c, T_full_c):
    """Thermostat opening 0..1, linear between T_open and T_full (section 3.4)."""
    if not T_full_c > T_open_c:
        raise ParameterError(f"thermostat T_full_c = {T_full_c} must exceed T_open_c = {T_open_c} [degC]")
    return np.clip((np.asarray(T_c, dtype=float) - T_open_c) / (T_full_c - T_open_c), 0.0, 1.0)


def thermostat_temperature_c(T_oil_sump_c, Q_cooler_w, mdot_kg_s, cp_j_per_kgk):
    """Temperature seen by the thermostat T_sump - Q / (mdot cp) [degC] (Eq 82); no flow gives T_sump."""
    C = np.abs(np.asarray(mdot_kg_s, dtype=float)) * cp_j_per_kgk
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.asarray(T_oil_sump_c, dtype=float) - np.where(
            C > 0.0, np.asarray(Q_cooler_w, dtype=float) / np.where(C > 0.0, C, 1.0), 0.0
        )


def cooler_heat_w(
    kind,
    hA_w_per_k,
    T_oil_c,
    T_medium_c,
    mdot_kg_s,
    cp_j_per_kgk,
    Q_max_cool_w,
    Q_max_heat_w,
    T_open_c,
    T_full_c,
    thermostat_sump=0.0,
):
    """Heat flow from the oil to the cooler [W] (Eq 83; positive cools the oil).

    * ``"none"``: 0.
    * ``"liquid"``: Q = hA_eff (T_oil - T_medium), saturated to -Q_max_heat .. Q_max_cool (can heat the oil);
      no thermostat (sf = 1). mdot, cp, T_open, T_full are not used.
    * ``"air"``: Q = hA_eff (T_oil - T_air) sf(T_th), 0 <= Q <= Q_max_cool (cannot heat), with the thermostat
      input T_th = T_oil - Q / (mdot cp) (Eq 82). The coupling is solved exactly: with dT = T_oil - T_air > 0,
      a = hA dT, D = T_full - T_open and C = mdot cp, the right-hand side is non-increasing in Q, so the fixed
      point is unique; on the open ramp Q = a (T_oil - T_open - Q/C)/D gives
      ``Q_lin = a (T_oil - T_open) / (D + a/C)``, the thermostat limits it to ``clip(Q_lin, 0, a)`` and the
      cooler saturation to ``min(., Q_max_cool)`` (at Q_max_cool the ramp still asks for more). No oil flow
      (C = 0) gives 0. ``thermostat_sump`` = 1: the thermostat reads the sump, before the cooler (T_th = T_oil):
      ``Q_lin = a (T_oil - T_open) / D``, the coupling term a/C dropped; the sump then stays in the band while the
      cooler can take the heat, and the return lies Q/C below it.
    hA_eff is the cooler's effective conductance (data-sheet output / temperature difference) at the
    current inner and outer flows.
    """
    if kind not in COOLER_KINDS:
        raise ParameterError(f"cooler kind = {kind!r} must be one of {COOLER_KINDS}")
    hA = np.asarray(hA_w_per_k, dtype=float)
    dT = np.asarray(T_oil_c, dtype=float) - np.asarray(T_medium_c, dtype=float)
    if kind == "none":
        return np.zeros(np.broadcast(hA, dT).shape) if np.ndim(hA) or np.ndim(dT) else 0.0
    if kind == "liquid":
        return np.clip(hA * dT, -np.asarray(Q_max_heat_w, dtype=float), np.asarray(Q_max_cool_w, dtype=float))  # Eq 83
    if not np.all(np.asarray(T_full_c) > np.asarray(T_open_c)):  # arrays: a thermostat per vehicle
        raise ParameterError(f"cooler T_full_c = {T_full_c} must exceed T_open_c = {T_open_c} [degC]")
    a = hA * np.maximum(dT, 0.0)
    C = np.abs(np.asarray(mdot_kg_s, dtype=float)) * cp_j_per_kgk
    D = T_full_c - T_open_c
    with np.errstate(divide="ignore", invalid="ignore"):
        coupling = np.where(np.asarray(thermostat_sump) > 0.5, 0.0, a / np.where(C > 0.0, C, 1.0))
        q_lin = a * (np.asarray(T_oil_c, dtype=float) - T_open_c) / (D + coupling)
    q = np.minimum(np.clip(q_lin, 0.0, a), np.asarray(Q_max_cool_w, dtype=float))  # Eq 82/83
    return np.where((C > 0.0) & (a > 0.0), q, 0.0)


# --- the cooler at an operating point ------------------------------------------------------------------------


def air_temperature_c(T_ambient_c, v_kmh):
    """Air temperature at the air cooler: ambient plus the recirculation excess at this vehicle speed (seed 3.4)."""
    return T_ambient_c + np.interp(np.maximum(v_kmh, 0.0), AIR_RECIRC_V_KMH, AIR_RECIRC_DT_K)


def cooler_hA_w_per_k(c: CoolerParams, kind: str, inner_flow_ratio, omega_engine_rad_s, v_kmh, scale=1.0):
    """The cooler's effective conductance at the current flows [W/K] (data sheet scaled by the flow ratios).

    inner_flow_ratio: oil flow / reference oil flow (= layshaft speed / ref_ls_speed: the flow is linear in it);
    liquid: outer flow linear in the engine speed; air: a fan share plus the ram air, linear in the vehicle speed up
    to AIR_FLOW_MAX_REL x the reference (v_kmh must be a number: callers substitute their default for a missing
    one). ``scale``: the cooler_effectiveness_scale effect."""
    inner = inner_flow_ratio**c.exp_inner
    if kind == "liquid":
        outer = (np.maximum(omega_engine_rad_s, 0.0) / c.ref_engine_speed_rad_s) ** c.exp_outer
        return c.liquid_hA_ref_w_per_k * inner * outer * scale
    fmin = c.air_flow_min_frac
    rel = np.minimum(np.maximum(v_kmh, 0.0) / AIR_REF_SPEED_KMH, AIR_FLOW_MAX_REL)
    return c.air_hA_ref_w_per_k * inner * (fmin + (1.0 - fmin) * rel) ** c.exp_outer * scale


def oil_cooler_heat(
    c: CoolerParams,
    kind: str,
    T_oil_c,
    inner_flow_ratio,
    omega_engine_rad_s,
    T_coolant_c,
    T_ambient_c,
    v_kmh,
    mcp_w_per_k,
    scale=1.0,
    thermostat_offset_c=0.0,
) -> CoolerHeat:
    """Heat from the sump to the cooler [W] (Eq 83, the air cooler's thermostat coupled through Eq 82) and the
    cooler's hA, for kind none | liquid | air.

    mcp_w_per_k: the oil-system flow capacity mdot cp (no flow: no heat); the liquid cooler exchanges with the
    coolant, the air cooler with ambient air warmed by recirculation (air_temperature_c). ``scale`` and
    ``thermostat_offset_c``: the cooler_effectiveness_scale and thermostat_offset effects."""
    flow_capacity_w_per_k = np.where(mcp_w_per_k > 0.0, mcp_w_per_k, 0.0)
    if kind == "none":
        z = np.zeros(np.broadcast(T_oil_c, inner_flow_ratio, flow_capacity_w_per_k).shape)
        return CoolerHeat(z, z)
    hA = cooler_hA_w_per_k(c, kind, inner_flow_ratio, omega_engine_rad_s, v_kmh, scale)
    if kind == "liquid":
        Q = cooler_heat_w(
            "liquid",
            hA,
            T_oil_c,
            T_coolant_c,
            flow_capacity_w_per_k,
            1.0,
            c.liquid_Q_max_cool_w,
            c.liquid_Q_max_heat_w,
            0.0,
            1.0,
        )
    else:
        Q = cooler_heat_w(
            "air",
            hA,
            T_oil_c,
            air_temperature_c(T_ambient_c, v_kmh),
            flow_capacity_w_per_k,
            1.0,
            c.air_Q_max_cool_w,
            0.0,
            c.thermostat_open_c + thermostat_offset_c,
            c.thermostat_full_c + thermostat_offset_c,
            c.thermostat_sump,
        )
    return CoolerHeat(np.where(flow_capacity_w_per_k > 0.0, Q, 0.0), hA)


#: the least share of the cooler's heat the sump keeps (1 - sum of the jets' stream conductances over mdot cp) that
#: measured_balance_heat_w divides by: jets as conductive as the whole flow would make the sump's balance blind
BALANCE_KEEP_MIN = 0.05


def measured_balance_heat_w(c: CoolerParams, H_w, stream_frac, hA_w_per_k, T_oil_c, T_air_c):
    """The cooler's heat net of the sump heater [W] while the sump is measured, for a description whose
    ``measured_cooler`` is "balance": the heat the sump must lose to stay at its reading, in place of the
    thermostat's law at it (Eq 82-83), whose narrow band a real sump sits a few kelvin off while its cooler works.

    The sump gains ``H_w`` at this step's temperatures (the heat its sources put in, its links to the parts,
    housings and boundaries) and, through the jets, ``stream_frac`` of the net heat Q the cooler took (the cooled oil
    the parts warm again: the jets' stream conductances over mdot cp); at rest ``(1 - stream_frac) Q = H``. The
    cooler itself takes 0 (bypass closed) up to its fully open valve, hA (T_oil - T_air) and at most Q_max_cool;
    the heater's heat is added before that bound and taken off after, as the law's is. The oil's own storage is left
    out: 0.5 MJ/K for 300 L, 0.2 K of drop at a sump moving 5 K/h, where a 0.1 s difference of a 1/32 K sensor
    would be noise."""
    heater = heater_heat_w(c, T_oil_c)
    keep = np.maximum(1.0 - np.asarray(stream_frac, dtype=float), BALANCE_KEEP_MIN)
    a = np.minimum(hA_w_per_k * np.maximum(np.asarray(T_oil_c, dtype=float) - T_air_c, 0.0), c.air_Q_max_cool_w)
    return np.clip(np.asarray(H_w, dtype=float) / keep + heater, 0.0, a) - heater


def inlet_drop_k(Q_w, mcp_w_per_k):
    """The oil-system inlet lies below the sump by the cooler's drop Q / (mdot cp) (the returning cooled oil, Eq 82),
    clipped to +- INLET_DROP_MAX_K; 0 without flow."""
    if np.ndim(Q_w) == 0 and np.ndim(mcp_w_per_k) == 0:  # the plant's one value a step, without numpy's overhead
        m = float(mcp_w_per_k)
        return min(max(float(Q_w) / m, -INLET_DROP_MAX_K), INLET_DROP_MAX_K) if m > 0.0 else 0.0
    m = np.asarray(mcp_w_per_k, dtype=float)
    return np.clip(np.where(m > 0.0, Q_w / np.where(m > 0.0, m, 1.0), 0.0), -INLET_DROP_MAX_K, INLET_DROP_MAX_K)


def cooler_hA_bound_w_per_k(
    c: CoolerParams,
    kind: str,
    omega_ls_max_rad_s: float,
    omega_engine_max_rad_s: float,
    scale_max: float,
    motor_pump: bool = False,
    air_min_c: float = -40.0,
) -> float:
    """An upper bound of the cooler's hA over the operating range (the stability proof): the highest flows, the
    effect scale at its maximum; the air cooler's outer flow factor bounded by AIR_FLOW_MAX_REL^exp_outer. A motor
    pump (``motor_pump``) runs at its data-sheet flow: inner flow ratio 1, whatever the layshaft. The thermostat, at
    the return or at the sump, only scales it: ``Q = hA x (T_oil - T_air)`` with the opening ``0 <= x <= 1``, a
    conductance of at most hA between the sump and the air, which the proof takes at its bound as it takes every
    conductance that depends on the oil temperature (docs/sensor.md, "Stability"). ``air_min_c`` is not used (kept
    for callers)."""
    inner = 1.0 if motor_pump else (omega_ls_max_rad_s / c.ref_ls_speed_rad_s) ** c.exp_inner
    if kind == "liquid":
        return (
            c.liquid_hA_ref_w_per_k
            * inner
            * (omega_engine_max_rad_s / c.ref_engine_speed_rad_s) ** c.exp_outer
            * scale_max
        )
    if kind == "air":
        hA = c.air_hA_ref_w_per_k * inner * AIR_FLOW_MAX_REL**c.exp_outer * scale_max
        return hA
    return 0.0
