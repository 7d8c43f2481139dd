"""Gearbox oil properties as functions of the oil temperature in degC (seed Appendix 2, section 2.5).

Every function takes a float or a numpy array ``T_c`` and broadcasts. The input temperature is clipped to
``T_MIN_C .. T_MAX_C`` (-40..200 degC) before any property is evaluated, so a wild sensor value cannot
produce NaN or a negative viscosity inside the solver loop.

Density, viscosity and the piezo-viscosity coefficient come from the seed's Appendix 2 table (Walther / ASTM D341
between the viscosity rows), conductivity and specific heat are assumed: docs/physics.md, "Oil properties", says
where each property comes from and how it is extended beyond the table.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from firmware_model.errors import InputError
from firmware_model.units import KELVIN_OFFSET_K

#: clip range of the input temperature [degC]
T_MIN_C = -40.0
T_MAX_C = 200.0


def check_temperature_c(label: str, value_c) -> float:
    """A temperature a user sets for the gearbox (an initial or a held temperature), checked: a finite number within
    T_MIN_C..T_MAX_C, the range the oil model describes (outside it every property is clipped; no gearbox in use
    is colder or hotter). InputError naming ``label`` (e.g. ``"--initial-temp"``) otherwise."""
    if (
        isinstance(value_c, bool)
        or not isinstance(value_c, (int, float, np.floating, np.integer))
        or not (math.isfinite(value_c) and T_MIN_C <= value_c <= T_MAX_C)
    ):
        raise InputError(
            f"{label} {value_c!r} degC is not a plausible gearbox temperature: use "
            f"{T_MIN_C:g}..{T_MAX_C:g} degC (the oil model's range)"
        )
    return float(value_c)


# --- Appendix 2 table -------------------------------------------------------------------------------------
#: table temperatures [degC]
TABLE_T_C = np.array([-20.0, 0.0, 20.0, 40.0, 60.0, 80.0, 100.0, 120.0, 140.0])
#: density [kg/m3]
TABLE_RHO_KG_M3 = np.array([896.438, 885.902, 875.366, 864.830, 854.294, 843.758, 833.222, 822.686, 812.150])
#: kinematic viscosity [cSt = mm2/s]
TABLE_NU_CST = np.array([9486.0, 1397.0, 337.6, 115.0, 49.9, 25.8, 15.2, 9.84, 6.84])
#: temperatures with a piezo-viscosity entry [degC]
TABLE_PIEZO_T_C = np.array([20.0, 40.0, 60.0, 80.0, 100.0, 120.0])
#: piezo-viscosity coefficient [1/Pa]
TABLE_PIEZO_PER_PA = np.array([24.0, 21.6, 19.3, 16.9, 14.7, 12.0]) * 1e-9
#: the 1000 degC row (T_c, rho_kg_m3, nu_cst, piezo_per_pa): documentation only, not used
_ROW_1000C = (1000.0, 359.102, 1.00, 1.00e-9)

#: lower bound of the extrapolated piezo-viscosity coefficient [1/Pa] (the seed's 1000 degC value)
PIEZO_FLOOR_PER_PA = 1.0e-9

# Density: exact straight line through the table (Eq: rho = RHO_0 + SLOPE * T_c)
_RHO_0_KG_M3 = 885.902
_RHO_SLOPE_KG_M3K = (TABLE_RHO_KG_M3[-1] - TABLE_RHO_KG_M3[0]) / (TABLE_T_C[-1] - TABLE_T_C[0])  # -0.5268

# Walther (ASTM D341): W = log10(log10(nu_cSt + 0.7)), X = log10(T_K); W is piecewise linear in X.
_WALTHER_C = 0.7
_X_ROWS = np.log10(TABLE_T_C + KELVIN_OFFSET_K)
_W_ROWS = np.log10(np.log10(TABLE_NU_CST + _WALTHER_C))
_W_SLOPE_FIRST = (_W_ROWS[1] - _W_ROWS[0]) / (_X_ROWS[1] - _X_ROWS[0])
_W_SLOPE_LAST = (_W_ROWS[-1] - _W_ROWS[-2]) / (_X_ROWS[-1] - _X_ROWS[-2])
_X_FIRST = float(_X_ROWS[0])
_X_LAST = float(_X_ROWS[-1])

_PIEZO_SLOPE_FIRST = (TABLE_PIEZO_PER_PA[1] - TABLE_PIEZO_PER_PA[0]) / (TABLE_PIEZO_T_C[1] - TABLE_PIEZO_T_C[0])
_PIEZO_SLOPE_LAST = (TABLE_PIEZO_PER_PA[-1] - TABLE_PIEZO_PER_PA[-2]) / (TABLE_PIEZO_T_C[-1] - TABLE_PIEZO_T_C[-2])
_PIEZO_T_FIRST = float(TABLE_PIEZO_T_C[0])
_PIEZO_T_LAST = float(TABLE_PIEZO_T_C[-1])

# Assumed, typical gear oil (not in the seed's table): k = K0 + K1*T_c, cp = CP0 + CP1*T_c
K0_W_PER_MK = 0.134
K1_W_PER_MK2 = -7.0e-5
CP0_J_PER_KGK = 1880.0
CP1_J_PER_KGK2 = 3.7


class OilProperties(NamedTuple):
    """All oil properties at one temperature (or array of temperatures); a tuple, cheap to build."""

    T_c: np.ndarray | float
    rho_kg_m3: np.ndarray | float
    nu_m2_s: np.ndarray | float
    mu_pa_s: np.ndarray | float
    piezo_per_pa: np.ndarray | float
    k_w_per_mk: np.ndarray | float
    cp_j_per_kgk: np.ndarray | float
    alpha_m2_s: np.ndarray | float
    pr: np.ndarray | float


def _clip_t(T_c):
    return np.clip(T_c, T_MIN_C, T_MAX_C)


def _density(Tc):
    return _RHO_0_KG_M3 + _RHO_SLOPE_KG_M3K * Tc


def _kinematic(Tc):
    x = np.log10(Tc + KELVIN_OFFSET_K)
    # np.interp holds the end rows; add the end-segment slopes outside the table (linear extrapolation of W)
    w = (
        np.interp(x, _X_ROWS, _W_ROWS)
        + _W_SLOPE_FIRST * np.minimum(x - _X_FIRST, 0.0)
        + _W_SLOPE_LAST * np.maximum(x - _X_LAST, 0.0)
    )
    nu_cst = 10.0 ** (10.0**w) - _WALTHER_C  # always > 0.3 cSt: 10**(10**w) > 1
    return nu_cst * 1e-6


def _piezo(Tc):
    a = (
        np.interp(Tc, TABLE_PIEZO_T_C, TABLE_PIEZO_PER_PA)
        + _PIEZO_SLOPE_FIRST * np.minimum(Tc - _PIEZO_T_FIRST, 0.0)
        + _PIEZO_SLOPE_LAST * np.maximum(Tc - _PIEZO_T_LAST, 0.0)
    )
    return np.maximum(a, PIEZO_FLOOR_PER_PA)


def _conductivity(Tc):
    return K0_W_PER_MK + K1_W_PER_MK2 * Tc


def _specific_heat(Tc):
    return CP0_J_PER_KGK + CP1_J_PER_KGK2 * Tc


def density_kg_m3(T_c):
    """Oil density [kg/m3] (Appendix 2 table, exactly linear in T)."""
    return _density(_clip_t(T_c))


def kinematic_viscosity_m2_s(T_c):
    """Oil kinematic viscosity [m2/s], Walther/ASTM D341 interpolation of the Appendix 2 table."""
    return _kinematic(_clip_t(T_c))


def dynamic_viscosity_pa_s(T_c):
    """Oil dynamic viscosity [Pa s] = rho * nu (section 2.5)."""
    Tc = _clip_t(T_c)
    return _density(Tc) * _kinematic(Tc)


def piezo_viscosity_per_pa(T_c):
    """Barus piezo-viscosity coefficient [1/Pa] (Appendix 2; linear, floored at 1e-9 /Pa outside 20..120 degC)."""
    return _piezo(_clip_t(T_c))


def thermal_conductivity_w_per_mk(T_c):
    """Oil thermal conductivity [W/(m K)]; assumed, typical gear oil: 0.134 - 7e-5 T_c."""
    return _conductivity(_clip_t(T_c))


def specific_heat_j_per_kgk(T_c):
    """Oil specific heat [J/(kg K)]; assumed, typical gear oil: 1880 + 3.7 T_c."""
    return _specific_heat(_clip_t(T_c))


def thermal_diffusivity_m2_s(T_c):
    """Oil thermal diffusivity alpha = k / (rho cp) [m2/s] (section 2.5)."""
    Tc = _clip_t(T_c)
    return _conductivity(Tc) / (_density(Tc) * _specific_heat(Tc))


def prandtl(T_c):
    """Oil Prandtl number Pr = nu / alpha [-] (section 2.5)."""
    Tc = _clip_t(T_c)
    return _kinematic(Tc) * _density(Tc) * _specific_heat(Tc) / _conductivity(Tc)


#: the last few scalar temperatures' properties: a plant step asks for the sump's three times (cooler, inlet drop,
#: conductances); the tuple is immutable, so a hit returns the same values bit for bit
_SCALAR_MEMO: dict = {}
_SCALAR_MEMO_SIZE = 8


def oil_properties(T_c) -> OilProperties:
    """Every oil property at once (one clip, one Walther evaluation); for the solver loop."""
    if type(T_c) in (float, np.float64):
        hit = _SCALAR_MEMO.get(T_c)
        if hit is None:
            hit = _oil_properties(T_c)
            if len(_SCALAR_MEMO) >= _SCALAR_MEMO_SIZE:
                _SCALAR_MEMO.clear()
            _SCALAR_MEMO[T_c] = hit
        return hit
    return _oil_properties(T_c)


def _oil_properties(T_c) -> OilProperties:
    Tc = _clip_t(T_c)
    rho = _density(Tc)
    nu = _kinematic(Tc)
    k = _conductivity(Tc)
    cp = _specific_heat(Tc)
    alpha = k / (rho * cp)
    return OilProperties(Tc, rho, nu, rho * nu, _piezo(Tc), k, cp, alpha, nu / alpha)
